//! The `cssm` command line: a thin layer over the `cssm-formats`, `cssm-bake` and
//! `cssm-runtime` libraries.
//! Exit codes: 0 success, 1 a check ran and failed its threshold, 2 an error.

use std::{
    path::{Path, PathBuf},
    process::ExitCode,
    time::Instant,
};

mod render;

use clap::{Parser, Subcommand};
use cssm::{bake, builtin, formats};
use formats::{CssmFile, Scene, Traversal, visibility::QueryOptions};

#[derive(Parser)]
#[command(
    name = "cssm",
    version,
    about = "Bake and inspect Coherent Surface Shadow Maps (Ritschel et al. 2008)",
    long_about = "Bake and inspect Coherent Surface Shadow Maps (Ritschel et al. 2008): precomputed \
                  depth cube maps swept over every surface of a scene, compressed per pixel, that \
                  answer visibility between any two surface points.\n\n\
                  Start with `cssm bake`, which bakes the built-in Cornell box."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Bake a scene directory into a .cssm file.
    #[command(after_help = "Examples:\n  cssm bake -o cornell.cssm\n  \
        cssm bake ../shared/scenes/bunny -o bunny.cssm --atlas 128 --cube 32 --traversal zigzag")]
    Bake(BakeArgs),
    /// Print the header and sizes of a .cssm file.
    #[command(
        after_help = "Examples:\n  cssm inspect cornell.cssm\n  cssm inspect cornell.cssm --json"
    )]
    Inspect {
        /// The .cssm file.
        file: PathBuf,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Measure a .cssm file's visibility against exact ray casts on random surface point pairs.
    #[command(after_help = "Examples:\n  cssm check cornell.cssm\n  \
        cssm check cornell.cssm --pairs 1000000 --no-pcf --min-agreement 0.98")]
    Check(CheckArgs),
    /// Render a scene on the GPU to a PNG (tone-mapped) and optionally an EXR (linear radiance).
    #[command(
        long_about = "Render a scene on the GPU (Vulkan; Mesa's lavapipe where there is no GPU) \
                      to a tone-mapped PNG and, with --exr, linear radiance in OpenEXR. The \
                      method `reference` path traces on the CPU instead: the ground truth.",
        after_help = render::after_help()
    )]
    Render(render::RenderArgs),
    /// Measure the toolchain against the paper and write a report.
    #[command(subcommand)]
    Report(ReportCommand),
}

#[derive(Subcommand)]
enum ReportCommand {
    /// Bake a grid of settings and write reports/compression.md, .csv and .svg: the paper's
    /// Tables 2 and 3 (compression ratio, sizes, bake time, peak memory, accuracy against ray
    /// casts) next to the paper's figures, and every option beyond the paper.
    ///
    /// Every row runs `cssm bake --json` and `cssm check --json` as child processes, so each
    /// row's peak memory is its own. The full grid (atlas up to 512, four scenes) takes about
    /// an hour on a quiet 2-core machine, the Cornell box's rows about 14 minutes of it;
    /// `reports/compression.sh` runs it. Rows whose scene is missing from
    /// --scenes are listed as not run.
    #[command(after_help = "Examples:\n  \
        cssm report compression --quick --out /tmp            # smoke test: atlas 32 and 64, cube 8, Cornell box\n  \
        cssm report compression --scene cornell               # Tables 2 and 3 and the options for the Cornell box\n  \
        cssm report compression --tables table3 --scene church --atlas 256\n  \
        cssm report compression                               # everything (reports/compression.sh)")]
    Compression(cssm::report::CompressionArgs),
    /// Write the "Cornell Heads" scene of Table 3 to a directory: the built-in Cornell box with
    /// the Utah teapot and the Stanford bunny inside, the bunny simplified (meshoptimizer) so
    /// that the scene has about 19,000 faces like the paper's. Bake and render it like any
    /// scene.
    #[command(after_help = "Example:\n  \
        cssm report heads --out /tmp/heads && cssm render /tmp/heads --method lightcuts")]
    Heads(HeadsArgs),
    /// Write the church of Table 3 at the paper's size to a directory: the Sibenik cathedral
    /// simplified (meshoptimizer, material by material) from about 73,500 faces to the paper's
    /// 3,700. Bake and render it like any scene.
    #[command(after_help = "Example:\n  \
        cssm report church --out /tmp/church && cssm bake /tmp/church --atlas 128")]
    Church(ChurchArgs),
}

#[derive(clap::Args)]
struct ChurchArgs {
    /// Directory of the third-party scenes (needs sibenik/).
    #[arg(long, default_value = "../shared/scenes")]
    scenes: PathBuf,
    /// Directory to write the scene into (created; OBJ and MTL).
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args)]
struct HeadsArgs {
    /// Directory of the third-party scenes (needs teapot/ and bunny/).
    #[arg(long, default_value = "../shared/scenes")]
    scenes: PathBuf,
    /// Directory to write the scene into (created; scene.toml, OBJ and MTL).
    #[arg(long)]
    out: PathBuf,
}

#[derive(clap::Args)]
struct BakeArgs {
    /// Scene directory (scene.toml + OBJ/MTL, or a directory of OBJ files). Default: the
    /// built-in Cornell box.
    scene: Option<PathBuf>,
    /// Output file. Default: <scene name>.cssm in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Atlas width and height in texels (32 to 1024).
    #[arg(long, default_value_t = 64)]
    atlas: u32,
    /// Cube-map face resolution N; each map has 6 x N x N pixels (8 to 128).
    #[arg(long, default_value_t = 32)]
    cube: u32,
    /// Order of the depth-map sequence: zigzag, spiral or greedy (§3.2.3); hilbert (chart by
    /// chart, a Hilbert curve inside each chart; beyond the paper, and the default: in
    /// reports/compression.md it compresses better than the paper's orders at the same
    /// accuracy); or piloted (per chart the Hilbert or the Spiral order, whichever a pilot bake
    /// of the chart at cube 8 compresses better; beyond the paper: a little better than hilbert,
    /// 41.2 against 41.0 : 1 on the Cornell box at atlas 128, cube 64, for 7-10% more bake time
    /// at cube 32).
    #[arg(long, default_value = "hilbert")]
    traversal: Traversal,
    /// How the chart-by-chart traversals choose the next chart: nearest (§3.2.3: the chart whose
    /// first texel is nearest) or ends (the chart with an end, first or last texel, nearest;
    /// walked backwards from its last one; beyond the paper).
    #[arg(long, default_value = "nearest")]
    chart_order: bake::traverse::ChartOrder,
    /// Which depth a run stores inside the codes all its maps accept: middle (the middle code)
    /// or balanced (equal relative margins to the near and the far layer). Beyond the paper.
    #[arg(long, default_value = "middle")]
    run_value: bake::compress::RunValue,
    /// Lossy: merge runs of at most this many depth maps into their neighbours when those agree
    /// (0: lossless, as in the paper). Fewer runs, a few wrong depths; measure with `cssm check`.
    #[arg(long, default_value_t = 0)]
    merge_short_runs: u32,
    /// Which intersections bound each pixel's depth interval: any (the first and the second, as in
    /// the paper); facing (the second is the nearest one beyond the first whose surface faces the
    /// texel: surfaces facing away exchange no light with it, so their visibility never matters;
    /// beyond the paper); or exchange (as facing, and a first surface that faces away sets no
    /// lower bound; a pixel that meets no facing surface, nor do its neighbours, is don't care;
    /// beyond the paper).
    #[arg(long, default_value = "any")]
    second_layer: bake::cubemap::SecondLayer,
    /// How the file stores the runs: packed (run lengths and depth differences as varints before
    /// zstd: a smaller file, the same data in memory) or plain (zstd only, the first format).
    #[arg(long, default_value = "packed")]
    file_coding: formats::cssm::FileCoding,
    /// Distance the cube maps sit off the surface, in scene units. Default: 0.2% of the scene
    /// diameter.
    #[arg(long)]
    near: Option<f32>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
struct CheckArgs {
    /// The .cssm file.
    file: PathBuf,
    /// Scene directory to check against. Default: the directory recorded in the file.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Number of random surface point pairs.
    #[arg(long, default_value_t = 100_000)]
    pairs: u64,
    /// Seed of the pairs.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Turn off percentage-closer filtering over the 2x2 pixels around each projection.
    #[arg(long)]
    no_pcf: bool,
    /// Use only the texel under each sender point (no filtering across neighbouring cube maps).
    #[arg(long)]
    no_sender_filter: bool,
    /// Constant depth bias, in multiples of the bake's near distance.
    #[arg(long, default_value_t = QueryOptions::default().bias_near)]
    bias_near: f32,
    /// Depth bias proportional to the query depth.
    #[arg(long, default_value_t = QueryOptions::default().bias_relative)]
    bias_relative: f32,
    /// Exit with status 1 when the agreement over the pairs that exchange light is below this
    /// fraction.
    #[arg(long)]
    min_agreement: Option<f64>,
    /// Print the result as one JSON object.
    #[arg(long)]
    json: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Bake(args) => run_bake(args),
        Command::Inspect { file, json } => run_inspect(&file, json),
        Command::Check(args) => run_check(args),
        Command::Render(args) => render::run_render(args),
        Command::Report(ReportCommand::Compression(args)) => run_report(args),
        Command::Report(ReportCommand::Heads(args)) => run_heads(args),
        Command::Report(ReportCommand::Church(args)) => run_church(args),
    };
    match result {
        Ok(code) => code,
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::from(2)
        }
    }
}

type CliResult = Result<ExitCode, String>;

fn load_scene(dir: &Path) -> Result<Scene, String> {
    let scene = Scene::load(dir).map_err(|e| e.to_string())?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

/// Mesa's Vulkan drivers print "error: XDG_RUNTIME_DIR is invalid or not set" on machines
/// without a desktop session although a headless render never needs it; point it at a private
/// directory of ours so users are not alarmed by an error that is not one.
pub(crate) fn quiet_mesa_wsi() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("cssm-runtime-{}", std::process::id()));
    #[cfg(unix)]
    {
        use std::os::unix::fs::DirBuilderExt;
        if std::fs::DirBuilder::new().mode(0o700).create(&dir).is_err() {
            return;
        }
    }
    // SAFETY: called from the main thread before the GPU instance or any worker thread exists.
    unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
}

/// Bakes `scene` with a progress bar of depth maps on stderr; errors name the scene directory.
fn bake_with_progress(scene: &Scene, options: &bake::BakeOptions) -> Result<bake::Baked, String> {
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
    })
    .map_err(|e| format!("{}: {e}", scene.dir.display()))?;
    bar.finish_and_clear();
    Ok(baked)
}

fn run_bake(args: BakeArgs) -> CliResult {
    let start = Instant::now();
    let dir = match &args.scene {
        Some(dir) => dir.clone(),
        None => builtin::cornell_box()
            .map_err(|e| format!("cannot prepare the built-in Cornell box: {e}"))?,
    };
    // Validate the cheap things before the expensive ones.
    if !bake::ATLAS_RESOLUTION_RANGE.contains(&args.atlas) {
        return Err(format!("--atlas {} is out of range 32..=1024", args.atlas));
    }
    if !bake::CUBE_RESOLUTION_RANGE.contains(&args.cube) {
        return Err(format!("--cube {} is out of range 8..=128", args.cube));
    }
    let scene = load_scene(&dir)?;
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("{}.cssm", scene.name)));
    check_writable(&output)?;
    let options = bake::BakeOptions {
        atlas_resolution: args.atlas,
        cube_resolution: args.cube,
        traversal: args.traversal,
        chart_order: args.chart_order,
        near: args.near,
        run_value: args.run_value,
        merge_short_runs: args.merge_short_runs,
        second_layer: args.second_layer,
    };
    let baked = bake_with_progress(&scene, &options)?;
    let file_bytes = formats::cssm::write_atomic_with(&output, &baked.file, args.file_coding)
        .map_err(|e| e.to_string())?;
    let seconds = start.elapsed().as_secs_f64();
    let s = &baked.stats;
    let summary = serde_json::json!({
        "scene": scene.name,
        "output": output.display().to_string(),
        "triangles": scene.triangles.len(),
        "atlas_resolution": args.atlas,
        "cube_resolution": args.cube,
        "traversal": args.traversal.name(),
        "chart_order": args.chart_order.name(),
        "run_value": args.run_value.name(),
        "merge_short_runs": args.merge_short_runs,
        "second_layer": args.second_layer.name(),
        "file_coding": args.file_coding.name(),
        "charts": s.charts,
        "defined_texels": s.defined_texels,
        "rays": s.rays,
        "runs": s.runs,
        "uncompressed_bytes": s.uncompressed_bytes,
        "gpu_bytes": s.gpu_bytes,
        "file_bytes": file_bytes,
        "ratio_gpu": s.ratio_gpu(),
        "ratio_file": s.uncompressed_bytes as f64 / file_bytes.max(1) as f64,
        "atlas_seconds": s.atlas_time.as_secs_f64(),
        "traversal_seconds": s.traversal_time.as_secs_f64(),
        "maps_seconds": s.maps_time.as_secs_f64(),
        "hierarchy_seconds": s.hierarchy_time.as_secs_f64(),
        "total_seconds": seconds,
        "rays_per_second": s.rays as f64 / s.maps_time.as_secs_f64().max(1e-9),
        "threads": rayon_threads(),
        "peak_rss_bytes": peak_rss_bytes(),
    });
    if args.json {
        println!("{summary}");
    } else {
        println!("baked {} -> {}", scene.name, output.display());
        println!(
            "  atlas {a}x{a}: {} defined texels (depth maps) in {} charts",
            s.defined_texels,
            s.charts,
            a = args.atlas
        );
        println!(
            "  cube 6x{c}x{c}, {} traversal, {} rays ({:.1} M rays/s, {:.0} maps/s)",
            args.traversal,
            s.rays,
            s.rays as f64 / s.maps_time.as_secs_f64().max(1e-9) / 1e6,
            s.defined_texels as f64 / s.maps_time.as_secs_f64().max(1e-9),
            c = args.cube
        );
        println!("  uncompressed   {:>12}", human_bytes(s.uncompressed_bytes));
        println!(
            "  in memory      {:>12}  ratio {:.1} : 1  ({} runs)",
            human_bytes(s.gpu_bytes),
            s.ratio_gpu(),
            s.runs
        );
        println!(
            "  file           {:>12}  ratio {:.1} : 1",
            human_bytes(file_bytes),
            s.uncompressed_bytes as f64 / file_bytes.max(1) as f64
        );
        println!(
            "  time {:.2} s (atlas {:.2} s, traversal {:.2} s, depth maps {:.2} s, hierarchy {:.2} s)",
            seconds,
            s.atlas_time.as_secs_f64(),
            s.traversal_time.as_secs_f64(),
            s.maps_time.as_secs_f64(),
            s.hierarchy_time.as_secs_f64()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// This process's peak resident set size so far (`VmHWM` of `/proc/self/status`), where the
/// system reports one (Linux); the compression report reads it from every bake it runs.
fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Fails early, before a long bake, when the output cannot be written.
fn check_writable(output: &Path) -> Result<(), String> {
    let parent = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !parent.is_dir() {
        return Err(format!(
            "cannot write {}: directory {} does not exist",
            output.display(),
            parent.display()
        ));
    }
    if output.is_dir() {
        return Err(format!(
            "cannot write {}: it is a directory",
            output.display()
        ));
    }
    let probe = parent.join(format!(".cssm-write-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| format!("cannot write {}: {e}", output.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

fn human_bytes(b: u64) -> String {
    cssm::human_bytes(b, 2)
}

fn read_file(path: &Path) -> Result<CssmFile, String> {
    formats::cssm::read(path).map_err(|e| e.to_string())
}

fn inspect_json(file: &CssmFile, file_bytes: u64) -> serde_json::Value {
    let p = &file.params;
    let uncompressed = file.runs.uncompressed_bytes();
    let gpu = file.runs.gpu_bytes();
    serde_json::json!({
        "format_version": formats::cssm::FORMAT_VERSION,
        "scene": file.scene.name,
        "scene_dir": file.scene.dir,
        "scene_hash": formats::scene::hash_hex(&file.scene.content_hash),
        "triangles": file.scene.triangle_count,
        "atlas_resolution": p.atlas_resolution,
        "cube_resolution": p.cube_resolution,
        "near": p.near,
        "far": p.far,
        "traversal": p.traversal.name(),
        "defined_texels": file.texels.len(),
        "runs": file.runs.runs.len(),
        "uncompressed_bytes": uncompressed,
        "gpu_bytes": gpu,
        "file_bytes": file_bytes,
        "ratio_gpu": uncompressed as f64 / gpu.max(1) as f64,
        "ratio_file": uncompressed as f64 / file_bytes.max(1) as f64,
    })
}

fn run_inspect(path: &Path, json: bool) -> CliResult {
    let file = read_file(path)?;
    let file_bytes = std::fs::metadata(path)
        .map_err(|e| format!("{}: {e}", path.display()))?
        .len();
    let j = inspect_json(&file, file_bytes);
    if json {
        println!("{j}");
        return Ok(ExitCode::SUCCESS);
    }
    let p = &file.params;
    println!(
        "{}: CSSM format version {}",
        path.display(),
        formats::cssm::FORMAT_VERSION
    );
    println!(
        "  scene          {} ({}, {} triangles)",
        file.scene.name, file.scene.dir, file.scene.triangle_count
    );
    println!(
        "  scene hash     {}",
        j["scene_hash"].as_str().unwrap_or("")
    );
    println!(
        "  atlas          {a}x{a}, {} defined texels",
        file.texels.len(),
        a = p.atlas_resolution
    );
    println!(
        "  cube maps      6x{c}x{c}, near {:.4}, far {:.4}",
        p.near,
        p.far,
        c = p.cube_resolution
    );
    println!("  traversal      {}", p.traversal);
    println!("  runs           {}", file.runs.runs.len());
    println!(
        "  uncompressed   {:>12}",
        human_bytes(file.runs.uncompressed_bytes())
    );
    println!(
        "  in memory      {:>12}  ratio {:.1} : 1",
        human_bytes(file.runs.gpu_bytes()),
        j["ratio_gpu"].as_f64().unwrap_or(0.0)
    );
    println!(
        "  file           {:>12}  ratio {:.1} : 1",
        human_bytes(file_bytes),
        j["ratio_file"].as_f64().unwrap_or(0.0)
    );
    Ok(ExitCode::SUCCESS)
}

fn run_report(args: cssm::report::CompressionArgs) -> CliResult {
    let exe = std::env::current_exe().map_err(|e| format!("cannot find the cssm binary: {e}"))?;
    let command = std::iter::once("cssm".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    let report = cssm::report::run(&args, &exe, &command)?;
    let done = report.rows.iter().filter(|r| r.outcome.is_ok()).count();
    println!(
        "wrote {} ({done} of {} rows ran)",
        args.out.join("compression.md").display(),
        report.rows.len()
    );
    Ok(ExitCode::SUCCESS)
}

fn run_heads(args: HeadsArgs) -> CliResult {
    for part in ["teapot", "bunny"] {
        let dir = args.scenes.join(part);
        if !dir.is_dir() {
            return Err(format!(
                "{}: not a directory; the heads scene needs the teapot and the bunny (pass --scenes)",
                dir.display()
            ));
        }
    }
    let cornell = cssm::builtin::cornell_box()
        .map_err(|e| format!("cannot prepare the built-in Cornell box: {e}"))?;
    let heads = cssm::report::heads::build(&cornell, &args.scenes, &args.out)?;
    println!(
        "wrote {} ({} faces: Cornell box {}, teapot {}, bunny {})",
        heads.dir.display(),
        heads.faces.iter().sum::<usize>(),
        heads.faces[0],
        heads.faces[1],
        heads.faces[2]
    );
    Ok(ExitCode::SUCCESS)
}

fn run_church(args: ChurchArgs) -> CliResult {
    let sibenik = args.scenes.join("sibenik");
    if !sibenik.is_dir() {
        return Err(format!(
            "{}: not a directory; the church is built from the Sibenik cathedral (pass --scenes)",
            sibenik.display()
        ));
    }
    let church = cssm::report::church::build(&sibenik, &args.out)?;
    println!(
        "wrote {} ({} faces, simplified from {})",
        church.dir.display(),
        church.faces,
        church.faces_in
    );
    Ok(ExitCode::SUCCESS)
}

fn run_check(args: CheckArgs) -> CliResult {
    let file = read_file(&args.file)?;
    let dir = args
        .scene
        .clone()
        .unwrap_or_else(|| PathBuf::from(&file.scene.dir));
    if !dir.is_dir() {
        return Err(format!(
            "{}: the scene it was baked from, {}, is not there; pass --scene DIR",
            args.file.display(),
            dir.display()
        ));
    }
    let scene = load_scene(&dir)?;
    if scene.content_hash != file.scene.content_hash
        || scene.triangles.len() as u32 != file.scene.triangle_count
    {
        return Err(format!(
            "{}: the scene in {} has changed since the bake (content hash {} now, {} when baked); bake again",
            args.file.display(),
            dir.display(),
            formats::scene::hash_hex(&scene.content_hash),
            formats::scene::hash_hex(&file.scene.content_hash)
        ));
    }
    let options = QueryOptions {
        bias_near: args.bias_near,
        bias_relative: args.bias_relative,
        pcf: !args.no_pcf,
        sender_filter: !args.no_sender_filter,
    };
    let start = Instant::now();
    let m = bake::check::measure(&scene, &file, args.pairs, args.seed, options);
    let seconds = start.elapsed().as_secs_f64();
    let a = &m.all;
    let x = &m.exchanging;
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "pairs": a.total(),
                "unmapped": a.unmapped,
                "visible_visible": a.visible_visible,
                "visible_occluded": a.visible_occluded,
                "occluded_visible": a.occluded_visible,
                "occluded_occluded": a.occluded_occluded,
                "agreement": a.agreement(),
                "false_visible_rate": a.false_visible_rate(),
                "false_occluded_rate": a.false_occluded_rate(),
                "exchanging_pairs": x.total(),
                "exchanging_agreement": x.agreement(),
                "exchanging_false_visible_rate": x.false_visible_rate(),
                "exchanging_false_occluded_rate": x.false_occluded_rate(),
                "seconds": seconds,
            })
        );
    } else {
        println!(
            "{}: {} random surface point pairs against exact ray casts",
            args.file.display(),
            a.total()
        );
        println!("{a}");
        println!(
            "\nthe {} of them that exchange light (each in front of the other's surface):",
            x.total()
        );
        println!("{x}");
        if a.unmapped > 0 {
            println!(
                "({} sender points had no texel and were skipped)",
                a.unmapped
            );
        }
    }
    // The bar is for the pairs that exchange light, the only ones whose visibility reaches an
    // image (a bake with `--second-layer facing` is only exact there).
    if let Some(min) = args.min_agreement {
        if x.agreement() < min {
            eprintln!(
                "agreement {:.4} (pairs that exchange light) is below --min-agreement {min}",
                x.agreement()
            );
            return Ok(ExitCode::from(1));
        }
    }
    Ok(ExitCode::SUCCESS)
}
