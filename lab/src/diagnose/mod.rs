//! `cssm diagnose`: the research diagnostics behind the visibility query's and the radiosity's
//! defaults, each taking a `.cssm` file and measuring one question on the scene it was baked
//! from. The reports quote what they print, so their text stays as it was when measured.
//!
//! - [`ends`] (`cssm diagnose ends FILE.cssm`): how the two ends' answers of the query are
//!   best combined. Over `cssm check`'s pairs (seed 1) that exchange light with texels at both
//!   ends, each end asked as the query asks it and with what other rules need, and every rule's
//!   agreement, bias and RMSE (reports/visibility.md, "Which end to trust" and "What else was
//!   tried on the turned church"). With `--mix FINE.cssm` (and `--coverage`) it measures
//!   instead what a per-texel cube resolution or a per-pixel coverage hint could buy
//!   (reports/visibility.md, "Per-texel cube resolution and coverage hints").
//! - [`filters`] (`cssm diagnose filters FILE.cssm [-v]`): what the "filters" class of `cssm
//!   check` is: which sender filter (by normal, plane, distance, side, wider tents) turns a
//!   right answer wrong, and which single change would have made each wrong answer right
//!   (reports/visibility.md, "The filters").
//! - [`radiosity_bias`] (`cssm diagnose radiosity-bias FILE.cssm`): where the radiosity's
//!   indirect light loses against the path tracer's, one bounce at random texels computed
//!   several ways that each differ in one thing (reports/final-gather.md, "The clusters'
//!   transfer: the nave's missing light"); with `--leak`, where the light the query lets
//!   through an exact ray's blocker is stopped.
//!
//! Each reads its inputs from its arguments ([`ends::EndsArgs`], [`filters::FiltersArgs`],
//! [`radiosity_bias::RadiosityBiasArgs`]) and answers bad input with an error naming the file
//! and the problem.

use std::path::Path;

use cssm_formats::{CssmFile, LoadOptions, Scene};
use cssm_raycast::{SplitMix64, SurfacePoint, SurfaceSampler};

pub mod ends;
pub mod filters;
pub mod radiosity_bias;

/// The diagnostics, as `cssm diagnose` names them.
#[derive(clap::Subcommand, Clone, Debug)]
pub enum DiagnoseCommand {
    /// Which end of a pair to trust: every rule for combining the two ends' answers.
    ///
    /// Over `cssm check`'s pairs (seed 1) that exchange light with texels at both ends, each end's
    /// answer as the query computes it and with what other rules need (occluder depths, wider
    /// tents, a parallax-corrected look, probes near the sender), and every rule for combining the
    /// two ends: its agreement with exact ray casts, the pairs it gains on the mean, its bias and
    /// RMSE (reports/visibility.md, "Which end to trust"). With --mix, what a per-texel cube
    /// resolution could buy instead.
    #[command(after_help = "Examples:\n  \
        cssm diagnose ends church.cssm\n  \
        cssm diagnose ends church.cssm --probes 0.25,0.5,1,2 --csv ends.csv\n  \
        cssm diagnose ends church32.cssm --mix church64.cssm [--coverage]")]
    Ends(ends::EndsArgs),
    /// What the "filters" class of `cssm check` is: which sender filter turns answers wrong.
    ///
    /// Over the pairs that exchange light with texels at both ends (seed 1), the agreement of the
    /// sender filter's variants (by normal, plane, distance, side; wider tents; other thresholds),
    /// and for each wrong answer whose sender texel is right, which single change would have made
    /// it right (reports/visibility.md, "The filters").
    #[command(after_help = "Example:\n  cssm diagnose filters church.cssm -v")]
    Filters(filters::FiltersArgs),
    /// Where the radiosity's indirect light loses against the path tracer's.
    ///
    /// One bounce of the lights' direct light, as irradiance at random texels' centres, path
    /// traced, gathered from every texel (exact rays, then the CSSM query), by the hierarchy, and
    /// by the hierarchy's gather with four transfers of a cluster; each against the path traced
    /// one, by material (reports/final-gather.md, "The clusters' transfer: the nave's missing
    /// light").
    #[command(after_help = "Examples:\n  \
        cssm diagnose radiosity-bias nave.cssm --receivers 3000\n  \
        cssm diagnose radiosity-bias nave.cssm --rays 16 --leak")]
    RadiosityBias(radiosity_bias::RadiosityBiasArgs),
}

/// Runs the diagnostic `command` names, printing its figures on standard output (and its
/// progress on standard error); `scenes` is what the scene a file was baked from may read
/// (`cssm --allow-outside-files`).
///
/// # Errors
/// A message naming the file and the problem: a `.cssm` file that cannot be read, the scene it
/// was baked from that cannot be loaded or has changed, an argument out of range, an output
/// that cannot be written.
pub fn run(command: &DiagnoseCommand, scenes: LoadOptions) -> Result<(), String> {
    match command {
        DiagnoseCommand::Ends(args) => ends::run(args, scenes),
        DiagnoseCommand::Filters(args) => filters::run(args, scenes),
        DiagnoseCommand::RadiosityBias(args) => radiosity_bias::run(args, scenes),
    }
}

/// Reads the `.cssm` file at `path` and loads the scene its header records, checked to be the
/// scene it was baked from: the diagnostics index that scene's triangles by the file's.
fn load(path: &Path, scenes: LoadOptions) -> Result<(CssmFile, Scene), String> {
    let file = cssm_formats::cssm::read(path).map_err(|e| e.to_string())?;
    let scene = Scene::load_with(Path::new(&file.scene.dir), scenes)
        .map_err(|e| format!("{}: the scene it was baked from: {e}", path.display()))?;
    cssm_runtime::load::check_scene(path, &file, &scene).map_err(|e| e.to_string())?;
    Ok((file, scene))
}

/// `count` random pairs of surface points of `scene`, drawn as `cssm check` draws them (seed
/// 1): the pairs the reports' figures were measured over.
fn draw_pairs(scene: &Scene, count: u32) -> Vec<(SurfacePoint, SurfacePoint)> {
    let sampler = SurfaceSampler::new(scene);
    let mut rng = SplitMix64(1);
    (0..count)
        .map(|_| {
            let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
            let a = sampler.point(r());
            let b = sampler.point(r());
            (a, b)
        })
        .collect()
}

/// `--pairs`: at least one (the figures are fractions of the pairs counted).
fn check_pairs(pairs: u32) -> Result<(), String> {
    if pairs == 0 {
        return Err("--pairs 0: draw at least one pair (default 100000)".to_string());
    }
    Ok(())
}

/// The message of a failed write of the figures to standard output.
fn output_error(e: std::io::Error) -> String {
    format!("cannot write the figures to standard output: {e}")
}

#[cfg(test)]
mod tests {
    use std::sync::OnceLock;

    use clap::Parser;

    use super::*;

    /// `cssm diagnose` as the command line spells it, so that the tests pass the user's flags.
    #[derive(clap::Parser)]
    struct Cli {
        #[command(subcommand)]
        command: DiagnoseCommand,
    }

    fn parse(args: &[&str]) -> Result<DiagnoseCommand, clap::Error> {
        Cli::try_parse_from(std::iter::once("diagnose").chain(args.iter().copied()))
            .map(|cli| cli.command)
    }

    fn command(args: &[&str]) -> DiagnoseCommand {
        parse(args).unwrap_or_else(|e| panic!("{args:?}: {e}"))
    }

    /// The built-in Cornell box baked small at cube `cube`, once per test binary and
    /// resolution: the bake is the slow part of these tests.
    fn baked(cube: u32) -> &'static CssmFile {
        static CUBE_8: OnceLock<CssmFile> = OnceLock::new();
        static CUBE_16: OnceLock<CssmFile> = OnceLock::new();
        let cell = match cube {
            8 => &CUBE_8,
            16 => &CUBE_16,
            _ => unreachable!("the tests bake at cube 8 and 16"),
        };
        cell.get_or_init(|| {
            let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/cornell-box");
            let scene = Scene::load(Path::new(dir)).expect("the built-in Cornell box loads");
            let options = cssm_bake::BakeOptions {
                atlas_resolution: 32,
                cube_resolution: cube,
                ..Default::default()
            };
            cssm_bake::bake(&scene, &options, &mut |_| {})
                .expect("the Cornell box bakes")
                .file
        })
    }

    /// `file` written as `name` in `dir`, as a path the command line takes.
    fn write(dir: &Path, name: &str, file: &CssmFile) -> String {
        let path = dir.join(name);
        cssm_formats::cssm::write_atomic(&path, file).expect("the temporary directory takes it");
        utf8(&path)
    }

    fn utf8(path: &Path) -> String {
        path.to_str().expect("a UTF-8 temporary path").to_string()
    }

    /// The Cornell box at cube 16 in a fresh temporary directory.
    fn cornell() -> (tempfile::TempDir, String) {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let path = write(dir.path(), "cornell.cssm", baked(16));
        (dir, path)
    }

    /// Runs the diagnostic `args` names and returns what it printed.
    fn output(args: &[&str]) -> String {
        let mut out = Vec::new();
        let result = match command(args) {
            DiagnoseCommand::Ends(a) => ends::diagnose(&a, LoadOptions::default(), &mut out),
            DiagnoseCommand::Filters(a) => filters::diagnose(&a, LoadOptions::default(), &mut out),
            DiagnoseCommand::RadiosityBias(a) => {
                radiosity_bias::diagnose(&a, LoadOptions::default(), &mut out)
            }
        };
        result.unwrap_or_else(|e| panic!("{args:?}: {e}"));
        String::from_utf8(out).expect("the figures are text")
    }

    /// The error `run` gives for `args`.
    fn error(args: &[&str]) -> String {
        match run(&command(args), LoadOptions::default()) {
            Ok(()) => panic!("{args:?} ran"),
            Err(e) => e,
        }
    }

    /// The number before `marker` in `text`.
    fn count_before(text: &str, marker: &str) -> usize {
        let head = &text[..text
            .find(marker)
            .unwrap_or_else(|| panic!("{marker}: {text}"))];
        let number = head.rsplit(' ').next().expect("a number before the marker");
        number
            .parse()
            .unwrap_or_else(|_| panic!("{number}: {text}"))
    }

    #[test]
    fn ends_prints_every_rule_and_writes_a_csv_line_per_counted_pair() {
        let (dir, file) = cornell();
        let csv = utf8(&dir.path().join("ends.csv"));
        let text = output(&["ends", &file, "--pairs", "2000", "--csv", &csv]);
        assert!(text.starts_with(&format!("{file}: ")), "{text}");
        let count = count_before(&text, " pairs that exchange light with texels at both ends");
        assert!(count > 0, "{text}");
        // The header, the query, both, either, the split, the table's title, then the rules.
        assert_eq!(text.lines().count(), 6 + 21, "{text}");
        assert!(text.contains("the mean (today)"), "{text}");
        let csv = std::fs::read_to_string(&csv).expect("the CSV was written");
        assert_eq!(csv.lines().count(), count, "{csv}");
        assert!(csv.lines().all(|l| l.split(',').count() == 13), "{csv}");
        // Other probes change only the probes' rule.
        let probes = output(&["ends", &file, "--pairs", "2000", "--probes", "0.25,0.5"]);
        assert_eq!(probes.lines().count(), text.lines().count(), "{probes}");
    }

    #[test]
    fn ends_mix_measures_a_finer_file_and_its_coverage() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let coarse = write(dir.path(), "cornell8.cssm", baked(8));
        let fine = write(dir.path(), "cornell16.cssm", baked(16));
        let args = ["ends", &coarse, "--pairs", "2000", "--mix", &fine];
        let text = output(&args);
        // The header, then one line per fraction of the texels refined.
        assert_eq!(text.lines().count(), 1 + 9, "{text}");
        assert!(text.contains("refine 100.0% of texels"), "{text}");
        let coverage = output(&[&args[..], &["--coverage"]].concat());
        assert!(
            coverage.contains("pairs; coarse taps covered by the fine file's sub-pixels"),
            "{coverage}"
        );
    }

    #[test]
    fn filters_prints_every_filter_and_the_breakdown() {
        let (_dir, file) = cornell();
        let text = output(&["filters", &file, "--pairs", "2000", "-v"]);
        let count: usize = text
            .lines()
            .find_map(|l| l.strip_prefix("exchanging pairs with texels at both ends: "))
            .unwrap_or_else(|| panic!("{text}"))
            .parse()
            .expect("a count");
        assert!(count > 0, "{text}");
        for filter in ["base", "dot.99+front", "own"] {
            assert!(text.contains(&format!("{filter:>14}: both ")), "{text}");
        }
        assert!(text.contains("tent radius 1/1.5/2/2.5"), "{text}");
    }

    #[test]
    fn radiosity_bias_prints_the_materials_and_the_leaks() {
        let (_dir, file) = cornell();
        let small = ["radiosity-bias", &file, "--receivers", "20", "--rays", "16"];
        let text = output(&small);
        assert!(
            text.starts_with(&format!(
                "{file}: one bounce, irradiance at 20 texel centres"
            )),
            "{text}"
        );
        assert!(
            text.lines().any(|l| l.trim_start().starts_with("all ")),
            "{text}"
        );
        assert!(text.contains("m.+other side: "), "{text}");
        let leaks = output(&[&small[..], &["--leak", "--threshold", "0.5"]].concat());
        assert!(
            leaks.starts_with("light let through where an exact ray is blocked: "),
            "{leaks}"
        );
        assert!(
            leaks.contains("sixths of the segment from the receiver"),
            "{leaks}"
        );
    }

    #[test]
    fn a_missing_or_invalid_cssm_file_is_named() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let missing = utf8(&dir.path().join("missing.cssm"));
        let invalid = dir.path().join("invalid.cssm");
        std::fs::write(&invalid, vec![b'x'; 4096]).expect("the temporary directory takes it");
        let invalid = utf8(&invalid);
        for diagnostic in ["ends", "filters", "radiosity-bias"] {
            let e = error(&[diagnostic, &missing]);
            assert!(e.contains(&missing) && e.contains("No such file"), "{e}");
            let e = error(&[diagnostic, &invalid]);
            assert!(
                e.contains(&invalid) && e.contains("not a .cssm file"),
                "{e}"
            );
        }
        let (_dir, file) = cornell();
        let e = error(&["ends", &file, "--mix", &missing]);
        assert!(e.starts_with("--mix ") && e.contains(&missing), "{e}");
    }

    #[test]
    fn a_scene_that_is_gone_or_another_is_named() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let mut gone = baked(16).clone();
        let nowhere = dir.path().join("nowhere");
        gone.scene.dir = utf8(&nowhere);
        let gone = write(dir.path(), "gone.cssm", &gone);
        let mut other = baked(16).clone();
        other.scene.dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/cornell-glossy").into();
        let other = write(dir.path(), "other.cssm", &other);
        for diagnostic in ["ends", "filters", "radiosity-bias"] {
            let e = error(&[diagnostic, &gone]);
            assert!(
                e.starts_with(&format!("{gone}: the scene it was baked from: "))
                    && e.contains(&utf8(&nowhere))
                    && e.contains("does not exist"),
                "{e}"
            );
            let e = error(&[diagnostic, &other]);
            assert!(
                e.starts_with(&other) && e.contains("baked from another scene"),
                "{e}"
            );
        }
    }

    #[test]
    fn a_mix_file_of_another_resolution_or_atlas_is_refused() {
        let (dir, file) = cornell();
        let e = error(&["ends", &file, "--mix", &file]);
        assert!(
            e.starts_with(&format!(
                "--mix {file}: cube resolution 16, not twice the 16"
            )),
            "{e}"
        );
        let mut other_atlas = baked(16).clone();
        // Another atlas: a texel elsewhere (the counts must stay, the file checks them).
        other_atlas.texels[0].position[0] += 0.25;
        let other_atlas = write(dir.path(), "other-atlas.cssm", &other_atlas);
        let coarse = write(dir.path(), "cornell8.cssm", baked(8));
        let e = error(&["ends", &coarse, "--mix", &other_atlas]);
        assert!(
            e.starts_with(&format!(
                "--mix {other_atlas}: its atlas texels are not those of"
            )),
            "{e}"
        );
    }

    #[test]
    fn a_csv_that_cannot_be_created_or_written_is_named() {
        let (dir, file) = cornell();
        let uncreatable = utf8(&dir.path().join("no-such-dir").join("ends.csv"));
        let e = error(&["ends", &file, "--pairs", "200", "--csv", &uncreatable]);
        assert!(
            e.starts_with(&format!("--csv {uncreatable}: cannot create")),
            "{e}"
        );
        // A device of our own with the full device's numbers (1, 7), inside the temporary
        // directory: it opens, and fails on the first write that reaches it.
        let full = dir.path().join("full");
        let made = std::process::Command::new("mknod")
            .args([utf8(&full).as_str(), "c", "1", "7"])
            .status()
            .expect("mknod");
        assert!(made.success(), "mknod needs root (the tests run as root)");
        let full = utf8(&full);
        let e = error(&["ends", &file, "--pairs", "200", "--csv", &full]);
        assert!(e.starts_with(&format!("--csv {full}: ")), "{e}");
    }

    #[test]
    fn probes_that_are_not_positive_increasing_numbers_are_refused() {
        let (_dir, file) = cornell();
        for (probes, problem) in [
            ("1,0", "0 is not a positive number"),
            ("-1", "-1 is not a positive number"),
            ("1,NaN", "NaN is not a positive number"),
            ("1,inf", "inf is not a positive number"),
            ("2,1", "the distances must increase"),
        ] {
            let e = error(&["ends", &file, "--probes", probes]);
            assert!(
                e.starts_with("--probes ") && e.contains(problem),
                "{probes}: {e}"
            );
        }
        assert!(parse(&["ends", &file, "--probes", "1,two"]).is_err());
    }

    #[test]
    fn pairs_receivers_and_rays_of_zero_are_refused() {
        let (_dir, file) = cornell();
        for diagnostic in ["ends", "filters"] {
            let e = error(&[diagnostic, &file, "--pairs", "0"]);
            assert!(e.starts_with("--pairs 0: "), "{e}");
        }
        let e = error(&["radiosity-bias", &file, "--receivers", "0"]);
        assert!(e.starts_with("--receivers 0: "), "{e}");
        let e = error(&["radiosity-bias", &file, "--rays", "0"]);
        assert!(e.starts_with("--rays 0: "), "{e}");
        let e = error(&["radiosity-bias", &file, "--threshold", "inf"]);
        assert!(e.starts_with("--threshold inf: "), "{e}");
    }

    #[test]
    fn flags_that_do_not_go_together_are_refused() {
        let file = "cornell.cssm";
        assert!(parse(&["ends", file, "--coverage"]).is_err());
        assert!(parse(&["ends", file, "--mix", file, "--csv", "x.csv"]).is_err());
        assert!(parse(&["ends", file, "--mix", file, "--probes", "1,2"]).is_err());
        assert!(parse(&["ends", file, "--mix", file, "--coverage"]).is_ok());
        assert!(parse(&["filters", file, "--verbose"]).is_ok());
        // The defaults are the figures the examples hard-coded, which the reports quote.
        let DiagnoseCommand::Ends(ends) = command(&["ends", file]) else {
            unreachable!("ends parses as ends")
        };
        assert_eq!(
            (ends.pairs, &ends.probes[..]),
            (100_000, &[1.0, 2.0, 4.0][..])
        );
        let DiagnoseCommand::RadiosityBias(bias) = command(&["radiosity-bias", file]) else {
            unreachable!("radiosity-bias parses as radiosity-bias")
        };
        assert_eq!((bias.receivers, bias.rays), (1500, 1024));
        assert_eq!(bias.threshold, cssm_runtime::radiosity::DEFAULT_THRESHOLD);
    }
}
