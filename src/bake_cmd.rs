//! `cssm bake`: loads the scene, bakes it with a progress bar and writes the file; the summary
//! is [`cssm::summary::BakeSummary`].

use std::{process::ExitCode, time::Instant};

use cssm::{
    bake, formats,
    summary::{BakeSummary, ChunkSummary, InspectSummary},
};
use formats::Scene;

use crate::{
    CliResult, check_writable,
    cli::{BakeConfig, MergeArgs},
    load_scene, scene_dir,
};

/// Bakes `scene` with a progress bar of depth maps on stderr. The file is checked as a written
/// one is ([`formats::cssm::validate`]) before anything uses it: a render that bakes in memory
/// must not trust what a `.cssm` read from disk would not be trusted with.
pub fn bake_with_progress(
    scene: &Scene,
    options: &bake::BakeOptions,
) -> Result<bake::Baked, bake::BakeError> {
    let baked = with_progress(scene, &mut |progress| bake::bake(scene, options, progress))?;
    formats::cssm::validate(&baked.file).map_err(|e| {
        bake::BakeError::Scene(format!("the bake's own file fails its checks: {e}"))
    })?;
    Ok(baked)
}

/// Where a bake tells its progress.
type ProgressSink<'a> = &'a mut (dyn FnMut(bake::Progress) + Send);

/// Runs `bake` (a whole bake or a chunk of `scene`) with a progress bar on stderr.
fn with_progress<T>(
    scene: &Scene,
    bake: &mut dyn FnMut(ProgressSink) -> Result<T, bake::BakeError>,
) -> Result<T, bake::BakeError> {
    let bar = indicatif::ProgressBar::new(0);
    let style = |template: &str| {
        indicatif::ProgressStyle::with_template(template)
            .expect("valid template")
            .progress_chars("=> ")
    };
    let name = crate::printable(&scene.name);
    let mut stage = None;
    let baked = bake(&mut |p| {
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
                    "{spinner} baking {msg} [{bar:32}] {pos}%, {elapsed}, eta {eta}"
                }
                bake::Stage::Pack => "{spinner} baking {msg}, attempt {pos}, {elapsed}",
                bake::Stage::Order => "{spinner} baking {msg}, {elapsed}",
                bake::Stage::Csm => {
                    "{spinner} baking {msg} [{bar:32}] {pos}/{len} maps, {per_sec}, eta {eta}"
                }
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
    let dir = scene_dir(config.scene.clone())?;
    let scene = load_scene(&dir)?;
    if let Some(spec) = config.chunk {
        return run_bake_chunk(&scene, &config, spec, start);
    }
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

/// `cssm bake --chunk I/N`: bakes one chunk and writes the chunk file.
fn run_bake_chunk(
    scene: &Scene,
    config: &BakeConfig,
    spec: formats::cssm::ChunkSpec,
    start: Instant,
) -> CliResult {
    let output = config.output.clone().unwrap_or_else(|| {
        format!(
            "{}.chunk-{}-of-{}",
            cssm::safe_file_stem(&scene.name),
            spec.index(),
            spec.count()
        )
        .into()
    });
    check_writable(&output, &scene.input_files())?;
    let baked = with_progress(scene, &mut |progress| {
        bake::bake_chunk(scene, &config.options, spec, config.file_coding, progress)
    })
    .map_err(|e| format!("{}: {}", scene.path.display(), cssm::flag_error(&e)))?;
    let file_bytes =
        formats::cssm::write_chunk_atomic(&output, &baked.chunk).map_err(|e| e.to_string())?;
    let summary = ChunkSummary::new(
        &output,
        &baked.chunk,
        Some((&baked.stats, start.elapsed().as_secs_f64())),
        file_bytes,
    );
    if config.json {
        println!("{}", summary.to_json());
    } else {
        println!("{summary}");
    }
    Ok(ExitCode::SUCCESS)
}

/// `cssm merge`: reads every chunk, joins them and writes the file atomically.
pub fn run_merge(args: MergeArgs) -> CliResult {
    let bar = indicatif::ProgressBar::new(args.chunks.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} reading chunks [{bar:32}] {pos}/{len}, {elapsed}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    // One chunk at a time: each one's tables are checked against the first's and dropped, so
    // memory does not grow with the number of chunks.
    let mut merger = formats::cssm::ChunkMerger::default();
    let mut output = None;
    for path in &args.chunks {
        let chunk = formats::cssm::read_chunk(path).map_err(|e| e.to_string())?;
        if output.is_none() {
            let name = cssm::safe_file_stem(&chunk.file().scene.name);
            let path = args
                .output
                .clone()
                .unwrap_or_else(|| format!("{name}.cssm").into());
            check_writable(&path, &args.chunks)?;
            output = Some(path);
        }
        merger.add(path.clone(), chunk).map_err(|e| e.to_string())?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    let count = args.chunks.len();
    let (file, coding) = merger.finish().map_err(|e| e.to_string())?;
    let output = output.unwrap_or_default();
    let file_bytes =
        formats::cssm::write_atomic_with(&output, &file, coding).map_err(|e| e.to_string())?;
    let summary = InspectSummary::new(&output, &file, file_bytes);
    if args.json {
        println!("{}", summary.to_json());
    } else {
        println!("merged {count} chunks");
        println!("{summary}");
    }
    Ok(ExitCode::SUCCESS)
}
