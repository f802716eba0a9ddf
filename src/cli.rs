//! The command line's definitions (clap) and each command's arguments turned into a config of
//! library types: what the flags mean and how they are spelled live here; every range is
//! checked by the library that takes the value ([`bake::BakeOptions::check`], the runtime's
//! method table and frame settings), and an error names the flag. The number parsers here
//! (`finite_f32`, `bias`, `stops`, `fraction`) refuse what no library value can mean (NaN,
//! infinities, a negative bias, a fraction beyond 1) as clap parses the flag.

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use cssm::{bake, formats, runtime};
use formats::{Traversal, cssm::FileCoding, visibility::QueryOptions};
use runtime::{
    common::compose::Component,
    method::{MethodEntry, OptionValue, OptionValues, Resolved},
};

#[derive(Parser)]
#[command(
    name = "cssm",
    version,
    about = "Bake and inspect Coherent Surface Shadow Maps (Ritschel et al. 2008)",
    long_about = "Bake and inspect Coherent Surface Shadow Maps (Ritschel et al. 2008): precomputed \
                  depth cube maps swept over every surface of a scene, compressed per pixel, that \
                  answer visibility between any two surface points.\n\n\
                  Start with `cssm bake`, which bakes the built-in Cornell box.",
    after_help = "Examples:\n  \
        cssm bake -o cornell.cssm                  # the built-in Cornell box\n  \
        cssm inspect cornell.cssm\n  \
        cssm check cornell.cssm --min-agreement 0.98\n  \
        cssm render --cssm cornell.cssm --method lightcuts --out gi.png\n  \
        cssm view --cssm cornell.cssm --method lightcuts   # a window: orbit, fly, switch methods\n  \
        cssm compare --out compare                 # every method against the path tracer\n  \
        cssm report compression --quick --out /tmp"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Let a glTF file's buffers and images be files outside its own directory (an absolute
    /// path, a `..` leading out, a link pointing out). Without it such a scene is refused: a
    /// downloaded model cannot make cssm read, or quote in an error, files elsewhere.
    #[arg(long, global = true)]
    pub allow_outside_files: bool,
}

#[derive(Subcommand)]
pub enum Command {
    /// Bake a scene (a directory, or one .obj, .gltf or .glb file) into a .cssm file.
    #[command(after_help = "Examples:\n  cssm bake -o cornell.cssm\n  \
        cssm bake ../shared/scenes/bunny -o bunny.cssm --atlas 128 --cube 32 --traversal zigzag\n  \
        cssm bake ../shared/scenes/cornell-original/CornellBox-Original.obj -o mcguire.cssm\n  \
        cssm bake sponza.glb -o sponza.cssm")]
    Bake(BakeArgs),
    /// Join the chunks of a chunked bake (cssm bake --chunk I/N) into one .cssm file.
    ///
    /// The merged file is byte for byte the one a single `cssm bake` with the same scene and
    /// options writes. Every chunk 0 to N-1 must be given once, in any order; a missing one
    /// (a failed job of the farm) is named, and chunks of another scene or other options are
    /// refused. The output is written atomically: nothing is left half-written.
    #[command(
        after_help = "Examples:\n  cssm merge cornell.chunk-*-of-4 -o cornell.cssm\n  \
        cssm merge parts/*.chunk-* -o sibenik.cssm --json"
    )]
    Merge(MergeArgs),
    /// Print the header and sizes of a .cssm file, or which slice a chunk (cssm bake --chunk) holds.
    #[command(
        after_help = "Examples:\n  cssm inspect cornell.cssm\n  cssm inspect cornell.cssm --json"
    )]
    Inspect(InspectArgs),
    /// Measure a .cssm file's visibility against exact ray casts on random surface point pairs.
    #[command(after_help = "Examples:\n  cssm check cornell.cssm\n  \
        cssm check cornell.cssm --pairs 1000000 --no-pcf --min-agreement 0.98\n  \
        cssm check bunny-box.cssm --place bunny=300,0,200,0,90,0   # the bunny moved and turned")]
    Check(CheckArgs),
    /// Render a scene on the GPU to a PNG (tone-mapped) and optionally an EXR (linear radiance).
    #[command(
        long_about = "Render a scene on the GPU (Vulkan; Mesa's lavapipe where there is no GPU) \
                      to a tone-mapped PNG and, with --exr, linear radiance in OpenEXR. The \
                      method `reference` path traces on the CPU instead: the ground truth.",
        after_help = render_after_help()
    )]
    Render(RenderArgs),
    /// Open a window on a scene: the GPU renderer of `cssm render`, with a camera and light to
    /// move and keys to switch method, component and bounces.
    #[command(
        long_about = "Open a window (X11 or Wayland) on a scene, rendered by the GPU renderer of \
                      `cssm render` with the same options: the image in the window is the one \
                      `cssm render` writes for the same camera, light, method and size. While \
                      nothing moves, the frames accumulate (methods that jitter converge). The \
                      overlay (H) shows the settings, camera, light, GPU milliseconds per pass \
                      and the frame time, with menus to switch method, component and bounces; \
                      the window title shows the method, component, GPU milliseconds per frame \
                      and the frames accumulated (stderr the GPU time per pass once a second). \
                      --script feeds the window scripted input, for \
                      tests and demonstrations.",
        after_help = view_after_help()
    )]
    View(ViewArgs),
    /// Render every method side by side against the path tracer and write a page (index.html).
    ///
    /// Every method of the table on each scene beside the reference path tracer: a page that
    /// answers which method, at what cost, how far from the ground truth: every method's full
    /// image, indirect light and error map, its relative
    /// RMSE, FLIP and bias against the path tracer with the reference's own noise taken out,
    /// its GPU milliseconds per pass and GPU memory, and a chart of error against time; the
    /// same figures as compare.csv, compare.json and compare.md.
    ///
    /// The reference is path traced in two independent halves: their mean is the ground truth,
    /// their difference its noise, which the page subtracts (in quadrature) from each method's
    /// error and reports beside it. References are cached in OUT/reference-cache/ by the
    /// scene's files and the settings. The GPU milliseconds are the device's (lavapipe's say
    /// nothing about a GPU).
    #[command(after_help = compare_after_help())]
    Compare(CompareArgs),
    /// Measure the toolchain against the paper and write a report.
    #[command(
        subcommand,
        after_help = "Examples:\n  \
            cssm report compression --quick --out /tmp\n  \
            cssm report heads --out /tmp/heads\n  \
            cssm report church --out /tmp/church\n  \
            cssm report error --method direct --method lightcuts --out /tmp/error"
    )]
    Report(ReportCommand),
}

#[derive(Subcommand)]
pub enum ReportCommand {
    /// Bake a grid of settings and write reports/compression.md, .csv and .svg: the paper's
    /// Tables 2 and 3 (compression ratio, sizes, bake time, peak memory, accuracy against ray
    /// casts) next to the paper's figures, and every option beyond the paper.
    ///
    /// Every row runs `cssm bake --json` and `cssm check --json` as child processes, so each
    /// row's peak memory is its own. The full grid (atlas up to 512, four scenes) takes long
    /// (reports/compression.md gives the last run's time and machine);
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
    /// Render each scene with the reference path tracer and with every --method variant, and
    /// write each variant's error against the path tracer: relative RMSE, mean bias, light
    /// leaking into the reference's dark places, mean FLIP, and the reference's own noise floor
    /// (error.md, error.csv, one PNG per image and a side-by-side strip per scene).
    ///
    /// The reference is path traced in two independent halves of --samples paths each (other
    /// seeds than `--method reference` uses): their mean is the ground truth, their difference
    /// gives its noise floor, the relative RMSE a method equal to the converged image would show
    /// against it. Every pixel counts in every figure. The leak's mask is the pixels whose
    /// reference luminance is below half the median of the nonzero ones.
    #[command(after_help = error_after_help())]
    Error(ErrorArgs),
}

#[derive(clap::Args)]
pub struct ChurchArgs {
    /// Directory of the third-party scenes (needs sibenik/).
    #[arg(long, default_value = "../shared/scenes")]
    pub scenes: PathBuf,
    /// Directory to write the scene into (created; OBJ and MTL).
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(clap::Args)]
pub struct HeadsArgs {
    /// Directory of the third-party scenes (needs teapot/ and bunny/).
    #[arg(long, default_value = "../shared/scenes")]
    pub scenes: PathBuf,
    /// Directory to write the scene into (created; scene.toml, OBJ and MTL).
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(clap::Args)]
pub struct BakeArgs {
    /// The scene: a directory (scene.toml with OBJ/MTL or glTF meshes, or a directory of .obj,
    /// .gltf and .glb files), or one .obj, .gltf or .glb file. Default: the built-in Cornell box.
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
    /// chart, a Hilbert curve inside each chart; beyond the paper: in reports/compression.md it
    /// compresses better than the paper's orders at the same accuracy); or piloted (per chart the
    /// Hilbert or the Spiral order, whichever a pilot bake of the chart at cube 8 compresses
    /// better; beyond the paper, and the default: a little better than hilbert for a little more
    /// bake time, part of the report's best variant).
    #[arg(long, default_value = "piloted")]
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
    /// beyond the paper, and the default: exact for every pair that exchanges light, the only
    /// visibility an image uses, in a much smaller file; reports/compression.md, best variant).
    #[arg(long, default_value = "exchange")]
    second_layer: bake::cubemap::SecondLayer,
    /// Which renderer draws the depth cube maps: raster (triangle by triangle, the watertight
    /// ray/triangle test on the pixels each triangle covers; fastest for scenes of few
    /// triangles), bvh (one BVH traversal per pixel), or auto (raster for scenes of at most
    /// N^2.5/5 triangles at cube resolution N, about where the two break even: 1,158 at cube 32,
    /// 6,553 at cube 64; bvh above; the default).
    /// The file is byte-identical either way; only the time differs (reports/bake.md).
    #[arg(long, default_value = "auto")]
    cube_renderer: bake::cubemap::CubeRenderer,
    /// Where each texel's cube-map pixels sit: centred (the paper's grid; the default) or
    /// staggered (each texel's grid shifted by an eighth of a pixel along both face axes, the
    /// signs set by its atlas column's and row's parity, so the neighbouring texels the query
    /// filters over see an occluder's edge at different places; beyond the paper: on detailed
    /// interiors it agrees better with exact ray casts for a few more runs, on simple scenes at
    /// fine atlases it costs runs for nothing; reports/visibility.md).
    #[arg(long, default_value = "centred", value_name = "GRID")]
    pixel_grid: formats::cube::PixelGrid,
    /// How every texel's cube map lies in the world: turned (the default: one fixed rotation
    /// that takes the world's up axis to the cube's diagonal, so the vertical and horizontal
    /// edges of rooms, columns and frames cross the pixel grid obliquely and the query's filter
    /// places them better; beyond the paper, for as many runs; reports/visibility.md) or world
    /// (the faces on the world's axes, as in the paper).
    #[arg(long, default_value = "turned", value_name = "FRAME")]
    cube_frame: formats::cube::CubeFrame,
    /// Where the depth maps' rays are cast: cpu (the default; --cube-renderer picks how), or gpu
    /// (a BVH traversal in a compute shader on the first GPU wgpu finds, Mesa's lavapipe where
    /// there is none; the CPU still orders the texels, quantises and compresses). A GPU may round
    /// a ray through an edge otherwise than the CPU, so a few pixels may differ from the CPU's
    /// file (reports/bake.md).
    #[arg(long, default_value = "cpu")]
    device: bake::BakeDevice,
    /// How the file stores the runs: packed (run lengths and depth differences as varints before
    /// zstd: a smaller file, the same data in memory) or plain (zstd only, the first format).
    #[arg(long, default_value = "packed")]
    file_coding: FileCoding,
    /// Distance the cube maps sit off the surface, in scene units. Default: 0.05% of the scene
    /// diameter.
    #[arg(long, value_parser = finite_f32)]
    near: Option<f32>,
    /// Bake only chunk I of N (I from 0 to N-1) for a batch farm: the depth maps of one
    /// contiguous slice of the traversal, into a chunk file (default name
    /// <scene>.chunk-I-of-N); `cssm merge` joins the N chunks into the file one bake writes.
    /// In a Slurm job array: --chunk $SLURM_ARRAY_TASK_ID/N; in a Kubernetes indexed Job:
    /// --chunk $JOB_COMPLETION_INDEX/N (docs/batch-bake.md).
    #[arg(long, value_name = "I/N")]
    chunk: Option<formats::cssm::ChunkSpec>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
}

/// `cssm bake`, checked.
pub struct BakeConfig {
    /// Scene directory or mesh file; `None`: the built-in Cornell box.
    pub scene: Option<PathBuf>,
    /// Output file; `None`: `<scene name>.cssm`.
    pub output: Option<PathBuf>,
    /// What to bake, checked by the bake library as far as it can without the scene.
    pub options: bake::BakeOptions,
    /// How the file codes the runs.
    pub file_coding: FileCoding,
    /// `--chunk I/N`: bake this chunk only.
    pub chunk: Option<formats::cssm::ChunkSpec>,
    /// `--json`.
    pub json: bool,
}

impl BakeArgs {
    /// The bake options, checked by the bake library before any scene is loaded (the near
    /// distance against the scene's size when it is); an error names the flag.
    pub fn config(self) -> Result<BakeConfig, String> {
        let options = bake::BakeOptions {
            atlas_resolution: self.atlas,
            cube_resolution: self.cube,
            traversal: self.traversal,
            chart_order: self.chart_order,
            near: self.near,
            run_value: self.run_value,
            merge_short_runs: self.merge_short_runs,
            second_layer: self.second_layer,
            cube_renderer: self.cube_renderer,
            device: self.device,
            pixel_grid: self.pixel_grid,
            cube_frame: self.cube_frame,
        };
        options.check().map_err(|e| cssm::flag_error(&e))?;
        Ok(BakeConfig {
            scene: self.scene,
            output: self.output,
            options,
            file_coding: self.file_coding,
            chunk: self.chunk,
            json: self.json,
        })
    }
}

#[derive(clap::Args)]
pub struct MergeArgs {
    /// The chunk files (cssm bake --chunk I/N), all N of them, in any order.
    #[arg(required = true, value_name = "CHUNKS")]
    pub chunks: Vec<PathBuf>,
    /// Output file. Default: <scene name>.cssm in the current directory.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args)]
pub struct InspectArgs {
    /// The .cssm file.
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args)]
pub struct CheckArgs {
    /// The .cssm file.
    file: PathBuf,
    /// Scene (directory or mesh file) to check against. Default: the one recorded in the file.
    #[arg(long)]
    scene: Option<PathBuf>,
    /// Number of random surface point pairs.
    #[arg(long, default_value_t = 100_000, value_parser = clap::value_parser!(u64).range(1..))]
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
    /// Ask only the sender's cube maps, as the paper does, instead of both points' (their
    /// answers weighted towards the end nearer the occluder; each pair's points both have
    /// texels, as in the runtime's radiosity and final gather).
    #[arg(long)]
    one_end: bool,
    /// Constant depth bias, in multiples of the bake's near distance.
    #[arg(long, default_value_t = QueryOptions::default().bias_near, value_parser = bias)]
    bias_near: f32,
    /// Depth bias proportional to the query depth.
    #[arg(long, default_value_t = QueryOptions::default().bias_relative, value_parser = bias)]
    bias_relative: f32,
    /// Exit with status 1 when the agreement over the pairs that exchange light is below this
    /// fraction.
    #[arg(long, value_parser = fraction)]
    min_agreement: Option<f64>,
    /// Print the result as one JSON object.
    #[arg(long)]
    json: bool,
    /// Move the rigid object NAME (an `[[objects]]` entry) before measuring, to translation
    /// X,Y,Z and, optionally, rotation RX,RY,RZ (degrees, as scene.toml's rotation_deg; its
    /// scale stays): visibility between moving objects (each object's own maps for itself,
    /// the others' coherent shadow maps) against ray casts of the moved scene. Repeatable.
    #[arg(long, value_name = "NAME=X,Y,Z[,RX,RY,RZ]", allow_hyphen_values = true, value_parser = parse_place)]
    place: Vec<Place>,
}

/// `--place NAME=X,Y,Z[,RX,RY,RZ]` of `cssm check`.
#[derive(Clone, Debug, PartialEq)]
pub struct Place {
    /// The `[[objects]]` name.
    pub name: String,
    /// Its new translation.
    pub translation: glam::Vec3,
    /// Its new rotation, XYZ Euler angles in degrees (zero when not given).
    pub rotation_deg: glam::Vec3,
}

fn parse_place(s: &str) -> Result<Place, String> {
    let Some((name, numbers)) = s.split_once('=') else {
        return Err(format!("'{s}' is not NAME=X,Y,Z[,RX,RY,RZ]"));
    };
    if name.is_empty() {
        return Err(format!("'{s}' names no object"));
    }
    let numbers: Vec<f32> = numbers
        .split(',')
        .map(finite_f32)
        .collect::<Result<_, _>>()
        .map_err(|e| format!("'{s}': {e}"))?;
    let (translation, rotation) = match numbers[..] {
        [x, y, z] => ([x, y, z], [0.0; 3]),
        [x, y, z, a, b, c] => ([x, y, z], [a, b, c]),
        _ => {
            return Err(format!(
                "'{s}': expected 3 or 6 numbers after the name, got {}",
                numbers.len()
            ));
        }
    };
    Ok(Place {
        name: name.to_string(),
        translation: translation.into(),
        rotation_deg: rotation.into(),
    })
}

/// `cssm check`, as library types.
pub struct CheckConfig {
    /// The .cssm file.
    pub file: PathBuf,
    /// Scene directory or mesh file; `None`: the one recorded in the file.
    pub scene: Option<PathBuf>,
    /// Random surface point pairs.
    pub pairs: u64,
    /// Seed of the pairs.
    pub seed: u64,
    /// How the CSSM is queried.
    pub query: QueryOptions,
    /// Exit status 1 below this agreement over the pairs that exchange light.
    pub min_agreement: Option<f64>,
    /// `--json`.
    pub json: bool,
    /// `--place`: rigid objects moved before measuring.
    pub place: Vec<Place>,
}

impl CheckArgs {
    /// The query options and the rest, as the bake library's check takes them.
    pub fn config(self) -> CheckConfig {
        CheckConfig {
            file: self.file,
            scene: self.scene,
            pairs: self.pairs,
            seed: self.seed,
            query: QueryOptions {
                bias_near: self.bias_near,
                bias_relative: self.bias_relative,
                pcf: !self.no_pcf,
                sender_filter: !self.no_sender_filter,
                both_ends: !self.one_end,
            },
            min_agreement: self.min_agreement,
            json: self.json,
            place: self.place,
        }
    }
}

/// `cssm report error --help`'s text after the options: the method table, then examples.
fn error_after_help() -> String {
    format!(
        "Methods and their options (--method NAME:OPTION=VALUE,OPTION=VALUE; --bounces and \
         --samples fill those options of every variant that has them and does not set them):\n{}\n\
         Every method marked [needs .cssm] gets one baked in memory per scene (--atlas, --cube).\n\n\
         Examples:\n  \
         cssm report error --method direct --method lightcuts --out /tmp/error\n  \
         cssm report error --method hrc --method lightmap --method lightcuts:jitter=true --samples 4096 --out /tmp/error\n  \
         cssm report error --scene reports/scenes/sibenik --method direct --size 320x240 --reference-cache --out /tmp/sibenik",
        runtime::method::describe_methods()
    )
}

#[derive(clap::Args)]
pub struct ErrorArgs {
    /// Scene directory or mesh file (.obj, .gltf, .glb); repeatable. Default: the built-in
    /// Cornell box and the Cornell box with a glossy floor (scenes/cornell-box,
    /// scenes/cornell-glossy).
    #[arg(long = "scene", value_name = "SCENE")]
    scenes: Vec<PathBuf>,
    /// A method variant to measure, NAME or NAME:OPTION=VALUE,OPTION=VALUE (for example
    /// `lightcuts:bounces=2,jitter=true`; the list below); repeatable, at least one.
    #[arg(long = "method", value_name = "SPEC", required = true)]
    methods: Vec<String>,
    /// Image size WIDTHxHEIGHT.
    #[arg(long, default_value = "160x120", value_parser = parse_size)]
    size: (u32, u32),
    /// Paths per pixel of the reference (and of `--method reference` unless its spec sets
    /// `samples`).
    #[arg(long, default_value_t = 1024)]
    samples: u32,
    /// Indirect bounces of the reference and of every variant with a `bounces` option that does
    /// not set it.
    #[arg(long, default_value_t = 1)]
    bounces: u32,
    /// Which light the images hold and the figures measure: direct, indirect or full.
    #[arg(long, default_value = "indirect")]
    component: Component,
    /// Exposure in stops of every PNG, the strip and the FLIP images (radiance is scaled by
    /// 2^EV before tone mapping; also the oracle's tone mapping of hrc, lightmap, lightcuts).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = stops)]
    exposure: f32,
    /// Shadow-map resolution in texels per side.
    #[arg(long, default_value_t = runtime::common::shadow_map::DEFAULT_RESOLUTION)]
    shadow_resolution: u32,
    /// CSSM methods: ask only the receiver's cube maps for each sender, as the paper does,
    /// instead of both ends' answers combined (the default; see `cssm check --one-end`).
    #[arg(long)]
    one_end: bool,
    /// Atlas resolution of the .cssm baked in memory for the methods that need one (32 to 1024).
    #[arg(long, default_value_t = 64)]
    atlas: u32,
    /// Cube-map face resolution of that bake (8 to 128).
    #[arg(long, default_value_t = 32)]
    cube: u32,
    /// Directory of the report (created; only the report's own files in it are replaced, and
    /// never through a symbolic link: a link under one of their names is refused).
    #[arg(long)]
    out: PathBuf,
    /// Reuse OUT/SCENE-reference.exr when its sidecar SCENE-reference.json records the same
    /// scene files, size, samples, bounces and component, instead of path tracing again.
    #[arg(long)]
    reference_cache: bool,
    /// Frames each GPU variant renders before its image is measured, the camera at rest: the
    /// temporally filtered methods (ssil) converge over a few.
    #[arg(long, default_value_t = 1)]
    frames: u32,
}

/// One `--method` of `cssm report error`, checked by the method table.
pub struct Variant {
    /// The spec as the user wrote it, spaces trimmed (`lightcuts:bounces=2`).
    pub spec: String,
    /// The method.
    pub method: &'static MethodEntry,
    /// The options the spec set, and `--bounces` / `--samples` where it did not.
    pub values: OptionValues,
    /// Every option of the method, checked.
    pub resolved: Resolved,
}

/// `cssm report error`, checked.
pub struct ErrorConfig {
    /// Scene directories or mesh files; empty: the built-in scenes.
    pub scenes: Vec<PathBuf>,
    /// The variants, in the order given.
    pub variants: Vec<Variant>,
    /// Image size, exposure (a multiplier) and shadow-map resolution, checked.
    pub frame: runtime::frame::FrameSettings,
    /// The reference's options (`samples`, `bounces`), checked by its table entry.
    pub reference: Resolved,
    /// Which light the images hold.
    pub component: Component,
    /// The in-memory bake of the methods that need a `.cssm`.
    pub bake: bake::BakeOptions,
    /// Report directory.
    pub out: PathBuf,
    /// `--reference-cache`.
    pub reference_cache: bool,
    /// Frames rendered per GPU variant, 1..=[`MAX_FRAMES`].
    pub frames: u32,
}

impl ErrorArgs {
    /// Every spec parsed and resolved against the method table, the reference's options, the
    /// frame settings and the bake options checked; an error names the spec or the flag.
    pub fn config(self) -> Result<ErrorConfig, String> {
        let checked = MeasureFlags {
            samples: self.samples,
            bounces: self.bounces,
            size: self.size,
            exposure: self.exposure,
            shadow_resolution: self.shadow_resolution,
            one_end: self.one_end,
            atlas: self.atlas,
            cube: self.cube,
            frames: self.frames,
        }
        .check()?;
        Ok(ErrorConfig {
            scenes: self.scenes,
            variants: parse_variants(&self.methods, self.bounces, self.samples)?,
            frame: checked.frame,
            reference: checked.reference,
            component: self.component,
            bake: checked.bake,
            out: self.out,
            reference_cache: self.reference_cache,
            frames: self.frames,
        })
    }
}

/// The flags `cssm report error` and `cssm compare` share.
struct MeasureFlags {
    samples: u32,
    bounces: u32,
    size: (u32, u32),
    exposure: f32,
    shadow_resolution: u32,
    one_end: bool,
    atlas: u32,
    cube: u32,
    frames: u32,
}

/// [`MeasureFlags`], checked.
struct MeasureChecked {
    reference: Resolved,
    frame: runtime::frame::FrameSettings,
    bake: bake::BakeOptions,
}

impl MeasureFlags {
    /// The reference's options checked by its table entry, the frame settings by the runtime,
    /// the bake options by the bake library, the frame count against [`MAX_FRAMES`]; an error
    /// names the flag.
    fn check(&self) -> Result<MeasureChecked, String> {
        // Until converged, the reference and each method would stop where their own light
        // says: a comparison needs them to compute the same bounces.
        if self.bounces == 0 {
            return Err(
                "--bounces 0 (until converged) cannot be compared: the reference and \
                        the methods must compute the same bounces; give a count, 1 to 8"
                    .into(),
            );
        }
        let reference_entry = runtime::method::find("reference").map_err(|e| e.to_string())?;
        for (name, value) in [("samples", self.samples), ("bounces", self.bounces)] {
            if let Some(spec) = reference_entry.option(name) {
                spec.check(OptionValue::Count(value))
                    .map_err(|e| format!("--{e}"))?;
            }
        }
        let mut values = OptionValues::default();
        values.set("samples", OptionValue::Count(self.samples));
        values.set("bounces", OptionValue::Count(self.bounces));
        let reference = reference_entry
            .resolve(&values)
            .map_err(|e| e.to_string())?;
        let frame = runtime::frame::FrameSettings {
            width: self.size.0,
            height: self.size.1,
            exposure: self.exposure.exp2(),
            shadow_resolution: self.shadow_resolution,
            visibility: QueryOptions {
                both_ends: !self.one_end,
                ..QueryOptions::default()
            },
        };
        frame.check().map_err(|e| e.to_string())?;
        let bake = bake::BakeOptions {
            atlas_resolution: self.atlas,
            cube_resolution: self.cube,
            ..Default::default()
        };
        bake.check().map_err(|e| cssm::flag_error(&e))?;
        if !(1..=MAX_FRAMES).contains(&self.frames) {
            return Err(format!(
                "--frames {} is out of range 1..={MAX_FRAMES}",
                self.frames
            ));
        }
        Ok(MeasureChecked {
            reference,
            frame,
            bake,
        })
    }
}

/// Each spec parsed ([`parse_variant`]); a spec given twice is refused.
fn parse_variants(specs: &[String], bounces: u32, samples: u32) -> Result<Vec<Variant>, String> {
    let mut variants: Vec<Variant> = Vec::new();
    for text in specs {
        let variant = parse_variant(text, bounces, samples)?;
        if let Some(other) = variants.iter().find(|v| v.spec == variant.spec) {
            return Err(format!("--method {}: given twice", other.spec));
        }
        variants.push(variant);
    }
    Ok(variants)
}

/// `cssm compare --help`'s text after the options: the method table, then examples.
fn compare_after_help() -> String {
    format!(
        "Methods and their options (--methods NAME:OPTION=VALUE,OPTION=VALUE,NAME,...; --bounces \
         and --samples fill those options of every method that has them and does not set them):\n{}\n\
         Every method marked [needs .cssm] gets one baked in memory per scene (--atlas, --cube).\n\n\
         Examples:\n  \
         cssm compare --out /tmp/compare                       # the built-in boxes, every method\n  \
         cssm compare scenes/cornell-box reports/scenes/sibenik --methods rsm,vct,vf --size 640x480\n  \
         cssm compare --methods lightcuts:bounces=2,jitter=true,ssil --bounces 2 --frames 16\n  \
         cssm compare ../shared/scenes/sibenik --atlas 256 --samples 4096 --out /tmp/sibenik",
        runtime::method::describe_methods()
    )
}

#[derive(clap::Args)]
pub struct CompareArgs {
    /// Scene directories or mesh files (.obj, .gltf, .glb). Default: the built-in Cornell box and
    /// the Cornell box with a glossy floor (scenes/cornell-box, scenes/cornell-glossy).
    #[arg(value_name = "SCENE")]
    scenes: Vec<PathBuf>,
    /// Methods to compare, comma-separated, each NAME or NAME:OPTION=VALUE,OPTION=VALUE (a part
    /// with `=` and no `:` is an option of the method before it: `lightcuts:bounces=2,jitter=true,rsm`
    /// is two methods); repeatable. Default: every method of the table but the path tracer.
    #[arg(long = "methods", value_name = "LIST")]
    methods: Vec<String>,
    /// Image size WIDTHxHEIGHT.
    #[arg(long, default_value = "320x240", value_parser = parse_size)]
    size: (u32, u32),
    /// Paths per pixel of the reference, split into two independent halves whose difference
    /// measures its noise.
    #[arg(long, default_value_t = 1024)]
    samples: u32,
    /// Indirect bounces of the reference and of every method with a `bounces` option that does
    /// not set it (the methods without one compute a single bounce).
    #[arg(long, default_value_t = 1)]
    bounces: u32,
    /// Frames each GPU method renders before its image is measured, the camera at rest (ssil's
    /// temporal filter converges over a few).
    #[arg(long, default_value_t = 1)]
    frames: u32,
    /// Exposure in stops of every tone-mapped image and of FLIP.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = stops)]
    exposure: f32,
    /// Shadow-map resolution in texels per side.
    #[arg(long, default_value_t = runtime::common::shadow_map::DEFAULT_RESOLUTION)]
    shadow_resolution: u32,
    /// CSSM methods: ask only the receiver's cube maps for each sender, as the paper does,
    /// instead of both ends' answers combined (the default; see `cssm check --one-end`).
    #[arg(long)]
    one_end: bool,
    /// Atlas resolution of the .cssm baked in memory for the methods that need one (32 to 1024).
    #[arg(long, default_value_t = 64)]
    atlas: u32,
    /// Cube-map face resolution of that bake (8 to 128).
    #[arg(long, default_value_t = 32)]
    cube: u32,
    /// Directory of the page (created; only the page's own files in it are replaced, and never
    /// through a symbolic link: a link under one of their names is refused): index.html,
    /// chart.svg, compare.csv, compare.json, compare.md, images/ and reference-cache/.
    #[arg(long, default_value = "compare")]
    out: PathBuf,
    /// Path trace the references again even where OUT/reference-cache/ holds one of the same
    /// scene files and settings.
    #[arg(long)]
    no_cache: bool,
}

/// `cssm compare`, checked.
pub struct CompareConfig {
    /// Scene directories or mesh files; empty: the built-in scenes.
    pub scenes: Vec<PathBuf>,
    /// The methods, in the order given.
    pub variants: Vec<Variant>,
    /// Image size, exposure (a multiplier) and shadow-map resolution, checked.
    pub frame: runtime::frame::FrameSettings,
    /// Exposure in stops, as given.
    pub exposure_stops: f32,
    /// The reference's options (`samples`, `bounces`), checked by its table entry.
    pub reference: Resolved,
    /// The in-memory bake of the methods that need a `.cssm`.
    pub bake: bake::BakeOptions,
    /// Page directory.
    pub out: PathBuf,
    /// Whether cached references may be reused.
    pub reuse_references: bool,
    /// Frames rendered per GPU method, 1..=[`MAX_FRAMES`].
    pub frames: u32,
}

impl CompareArgs {
    /// The methods split ([`split_methods`]), parsed and resolved against the method table, and
    /// the shared flags checked; an error names the method or the flag.
    pub fn config(self) -> Result<CompareConfig, String> {
        let checked = MeasureFlags {
            samples: self.samples,
            bounces: self.bounces,
            size: self.size,
            exposure: self.exposure,
            shadow_resolution: self.shadow_resolution,
            one_end: self.one_end,
            atlas: self.atlas,
            cube: self.cube,
            frames: self.frames,
        }
        .check()?;
        let specs: Vec<String> = if self.methods.is_empty() {
            runtime::METHODS
                .iter()
                .filter(|m| m.on_gpu())
                .map(|m| m.name.to_string())
                .collect()
        } else {
            self.methods.iter().flat_map(|l| split_methods(l)).collect()
        };
        if specs.is_empty() {
            return Err("--methods: no method given".into());
        }
        Ok(CompareConfig {
            scenes: self.scenes,
            variants: parse_variants(&specs, self.bounces, self.samples)?,
            frame: checked.frame,
            exposure_stops: self.exposure,
            reference: checked.reference,
            bake: checked.bake,
            out: self.out,
            reuse_references: !self.no_cache,
            frames: self.frames,
        })
    }
}

/// A `--methods` list split into method specs: at each comma, unless the part after it holds
/// `=` and no `:` (an option of the method before it). Empty parts are dropped.
fn split_methods(list: &str) -> Vec<String> {
    let mut specs: Vec<String> = Vec::new();
    for part in list.split(',') {
        let part = part.trim();
        if part.is_empty() {
            continue;
        }
        match specs.last_mut() {
            Some(last) if part.contains('=') && !part.contains(':') && last.contains(':') => {
                last.push(',');
                last.push_str(part);
            }
            _ => specs.push(part.to_string()),
        }
    }
    specs
}

/// `NAME` or `NAME:OPTION=VALUE,OPTION=VALUE`, checked against the method table; `bounces` and
/// `samples` filled from the flags where the method has them and the spec does not set them.
/// Errors name the spec.
fn parse_variant(text: &str, bounces: u32, samples: u32) -> Result<Variant, String> {
    let fail = |message: String| format!("--method {text}: {message}");
    let (name, options) = match text.split_once(':') {
        Some((name, options)) => (name.trim(), Some(options)),
        None => (text.trim(), None),
    };
    let method = runtime::method::find(name).map_err(|e| fail(e.to_string()))?;
    let mut values = OptionValues::default();
    let mut given = Vec::new();
    for part in options.into_iter().flat_map(|o| o.split(',')) {
        let (key, value) = part
            .split_once('=')
            .ok_or_else(|| fail(format!("'{}' is not OPTION=VALUE", part.trim())))?;
        let (key, value) = (key.trim(), value.trim());
        let spec = method.option(key).ok_or_else(|| {
            let known: Vec<&str> = method.options.iter().map(|o| o.name).collect();
            fail(format!(
                "method {method} has no option '{key}' (its options: {})",
                if known.is_empty() {
                    "none".into()
                } else {
                    known.join(", ")
                }
            ))
        })?;
        if values.get(spec.name).is_some() {
            return Err(fail(format!("option '{key}' is given twice")));
        }
        values.set(spec.name, spec.parse(value).map_err(fail)?);
        given.push(format!("{key}={value}"));
    }
    for (option, value) in [("bounces", bounces), ("samples", samples)] {
        if method.option(option).is_some() && values.get(option).is_none() {
            values.set(option, OptionValue::Count(value));
        }
    }
    let resolved = method.resolve(&values).map_err(|e| fail(e.to_string()))?;
    let spec = if given.is_empty() {
        method.name.to_string()
    } else {
        format!("{}:{}", method.name, given.join(","))
    };
    Ok(Variant {
        spec,
        method,
        values,
        resolved,
    })
}

/// `cssm render --help`'s text after the options: the method table, then examples.
fn render_after_help() -> String {
    format!(
        "Methods and their options (--set NAME=VALUE; --bounces, --threshold and --samples are \
         short for those options):\n{}\n\
         Every method marked [needs .cssm] takes the scene's .cssm: --cssm FILE, else one is \
         baked first (atlas 64, cube 32; a few seconds for the Cornell box).\n\n\
         Examples:\n  cssm render --out cornell.png\n  \
         cssm bake -o cornell-box.cssm && cssm render --cssm cornell-box.cssm --method lightcuts --bounces 2 --out gi.png\n  \
         cssm render scenes/cornell-glossy --method lightcuts --frames 16 --out glossy.png\n  \
         cssm render --method lightmap --component indirect --exr indirect.exr\n  \
         cssm render --method reference --bounces 3 --samples 1024 --exr truth.exr\n  \
         cssm render --method rsm --component indirect --set visibility=none --out rsm-no-visibility.png\n  \
         cssm render scenes/cornell-glossy --method vct --set resolution=64 --out vct.png\n  \
         cssm render --method ssil --frames 16 --set visibility=none --out ssil.png\n  \
         cssm render scenes/cornell-glossy --method direct --out glossy.png --exr glossy.exr --size 1280x720 --timings\n  \
         cssm render --camera=400,300,-700,278,273,0 --light=278,540,279.5,0.2,-1,0 --out moved.png   # cssm view prints these\n  \
         cssm render scenes/my-scene --cssm my-scene.cssm --method lightcuts --animate --frames 48 --out frames/   # frames/frame-0000.png ... and frames/animation.gif",
        runtime::method::describe_methods()
    )
}

/// `cssm view --help`'s text after the options: the keys, then examples.
fn view_after_help() -> String {
    "Mouse and keys:\n  \
     left drag            orbit about the point the camera looks at\n  \
     wheel                dolly towards it and away\n  \
     W A S D / Q E        fly forward, left, back, right / down, up (a press steps; held, the \
     camera flies on every frame)\n  \
     right drag           aim the first spot light\n  \
     shift + right drag   move the first spot light (in the view plane)\n  \
     Tab / shift + Tab    next / previous method of the table (`cssm render --help` lists them; \
     those needing a .cssm are skipped when none is loaded)\n  \
     C                    cycle the component: direct, indirect, full\n  \
     P                    play / pause the objects' animation ([objects.animation], else each \
     rigid object turning about the vertical, as `cssm render --animate`), at the frame time\n  \
     [ / ]                one bounce fewer / more (methods with a `bounces` option)\n  \
     - / =                halve / double the oracle threshold (methods with `threshold`)\n  \
     F12                  write a screenshot, cssm-view-NNNN.png in the current directory \
     (and .exr with --shot-exr), and print the `cssm render` flags of the same image\n  \
     H                    show / hide the overlay: settings, camera, light, GPU time per pass, \
     frame time; menus for method, component and bounces (never in a screenshot)\n  \
     Esc                  quit\n\n\
     Script (--script FILE): one step a line, one step per frame, # starts a comment; each \
     step goes through the window's own mouse and key handling (DX, DY are pixels of mouse \
     motion).\n  \
     orbit DX DY          left drag by DX, DY pixels\n  \
     drag-light DX DY     right drag (aim the light)\n  \
     move-light DX DY     shift + right drag (move the light)\n  \
     dolly LINES          turn the wheel LINES lines (negative: away)\n  \
     key KEY              press and release KEY: a character (c, [, ], -, =, h, w, ...), or \
     Tab, F12, Escape; shift+KEY holds shift\n  \
     hold KEY N           press KEY, let N frames render, release it (W A S D Q E fly)\n  \
     wait N               let N frames render before the next step (they accumulate)\n  \
     animate SECONDS      move the objects' animation SECONDS on (exactly; P plays it at the \
     frame time)\n  \
     screenshot PATH      write the last frame: PNG, or with .exr the linear radiance; print \
     the `cssm render` flags of the same image\n  \
     quit                 close the window (at the end of the file it stays open)\n\n\
     Examples:\n  cssm view\n  \
     cssm bake -o cornell-box.cssm && cssm view --cssm cornell-box.cssm --method lightcuts\n  \
     cssm view scenes/cornell-glossy --method vct --size 800x600\n  \
     xvfb-run -a cssm view --method direct --size 64x48 --screenshot shot.png --frames 1\n  \
     printf 'orbit 40 0\\nkey Tab\\nwait 2\\nscreenshot a.png\\nquit\\n' > s.txt && xvfb-run -a cssm view --size 64x48 --script s.txt"
        .to_string()
}

#[derive(clap::Args)]
pub struct ViewArgs {
    /// Scene directory or mesh file (.obj, .gltf, .glb). Default: the built-in Cornell box.
    scene: Option<PathBuf>,
    /// Method to start with (`cssm render --help` lists them; Tab switches in the window).
    /// The default, lightmap, is `cssm render`'s.
    #[arg(long, default_value = "lightmap", value_parser = parse_method)]
    method: &'static MethodEntry,
    /// The scene's baked CSSM (`cssm bake`), for the methods that need one. Default: bake one
    /// in memory at atlas 64 (or the smallest larger page that holds the charts), cube 32 when
    /// the first method needs it; without one, Tab skips the methods that need it.
    #[arg(long)]
    cssm: Option<PathBuf>,
    /// Image (and window) size WIDTHxHEIGHT. Default: the scene camera's resolution.
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Exposure in stops (radiance is scaled by 2^EV before tone mapping). Fixed in the window
    /// (`cssm render` meters its own when not given one; a screenshot prints the flag).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = stops)]
    exposure: f32,
    /// Shadow-map resolution in texels per side.
    #[arg(long, default_value_t = runtime::common::shadow_map::DEFAULT_RESOLUTION)]
    shadow_resolution: u32,
    /// CSSM methods: ask only the receiver's cube maps (see `cssm render --one-end`).
    #[arg(long)]
    one_end: bool,
    /// Indirect bounces (the option `bounces`). Default: the method's.
    #[arg(long)]
    bounces: Option<u32>,
    /// Oracle threshold (the option `threshold`). Default: the method's.
    #[arg(long, allow_negative_numbers = true, value_parser = finite_f32)]
    threshold: Option<f32>,
    /// Set a method option, NAME=VALUE (`cssm render --help` lists them); repeatable.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
    /// Which light the image holds: direct, indirect or full (C switches in the window).
    #[arg(long, default_value = "full")]
    component: Component,
    /// For scripts: render --frames frames in the window, write this image and exit: a PNG
    /// (what F12 writes: byte for byte what `cssm render --out` writes for the same options),
    /// or with the extension .exr the linear radiance (what `cssm render --exr` writes).
    #[arg(long, value_name = "PATH")]
    screenshot: Option<PathBuf>,
    /// Frames to render before the --screenshot, 1 to 4096 (as `cssm render --frames`).
    #[arg(long, default_value_t = 1, requires = "screenshot")]
    frames: u32,
    /// Feed the window the input steps of this file, one per frame (the format is below);
    /// its screenshots print the `cssm render` flags of the same image.
    #[arg(long, value_name = "FILE", conflicts_with = "screenshot")]
    script: Option<PathBuf>,
    /// F12 also writes the linear radiance, cssm-view-NNNN.exr (what `cssm render --exr`
    /// writes).
    #[arg(long)]
    shot_exr: bool,
    /// Start with this camera eye and target, EX,EY,EZ,TX,TY,TZ (as `cssm render --camera`).
    #[arg(long, value_name = "EYE,TARGET", allow_hyphen_values = true, value_parser = parse_pose)]
    camera: Option<Pose>,
    /// Start with this first spot light, PX,PY,PZ,DX,DY,DZ (as `cssm render --light`).
    #[arg(long, value_name = "POSITION,DIRECTION", allow_hyphen_values = true, value_parser = parse_pose)]
    light: Option<Pose>,
}

/// `cssm view`, checked: the render configuration `cssm render` would use (its `out` is the
/// screenshot), and whether the window closes after the screenshot.
pub struct ViewConfig {
    /// What the window renders, as `cssm render` would.
    pub render: RenderConfig,
    /// `--screenshot`: write the image after `render.frames` frames and exit.
    pub screenshot: Option<PathBuf>,
    /// `--script`: input steps to feed the window.
    pub script: Option<PathBuf>,
    /// `--shot-exr`: F12 also writes the radiance as OpenEXR.
    pub shot_exr: bool,
}

impl ViewArgs {
    /// The render configuration of the first method, checked as `cssm render` checks it.
    pub fn config(self) -> Result<ViewConfig, String> {
        if !(1..=MAX_FRAMES).contains(&self.frames) {
            return Err(format!(
                "--frames {} is out of range 1..={MAX_FRAMES}",
                self.frames
            ));
        }
        // An interactive window accumulates without end: the methods that jitter do (as
        // `cssm render --frames N` with N > 1); a screenshot takes exactly `cssm render`'s
        // options for its frame count.
        let jitter_frames = if self.screenshot.is_some() {
            self.frames
        } else {
            MAX_FRAMES
        };
        let values = option_values(
            self.method,
            [
                ("bounces", self.bounces.map(OptionValue::Count)),
                ("threshold", self.threshold.map(OptionValue::Number)),
                ("samples", None),
            ],
            jitter_frames,
            &self.set,
        )?;
        let resolved = self.method.resolve(&values).map_err(|e| e.to_string())?;
        if !self.method.on_gpu() {
            return Err(format!(
                "method '{}' runs on the CPU, not in the window; `cssm render --method {}` \
                 runs it",
                self.method, self.method
            ));
        }
        Ok(ViewConfig {
            render: RenderConfig {
                scene: self.scene,
                method: self.method,
                values,
                resolved,
                out: self
                    .screenshot
                    .clone()
                    .unwrap_or_else(|| PathBuf::from("cssm-view.png")),
                exr: None,
                size: self.size,
                exposure: Some(self.exposure),
                shadow_resolution: self.shadow_resolution,
                visibility: QueryOptions {
                    both_ends: !self.one_end,
                    ..QueryOptions::default()
                },
                timings: false,
                stats: false,
                cssm: self.cssm,
                frames: self.frames,
                component: self.component,
                camera: self.camera,
                light: self.light,
                animate: None,
                time: None,
            },
            screenshot: self.screenshot,
            script: self.script,
            shot_exr: self.shot_exr,
        })
    }
}

#[derive(clap::Args)]
pub struct RenderArgs {
    /// Scene directory or mesh file (.obj, .gltf, .glb). Default: the built-in Cornell box.
    scene: Option<PathBuf>,
    /// Rendering method (see the list below). The default, lightmap, is the hierarchical
    /// radiosity's converged solution looked up per pixel (a .cssm baked first when none is
    /// given); direct is instant but holds the lights' direct light only.
    #[arg(long, default_value = "lightmap", value_parser = parse_method)]
    method: &'static MethodEntry,
    /// Output PNG (tone-mapped sRGB), default render.png. With --animate: the directory the
    /// frames go into (created if missing; required).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also write linear radiance to this OpenEXR file.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Image size WIDTHxHEIGHT. Default: the scene camera's resolution.
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Exposure in stops (radiance is scaled by 2^EV before tone mapping). Default: automatic,
    /// the log-average luminance of the image's lit pixels at middle grey (with --animate, the
    /// first frame's for every frame), printed so that --exposure can fix it; the CSSM methods'
    /// oracle meters at 0 then.
    #[arg(long, allow_negative_numbers = true, value_parser = stops)]
    exposure: Option<f32>,
    /// Shadow-map resolution in texels per side.
    #[arg(long, default_value_t = runtime::common::shadow_map::DEFAULT_RESOLUTION)]
    shadow_resolution: u32,
    /// CSSM methods: ask only the receiver's cube maps for each sender, as the paper does,
    /// instead of both ends' answers combined (the default; see `cssm check --one-end`).
    #[arg(long)]
    one_end: bool,
    /// Print GPU milliseconds per pass (timestamp queries): the first frame, which also runs
    /// the view-independent passes, and the last (one more frame is rendered to time it warm).
    #[arg(long)]
    timings: bool,
    /// Print what the passes do, counted by their CPU twins on a sample of their receivers (the
    /// radiosity gather of hrc, lightmap and lightcuts, lightcuts' final gather): nodes visited
    /// and queried per receiver, CSSM taps, search steps and bytes, the threads against the
    /// device's, their warps replayed (lane efficiency, 32-byte sectors per load), and the GPU
    /// milliseconds a cost model of the NVIDIA H200 predicts from them (reports/runtime.md).
    #[arg(long)]
    stats: bool,
    /// The scene's baked CSSM (`cssm bake`), for the methods that need one. Default: bake one
    /// in memory at atlas 64 (or the smallest larger page that holds the scene's charts),
    /// cube 32.
    #[arg(long)]
    cssm: Option<PathBuf>,
    /// Indirect bounces (the option `bounces`; lightcuts: the final gather is the last).
    /// Default: the method's.
    #[arg(long)]
    bounces: Option<u32>,
    /// Oracle threshold (the option `threshold`, §4.3): a sender is refined while the
    /// tone-mapped upper bound of what it sends is above this; smaller is slower and closer.
    #[arg(long, allow_negative_numbers = true, value_parser = finite_f32)]
    threshold: Option<f32>,
    /// Paths per pixel of `--method reference` (the option `samples`).
    #[arg(long)]
    samples: Option<u32>,
    /// Set a method option, NAME=VALUE (see the list below); repeatable.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
    /// Frames to render and average, 1 to 4096, default 1 (lightcuts: every frame jitters
    /// its senders over their nodes' surfaces, §4.5, so the average converges for glossy
    /// scenes; ssil: every frame draws new samples and its temporal filter blends them into the
    /// history). With --animate: the number of animation frames, 1 to 4096 (default: --fps
    /// times the duration).
    #[arg(long)]
    frames: Option<u32>,
    /// Render the scene's animation (scene.toml's [objects.animation], docs/scene-format.md)
    /// into the directory --out: frame-0000.png, frame-0001.png, ... and animation.gif, with one
    /// renderer that moves the objects between frames (set_object_transform; nothing is
    /// reloaded). Frame i shows the time i x duration / frames, so a looping animation's last
    /// frame leads back into its first; each frame is rendered once (no averaging). Where
    /// some objects have an animation, the others stand still; a scene whose objects have none
    /// gets each rigid [[objects]] entry spun one full turn about the vertical axis (the
    /// camera's up) through the centre of its bounding box, over --duration (default 4 s).
    /// The objects' shadows, visibility and atlas texels follow them, so the light they
    /// receive and send moves with them. Existing frames are not overwritten
    /// without --overwrite; every file is written under a temporary name and renamed, so none
    /// is ever half-written.
    #[arg(long)]
    animate: bool,
    /// --animate: frames per second, default 24 (sets the frame count from the duration, or,
    /// with --frames, the duration from the frame count; the GIF plays at this rate).
    #[arg(long, requires = "animate", value_parser = positive_f32)]
    fps: Option<f32>,
    /// --animate: seconds of animation to render from time 0. Default: the scene's animation's
    /// duration (its longest object's: the last keyframe's time, twice that for ping-pong, or
    /// one full spin), 4 s for the default spin. At most two of --frames, --fps and --duration.
    #[arg(long, requires = "animate", value_parser = positive_f32)]
    duration: Option<f32>,
    /// --animate: replace the frames and animation.gif already in --out.
    #[arg(long, requires = "animate")]
    overwrite: bool,
    /// --animate: write the PNG frames only, no animation.gif.
    #[arg(long, requires = "animate")]
    no_gif: bool,
    /// Place the moving objects where the animation has them after SECONDS (the scene's
    /// [objects.animation], else the default spin of --animate) and render that one image;
    /// `cssm view` prints it once its animation has moved.
    #[arg(long, value_name = "SECONDS", conflicts_with = "animate", allow_negative_numbers = true, value_parser = finite_f32)]
    time: Option<f32>,
    /// Which light the image holds: direct, indirect or full.
    #[arg(long, default_value = "full")]
    component: Component,
    /// The camera's eye and target, EX,EY,EZ,TX,TY,TZ, instead of the scene's (its up and
    /// field of view stay); `cssm view` prints the camera it ends with in this form.
    #[arg(long, value_name = "EYE,TARGET", allow_hyphen_values = true, value_parser = parse_pose)]
    camera: Option<Pose>,
    /// The first spot light's position and direction, PX,PY,PZ,DX,DY,DZ, instead of the
    /// scene's (its cone and intensity stay); `cssm view` prints the light it ends with.
    #[arg(long, value_name = "POSITION,DIRECTION", allow_hyphen_values = true, value_parser = parse_pose)]
    light: Option<Pose>,
}

fn parse_method(s: &str) -> Result<&'static MethodEntry, String> {
    runtime::method::find(s).map_err(|e| e.to_string())
}

/// `WIDTHxHEIGHT`; the range is the renderer's to check.
/// A flag's number, finite: NaN passes no comparison (`--min-agreement NaN` would never
/// fail) and an infinity poisons every pixel it reaches.
fn finite_f32(s: &str) -> Result<f32, String> {
    let v: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(format!("'{s}' is not a finite number"))
    }
}

/// A finite number above 0 (`--fps`, `--duration`).
fn positive_f32(s: &str) -> Result<f32, String> {
    match finite_f32(s)? {
        v if v > 0.0 => Ok(v),
        v => Err(format!("{v} is not above 0")),
    }
}

/// A depth bias: finite and not negative.
fn bias(s: &str) -> Result<f32, String> {
    match finite_f32(s)? {
        v if v >= 0.0 => Ok(v),
        v => Err(format!("{v} is negative; a bias is 0 or more")),
    }
}

/// An exposure in stops, from -64 to 64 (2^64 is beyond any radiance this renders).
fn stops(s: &str) -> Result<f32, String> {
    match finite_f32(s)? {
        v if (-64.0..=64.0).contains(&v) => Ok(v),
        v => Err(format!("{v} is not a number of stops from -64 to 64")),
    }
}

/// A fraction from 0 to 1.
fn fraction(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a number"))?;
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("'{s}' is not a fraction from 0 to 1"))
    }
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT (for example 640x480)"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{s}': each side must be a whole number"))
    };
    Ok((parse(w)?, parse(h)?))
}

/// A placement given on the command line: `--camera EYE,TARGET` or `--light POSITION,DIRECTION`,
/// six numbers. `cssm view` prints the ones it ends with (`Pose`'s `Display`, the shortest
/// text that parses back to the same `f32`s), so that `cssm render` reproduces its image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// The camera's eye, or the light's position.
    pub position: glam::Vec3,
    /// The camera's target (the point looked at), or the light's direction.
    pub aim: glam::Vec3,
}

impl std::fmt::Display for Pose {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [a, b, c] = self.position.to_array();
        let [d, e, g] = self.aim.to_array();
        write!(f, "{a},{b},{c},{d},{e},{g}")
    }
}

/// `X,Y,Z,X,Y,Z`: six finite numbers.
fn parse_pose(s: &str) -> Result<Pose, String> {
    let numbers: Vec<f32> = s
        .split(',')
        .map(finite_f32)
        .collect::<Result<_, _>>()
        .map_err(|e| format!("'{s}': {e}"))?;
    let [a, b, c, d, e, f] = numbers[..] else {
        return Err(format!(
            "'{s}' is not six numbers X,Y,Z,X,Y,Z (it has {})",
            numbers.len()
        ));
    };
    Ok(Pose {
        position: glam::Vec3::new(a, b, c),
        aim: glam::Vec3::new(d, e, f),
    })
}

/// Most frames `--frames` takes.
const MAX_FRAMES: u32 = 4096;

/// `cssm render`, checked: the method's options resolved by its table; the image size and the
/// shadow-map resolution are checked by the runtime's frame settings once the scene (its
/// camera) is loaded.
pub struct RenderConfig {
    /// Scene directory or mesh file; `None`: the built-in Cornell box.
    pub scene: Option<PathBuf>,
    /// The method.
    pub method: &'static MethodEntry,
    /// The method options the user gave.
    pub values: OptionValues,
    /// Every option of the method, the given ones and the defaults, checked by its table.
    pub resolved: Resolved,
    /// Output PNG.
    pub out: PathBuf,
    /// Output OpenEXR.
    pub exr: Option<PathBuf>,
    /// Image size; `None`: the scene camera's.
    pub size: Option<(u32, u32)>,
    /// Exposure in stops; `None`: automatic ([`runtime::common::tonemap::auto_exposure_stops`]).
    pub exposure: Option<f32>,
    /// Shadow-map resolution.
    pub shadow_resolution: u32,
    /// How the CSSM methods query visibility (`--one-end`).
    pub visibility: QueryOptions,
    /// `--timings`.
    pub timings: bool,
    /// `--stats`.
    pub stats: bool,
    /// The scene's `.cssm`; `None`: baked in memory where the method needs one.
    pub cssm: Option<PathBuf>,
    /// Frames to average, 1..=[`MAX_FRAMES`].
    pub frames: u32,
    /// Which light the image holds.
    pub component: Component,
    /// `--camera EYE,TARGET`: the camera's eye and target instead of the scene's (its up and
    /// field of view stay).
    pub camera: Option<Pose>,
    /// `--light POSITION,DIRECTION`: the first spot light's instead of the scene's (its cone
    /// and intensity stay).
    pub light: Option<Pose>,
    /// `--animate`: render the scene's animation into the directory `out`.
    pub animate: Option<AnimateOptions>,
    /// `--time SECONDS`: the moving objects placed where the animation has them then.
    pub time: Option<f32>,
}

/// `cssm render --animate`'s options, as given: the frame count, rate and duration are resolved
/// against the scene's animation by [`AnimateOptions::plan`].
#[derive(Clone, Debug, PartialEq)]
pub struct AnimateOptions {
    /// `--frames`.
    pub frames: Option<u32>,
    /// `--fps`, finite and above 0.
    pub fps: Option<f32>,
    /// `--duration` in seconds, finite and above 0.
    pub duration: Option<f32>,
    /// `--overwrite`.
    pub overwrite: bool,
    /// Write `animation.gif` (no `--no-gif`).
    pub gif: bool,
}

/// Frames per second of `--animate` without `--fps`.
pub const DEFAULT_FPS: f32 = 24.0;

impl AnimateOptions {
    /// The frame count and the seconds they span, for an animation of `scene_duration` seconds
    /// (the scene's, or the default spin's): at most two of `--frames`, `--fps` and `--duration`
    /// are given, the others follow (`--fps` defaults to [`DEFAULT_FPS`], `--duration` to
    /// `scene_duration`), and the count is 1 to [`MAX_FRAMES`].
    pub fn plan(&self, scene_duration: f32) -> Result<(u32, f32), String> {
        let (frames, duration) = match (self.frames, self.fps, self.duration) {
            (Some(_), Some(_), Some(_)) => {
                return Err(
                    "--animate takes at most two of --frames, --fps and --duration \
                            (the third follows from them)"
                        .into(),
                );
            }
            (Some(n), Some(fps), None) => (n as f64, n as f64 / fps as f64),
            (Some(n), None, duration) => (n as f64, duration.unwrap_or(scene_duration) as f64),
            (None, fps, duration) => {
                let duration = duration.unwrap_or(scene_duration) as f64;
                let fps = fps.unwrap_or(DEFAULT_FPS) as f64;
                ((duration * fps).round().max(1.0), duration)
            }
        };
        if !(1.0..=MAX_FRAMES as f64).contains(&frames) {
            return Err(format!(
                "--animate: {frames} frames is out of range 1..={MAX_FRAMES} (lower --fps or \
                 --duration, or give --frames)"
            ));
        }
        if !(duration.is_finite() && duration > 0.0 && duration <= f32::MAX as f64) {
            return Err(format!(
                "--animate: the animation lasts {duration} s; give --duration"
            ));
        }
        Ok((frames as u32, duration as f32))
    }
}

impl RenderArgs {
    /// The method's options from the flags, resolved by the runtime's method table, and the
    /// frame count checked.
    pub fn config(self) -> Result<RenderConfig, String> {
        // With --animate, --frames counts the animation's frames, each rendered once.
        let frames = if self.animate {
            1
        } else {
            self.frames.unwrap_or(1)
        };
        if let Some(n) = self.frames
            && !(1..=MAX_FRAMES).contains(&n)
        {
            return Err(format!("--frames {n} is out of range 1..={MAX_FRAMES}"));
        }
        let animate = self.animate.then_some(AnimateOptions {
            frames: self.frames,
            fps: self.fps,
            duration: self.duration,
            overwrite: self.overwrite,
            gif: !self.no_gif,
        });
        if animate.is_some() {
            if self.out.is_none() {
                return Err("--animate writes its frames into a directory: give --out DIR".into());
            }
            for (given, flag) in [(self.exr.is_some(), "--exr"), (self.timings, "--timings")] {
                if given {
                    return Err(format!(
                        "{flag} is for one image and does not go with --animate"
                    ));
                }
            }
        }
        let values = self.option_values(frames)?;
        let resolved = self.method.resolve(&values).map_err(|e| e.to_string())?;
        Ok(RenderConfig {
            scene: self.scene,
            method: self.method,
            values,
            resolved,
            out: self.out.unwrap_or_else(|| PathBuf::from("render.png")),
            exr: self.exr,
            size: self.size,
            exposure: self.exposure,
            shadow_resolution: self.shadow_resolution,
            visibility: QueryOptions {
                both_ends: !self.one_end,
                ..QueryOptions::default()
            },
            timings: self.timings,
            stats: self.stats,
            cssm: self.cssm,
            frames,
            component: self.component,
            camera: self.camera,
            light: self.light,
            animate,
            time: self.time,
        })
    }

    /// The method options the user gave: the short flags, then `--set` in order. A short flag
    /// for an option the method does not have is ignored with a warning (`--bounces` with
    /// `direct`); `--set` of an unknown option is an error, from the method table.
    fn option_values(&self, frames: u32) -> Result<OptionValues, String> {
        option_values(
            self.method,
            [
                ("bounces", self.bounces.map(OptionValue::Count)),
                ("threshold", self.threshold.map(OptionValue::Number)),
                ("samples", self.samples.map(OptionValue::Count)),
            ],
            frames,
            &self.set,
        )
    }
}

/// The method options the user gave (`cssm render` and `cssm view`): the short flags, then
/// `--set` in order; see [`RenderArgs::option_values`].
fn option_values(
    method: &'static MethodEntry,
    short: [(&str, Option<OptionValue>); 3],
    frames: u32,
    set: &[String],
) -> Result<OptionValues, String> {
    let mut values = OptionValues::default();
    for (name, value) in short {
        let Some(value) = value else { continue };
        if method.option(name).is_some() {
            values.set(name, value);
        } else {
            eprintln!("warning: --{name} has no effect on method {method}");
        }
    }
    // Several frames of lightcuts jitter unless told otherwise (§4.5).
    if frames > 1 && method.option("jitter").is_some() {
        values.set("jitter", OptionValue::Switch(true));
    }
    for assignment in set {
        let (name, text) = assignment
            .split_once('=')
            .ok_or_else(|| format!("--set {assignment}: expected NAME=VALUE"))?;
        let spec = method.option(name.trim()).ok_or_else(|| {
            let known: Vec<&str> = method.options.iter().map(|o| o.name).collect();
            format!(
                "--set {assignment}: method {method} has no option '{}' (its options: {})",
                name.trim(),
                if known.is_empty() {
                    "none".into()
                } else {
                    known.join(", ")
                }
            )
        })?;
        values.set(spec.name, spec.parse(text)?);
    }
    Ok(values)
}

#[cfg(test)]
mod tests {
    use clap::{CommandFactory, Parser};

    use super::{Cli, Command};

    #[test]
    fn the_definitions_are_consistent() {
        Cli::command().debug_assert();
    }

    /// What `cssm view` prints for `--camera`/`--light` parses back to the same floats, bit
    /// for bit: the render of the printed flags is the window's image.
    #[test]
    fn a_printed_pose_parses_back_to_the_same_floats() {
        let pose = super::Pose {
            position: glam::Vec3::new(0.1 + 0.2, -1.0e-7, 436.736_8),
            aim: glam::Vec3::new(-0.0, f32::MIN_POSITIVE, 1.0 / 3.0),
        };
        let parsed = super::parse_pose(&pose.to_string()).unwrap();
        assert_eq!(
            parsed.position.to_array().map(f32::to_bits),
            pose.position.to_array().map(f32::to_bits)
        );
        assert_eq!(
            parsed.aim.to_array().map(f32::to_bits),
            pose.aim.to_array().map(f32::to_bits)
        );
        assert!(super::parse_pose("1,2,3,4,5").is_err());
        assert!(super::parse_pose("1,2,3,4,5,inf").is_err());
        assert!(super::parse_pose("1,2,3,4,5,6,7").is_err());
    }

    #[test]
    fn place_takes_a_name_and_three_or_six_numbers() {
        let p = super::parse_place("bunny=1,2,3").unwrap();
        assert_eq!(p.name, "bunny");
        assert_eq!(p.translation, glam::Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(p.rotation_deg, glam::Vec3::ZERO);
        let p = super::parse_place("a=b=1,-2,3,0,90,-45").unwrap_err();
        assert!(p.contains("'a=b=1,-2,3,0,90,-45'"), "{p}");
        let p = super::parse_place("box=1,-2,3,0,90,-45").unwrap();
        assert_eq!(p.rotation_deg, glam::Vec3::new(0.0, 90.0, -45.0));
        for bad in [
            "bunny",
            "=1,2,3",
            "bunny=1,2",
            "bunny=1,2,3,4",
            "bunny=1,2,nan",
        ] {
            assert!(super::parse_place(bad).is_err(), "{bad}");
        }
    }

    fn bake_config(args: &[&str]) -> Result<super::BakeConfig, String> {
        let cli = Cli::try_parse_from([&["cssm", "bake"], args].concat()).unwrap();
        let Command::Bake(args) = cli.command else {
            unreachable!()
        };
        args.config()
    }

    /// The bake library checks the options; the command line names the flag.
    #[test]
    fn bake_options_are_checked_by_the_library_and_name_the_flag() {
        let config = bake_config(&["--atlas", "128", "--near", "0.5"]).unwrap();
        assert_eq!(config.options.atlas_resolution, 128);
        assert_eq!(config.options.near, Some(0.5));
        for (args, message) in [
            (["--atlas", "16"], "--atlas 16 is out of range 32..=1024"),
            (["--cube", "256"], "--cube 256 is out of range 8..=128"),
            (["--near", "0"], "--near 0 must be positive and finite"),
        ] {
            assert_eq!(bake_config(&args).err().as_deref(), Some(message));
        }
    }

    /// A spec's options are parsed by the method's table, the flags fill `bounces` and
    /// `samples` where the spec leaves them, and the spec is kept as written, trimmed.
    #[test]
    fn method_lists_split_at_methods_not_at_options() {
        assert_eq!(
            super::split_methods("lightcuts:bounces=2,jitter=true,rsm, vct:resolution=64"),
            [
                "lightcuts:bounces=2,jitter=true",
                "rsm",
                "vct:resolution=64"
            ]
        );
        assert_eq!(super::split_methods("direct,,ssil"), ["direct", "ssil"]);
        // An option with no method before it stays a spec of its own (and fails to parse).
        assert_eq!(super::split_methods("bounces=2,rsm"), ["bounces=2", "rsm"]);
        assert_eq!(super::split_methods("rsm,bounces=2"), ["rsm", "bounces=2"]);
    }

    #[test]
    fn method_specs_parse_against_the_table() {
        let v = super::parse_variant(" lightcuts : threshold=0.5 , jitter=on", 2, 64).unwrap();
        assert_eq!(v.spec, "lightcuts:threshold=0.5,jitter=on");
        assert_eq!(v.resolved.count("bounces"), 2);
        assert_eq!(v.resolved.number("threshold"), 0.5);
        assert!(v.resolved.switch("jitter"));
        let v = super::parse_variant("reference:bounces=3", 1, 64).unwrap();
        assert_eq!(
            (v.resolved.count("bounces"), v.resolved.count("samples")),
            (3, 64)
        );
        assert_eq!(
            super::parse_variant("direct", 1, 64).unwrap().spec,
            "direct"
        );
        let err = super::parse_variant("direct:bounces=2", 1, 64)
            .err()
            .unwrap();
        assert!(err.starts_with("--method direct:bounces=2: "), "{err}");
        let err = super::parse_variant("hrc:bounces=1,bounces=2", 1, 64)
            .err()
            .unwrap();
        assert!(err.contains("given twice"), "{err}");
        let err = super::parse_variant("hrc:threshold=x", 1, 64)
            .err()
            .unwrap();
        assert!(err.contains("threshold x must be a number"), "{err}");
    }
}
