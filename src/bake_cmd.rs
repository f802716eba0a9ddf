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
    let style = |template: &str| {
        indicatif::ProgressStyle::with_template(template)
            .expect("valid template")
            .progress_chars("=> ")
    };
    let name = crate::printable(&scene.name);
    let mut stage = None;
    let baked = bake::bake(scene, options, &mut |p| {
        bar.set_length(p.total);
        bar.set_position(p.done);
        // Each stage its own style: a bar where the stage can tell how far it is.
        if stage != Some(p.stage) {
            stage = Some(p.stage);
            bar.set_style(style(match p.stage {
                bake::Stage::Maps => {
                    "{spinner} baking {msg} [{bar:32}] {pos}/{len} depth maps, {per_sec}, eta {eta}"
                }
                bake::Stage::Charts | bake::Stage::Parameterize => {
                    "{spinner} baking {msg} [{bar:32}] {pos}%, {elapsed}"
                }
                bake::Stage::Pack => "{spinner} baking {msg}, attempt {pos}, {elapsed}",
                bake::Stage::Order => "{spinner} baking {msg}, {elapsed}",
            }));
            bar.set_message(format!("{name}: {}", p.stage.describe()));
            bar.reset_elapsed();
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
        }
    })?;
    bar.finish_and_clear();
    Ok(baked)
}

pub fn run_bake(config: BakeConfig) -> CliResult {
    let start = Instant::now();
    let dir = scene_dir(config.scene)?;
    let scene = load_scene(&dir)?;
    // The default name is the scene's as one safe file name in the current directory.
    let output = config
        .output
        .unwrap_or_else(|| format!("{}.cssm", cssm::safe_file_stem(&scene.name)).into());
    check_writable(&output, &scene.input_files())?;
    // What the options' check could not tell without the scene (the near distance against its
    // size) or the atlas refuses: the error names the scene directory, and a flag where one is
    // to blame.
    let baked = bake_with_progress(&scene, &config.options)
        .map_err(|e| format!("{}: {}", scene.path.display(), cssm::flag_error(&e)))?;
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
