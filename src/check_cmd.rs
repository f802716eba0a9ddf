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
    let has_rigid = scene
        .objects
        .iter()
        .any(|o| o.kind == formats::ObjectKind::Rigid);
    let m = if has_rigid {
        // Moving objects (§3.3): where --place puts them, else where the scene placed them.
        let poses = poses(&scene, &config.place, &dir)?;
        let posed = bake::check::measure_posed_with_progress(
            &scene,
            &file,
            &poses,
            config.pairs,
            config.seed,
            config.query,
            &mut |done, _| bar.set_position(done),
        )
        .map_err(|e| format!("{}: {e}", config.file.display()))?;
        bar.finish_and_clear();
        for line in posed.overlaps.describe(&scene) {
            eprintln!("warning: {line}");
        }
        posed.measurement
    } else {
        if let Some(p) = config.place.first() {
            return Err(format!(
                "--place {}: the scene in {} has no rigid objects ([[objects]] in scene.toml)",
                p.name,
                dir.display()
            ));
        }
        let m = bake::check::measure_with_progress(
            &scene,
            &file,
            config.pairs,
            config.seed,
            config.query,
            &mut |done, _| bar.set_position(done),
        )
        .map_err(|e| format!("{}: {e}", config.file.display()))?;
        bar.finish_and_clear();
        m
    };
    let summary = CheckSummary::new(&config.file, &m, start.elapsed().as_secs_f64());
    if config.json {
        println!("{}", summary.to_json());
    } else {
        println!("{summary}");
    }
    if summary.exchanging_pairs == 0 {
        // An agreement over no pairs is no measurement: say so rather than print 0% or 100%.
        eprintln!(
            "warning: none of the {} pairs exchanges light (each in front of the other's \
             surface), so nothing that reaches an image was checked{}",
            summary.pairs,
            if config.place.is_empty() {
                ""
            } else {
                "; --place may have put the objects where they face nothing"
            }
        );
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

/// Every object's pose: as loaded, but for the rigid objects `places` moves (their scale
/// stays). `Err` names an unknown or static object.
fn poses(
    scene: &formats::Scene,
    places: &[crate::cli::Place],
    dir: &std::path::Path,
) -> Result<Vec<glam::Affine3A>, String> {
    let mut poses: Vec<glam::Affine3A> = scene.objects.iter().map(|o| o.transform).collect();
    for place in places {
        let rigid = |o: &&formats::SceneObject| o.kind == formats::ObjectKind::Rigid;
        let Some(index) = scene
            .objects
            .iter()
            .position(|o| rigid(&o) && o.name == place.name)
        else {
            let names: Vec<&str> = scene
                .objects
                .iter()
                .filter(rigid)
                .map(|o| o.name.as_str())
                .collect();
            return Err(format!(
                "--place {}: no rigid object of that name in {} (it has: {})",
                place.name,
                dir.display(),
                names.join(", ")
            ));
        };
        let (scale, _, _) = scene.objects[index]
            .transform
            .to_scale_rotation_translation();
        poses[index] = formats::scene::placement(place.translation, place.rotation_deg, scale.x);
    }
    // Posing is cheap: refuse a placement the check could not use (too far from the scene)
    // under the option's name, before the check's own work.
    if !places.is_empty() {
        scene.posed(&poses).map_err(|e| format!("--place: {e}"))?;
    }
    Ok(poses)
}
