//! `cssm check`: the bake library's measurement against exact ray casts
//! ([`cssm::bake::check::measure`]) of a `.cssm` file, on the scene it was baked from; the
//! summary is [`cssm::summary::CheckSummary`].

use std::{path::PathBuf, process::ExitCode, time::Instant};

use cssm::{bake, formats, runtime, summary::CheckSummary};

use crate::{CliResult, cli::CheckConfig, load_scene, read_file};

pub fn run_check(config: CheckConfig) -> CliResult {
    let file = read_file(&config.file)?;
    let dir = config
        .scene
        .clone()
        .unwrap_or_else(|| PathBuf::from(&file.scene.dir));
    if !dir.exists() {
        return Err(format!(
            "{}: the scene it was baked from, {}, is not there; pass --scene PATH",
            config.file.display(),
            dir.display()
        ));
    }
    let scene = load_scene(&dir)?;
    // The runtime's check that a file belongs to its scene (triangle count, content hash, the
    // indices into the scene); its message says whether this is another scene or the same one
    // changed, and here both hashes follow.
    runtime::load::check_scene(&config.file, &file, &scene).map_err(|e| match e {
        runtime::RuntimeError::SceneMismatch { .. } => format!(
            "{e} (scene in {}: content hash {} now, {} when baked)",
            dir.display(),
            formats::scene::hash_hex(&scene.content_hash),
            formats::scene::hash_hex(&file.scene.content_hash)
        ),
        other => other.to_string(),
    })?;
    let start = Instant::now();
    let bar = indicatif::ProgressBar::new(config.pairs).with_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} checking [{bar:32}] {pos}/{len} pairs, {per_sec}, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let m = bake::check::measure_with_progress(
        &scene,
        &file,
        config.pairs,
        config.seed,
        config.query,
        &mut |done, _| bar.set_position(done),
    );
    bar.finish_and_clear();
    let summary = CheckSummary::new(&config.file, &m, start.elapsed().as_secs_f64());
    if config.json {
        println!("{}", summary.to_json());
    } else {
        println!("{summary}");
    }
    // The bar is for the pairs that exchange light, the only ones whose visibility reaches an
    // image (a bake with `--second-layer facing` is only exact there).
    if let Some(min) = config.min_agreement
        && summary.exchanging_agreement < min
    {
        eprintln!(
            "agreement {:.4} (pairs that exchange light) is below --min-agreement {min}",
            summary.exchanging_agreement
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}
