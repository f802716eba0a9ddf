//! The command line's definitions (clap) and each command's arguments turned into a config of
//! library types: what the flags mean and how they are spelled live here; every range is
//! checked by the library that takes the value ([`bake::BakeOptions::check`], the runtime's
//! method table and frame settings), and an error names the flag. The number parsers here
//! (`finite_f32`, `bias`, `stops`, `fraction`) refuse what no library value can mean (NaN,
//! infinities, a negative bias, a fraction beyond 1) as clap parses the flag.

mod baking;
mod checking;
mod measuring;
mod rendering;

pub use baking::*;
pub use checking::*;
pub use measuring::*;
pub use rendering::*;

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
    /// Take a baked file's visibility or radiosity apart against exact ray casts: the
    /// measurements behind reports/visibility.md and reports/final-gather.md.
    #[command(
        subcommand,
        after_help = "Examples:\n  \
            cssm diagnose filters church.cssm\n  \
            cssm diagnose ends church.cssm --csv /tmp/ends.csv\n  \
            cssm diagnose radiosity-bias sibenik.cssm --receivers 1500 --rays 1024"
    )]
    Diagnose(cssm::diagnose::DiagnoseCommand),
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
        let p = super::checking::parse_place("bunny=1,2,3").unwrap();
        assert_eq!(p.name, "bunny");
        assert_eq!(p.translation, glam::Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(p.rotation_deg, glam::Vec3::ZERO);
        let p = super::checking::parse_place("a=b=1,-2,3,0,90,-45").unwrap_err();
        assert!(p.contains("'a=b=1,-2,3,0,90,-45'"), "{p}");
        let p = super::checking::parse_place("box=1,-2,3,0,90,-45").unwrap();
        assert_eq!(p.rotation_deg, glam::Vec3::new(0.0, 90.0, -45.0));
        for bad in [
            "bunny",
            "=1,2,3",
            "bunny=1,2",
            "bunny=1,2,3,4",
            "bunny=1,2,nan",
        ] {
            assert!(super::checking::parse_place(bad).is_err(), "{bad}");
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
            super::measuring::split_methods(
                "lightcuts:bounces=2,jitter=true,rsm, vct:resolution=64"
            ),
            [
                "lightcuts:bounces=2,jitter=true",
                "rsm",
                "vct:resolution=64"
            ]
        );
        assert_eq!(
            super::measuring::split_methods("direct,,ssil"),
            ["direct", "ssil"]
        );
        // An option with no method before it stays a spec of its own (and fails to parse).
        assert_eq!(
            super::measuring::split_methods("bounces=2,rsm"),
            ["bounces=2", "rsm"]
        );
        assert_eq!(
            super::measuring::split_methods("rsm,bounces=2"),
            ["rsm", "bounces=2"]
        );
    }

    #[test]
    fn method_specs_parse_against_the_table() {
        let v = super::measuring::parse_variant(" lightcuts : threshold=0.5 , jitter=on", 2, 64)
            .unwrap();
        assert_eq!(v.spec, "lightcuts:threshold=0.5,jitter=on");
        assert_eq!(v.resolved.count("bounces"), 2);
        assert_eq!(v.resolved.number("threshold"), 0.5);
        assert!(v.resolved.switch("jitter"));
        let v = super::measuring::parse_variant("reference:bounces=3", 1, 64).unwrap();
        assert_eq!(
            (v.resolved.count("bounces"), v.resolved.count("samples")),
            (3, 64)
        );
        assert_eq!(
            super::measuring::parse_variant("direct", 1, 64)
                .unwrap()
                .spec,
            "direct"
        );
        let err = super::measuring::parse_variant("direct:bounces=2", 1, 64)
            .err()
            .unwrap();
        assert!(err.starts_with("--method direct:bounces=2: "), "{err}");
        let err = super::measuring::parse_variant("hrc:bounces=1,bounces=2", 1, 64)
            .err()
            .unwrap();
        assert!(err.contains("given twice"), "{err}");
        let err = super::measuring::parse_variant("hrc:threshold=x", 1, 64)
            .err()
            .unwrap();
        assert!(err.contains("threshold x must be a number"), "{err}");
    }
}
