//! `cssm bake`: loads the scene, bakes it with a progress bar and writes the file; the summary
//! is [`cssm::summary::BakeSummary`].

use std::{process::ExitCode, time::Instant};

use cssm::{bake, formats, summary::BakeSummary};
use formats::Scene;

use crate::{CliResult, check_writable, cli::BakeConfig, load_scene, scene_dir};

/// Bakes `scene` with a progress bar of depth maps on stderr.
pub fn bake_with_progress(
    scene: &Scene,
    options: &bake::BakeOptions,
) -> Result<bake::Baked, bake::BakeError> {
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} baking {msg} [{bar:32}] {pos}/{len} depth maps, {per_sec}, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(scene.name.clone());
    let baked = bake::bake(scene, options, &mut |done, total| {
        bar.set_length(total);
        bar.set_position(done);
    })?;
    bar.finish_and_clear();
    Ok(baked)
}

pub fn run_bake(config: BakeConfig) -> CliResult {
    let start = Instant::now();
    let dir = scene_dir(config.scene)?;
    let scene = load_scene(&dir)?;
    let output = config
        .output
        .unwrap_or_else(|| format!("{}.cssm", scene.name).into());
    check_writable(&output)?;
    // What the options' check could not tell without the scene (the near distance against its
    // size) or the atlas refuses: the error names the scene directory, and a flag where one is
    // to blame.
    let baked = bake_with_progress(&scene, &config.options)
        .map_err(|e| format!("{}: {}", scene.dir.display(), cssm::flag_error(&e)))?;
    let file_bytes = formats::cssm::write_atomic_with(&output, &baked.file, config.file_coding)
        .map_err(|e| e.to_string())?;
    let summary = BakeSummary::new(
        &scene,
        &output,
        &config.options,
        config.file_coding,
        &baked.stats,
        file_bytes,
        start.elapsed().as_secs_f64(),
    );
    if config.json {
        println!("{}", summary.to_json());
    } else {
        println!("{summary}");
    }
    Ok(ExitCode::SUCCESS)
}
