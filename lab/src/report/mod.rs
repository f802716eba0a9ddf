//! Reports that measure the toolchain against the paper. `cssm report compression` (and the
//! `benches/compression.rs` harness, which calls the same code) bakes a grid of settings and
//! writes `compression.md`, `compression.csv` and `compression.svg`:
//!
//! - **Table 2** (§5): the Cornell box at cube `6 x 32 x 32`, atlas 32, 64 and 128, every
//!   traversal (the paper's three and the Hilbert order);
//! - **Table 3** (§5): cube `6 x 64 x 64`, atlas 64 to 512, for the Cornell box, the Cornell
//!   Heads ([`heads`]) and the church (the Sibenik cathedral), once with the paper's method and
//!   once with the best options;
//! - **Options**: every option beyond the paper, one row each, against the paper's method at the
//!   same settings (Cornell box, atlas 128, cube 64).
//!
//! Every row is one `cssm bake --json` child process (its figures, and its own peak resident
//! memory, `VmHWM`, which it reads before exiting), followed by `cssm check --json` on the file
//! (agreement with exact ray casts on random surface point pairs, §3.2.2). The ratio that counts
//! is uncompressed / GPU-resident size, as in the paper; the file ratio is a column beside it.
//!
//! `cssm report error` measures each method's image against the reference path tracer's: the
//! figures are [`error`], the files beside the images [`error_write`]. `cssm compare` puts
//! every method of the table side by side on each scene, full image and indirect light, the
//! reference's noise taken out: its data and files are [`compare`], its page and chart
//! [`compare_html`].
//!
//! The compression report's code: `planning.rs` its tables, scenes and arguments and the rows
//! they ask for ([`plan`]); `options.rs` the bake variants ([`PAPER`], [`BEST`], the Options
//! table's [`OPTIONS`]); `bake_check.rs` a row's child processes; here the run over the rows
//! ([`run`]) and the machine and commit every report names; `write.rs` and `write/` its files.

pub mod church;
pub mod compare;
pub mod compare_html;
pub mod error;
pub mod error_write;
pub mod heads;
pub mod paper;

mod bake_check;
mod options;
mod planning;
mod write;

pub use options::{BEST, OPTIONS, PAPER, Variant};
pub use planning::{CompressionArgs, PaperFigures, Plan, SceneId, TableId, plan};

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use bake_check::bake_and_check;

/// Figures of one bake and its accuracy check.
#[derive(Clone, Debug, Default)]
pub struct Measured {
    /// Scene triangles.
    pub faces: u64,
    /// Atlas charts.
    pub charts: u64,
    /// Depth maps (defined texels).
    pub maps: u64,
    /// Runs.
    pub runs: u64,
    /// 2 bytes per cube-map pixel.
    pub uncompressed: u64,
    /// GPU-resident run data.
    pub gpu: u64,
    /// File size.
    pub file: u64,
    /// Bake time, process start to file written.
    pub seconds: f64,
    /// Peak resident memory of the bake process, where the system reports it.
    pub peak_rss: Option<u64>,
    /// Fraction of the pairs that exchange light (each point in front of the other's surface)
    /// where the CSSM agrees with ray casts: the visibility an image needs.
    pub agreement: f64,
    /// The same over every pair drawn.
    pub agreement_all: f64,
    /// Pairs that exchange light.
    pub exchanging_pairs: u64,
    /// Truly occluded pairs reported visible (fraction of the occluded; pairs that exchange light).
    pub false_visible: f64,
    /// Truly visible pairs reported occluded (fraction of the visible; pairs that exchange light).
    pub false_occluded: f64,
}

impl Measured {
    /// Uncompressed / GPU-resident size.
    pub fn ratio(&self) -> f64 {
        self.uncompressed as f64 / self.gpu.max(1) as f64
    }
    /// Uncompressed / file size.
    pub fn file_ratio(&self) -> f64 {
        self.uncompressed as f64 / self.file.max(1) as f64
    }
}

/// A planned row and what came of it.
#[derive(Clone, Debug)]
pub struct Row {
    /// The plan.
    pub plan: Plan,
    /// Its figures, or why it did not run.
    pub outcome: Result<Measured, String>,
    /// Wall time of the row (bake and check), seconds; 0 for a row that reuses another's bake.
    pub wall_seconds: f64,
    /// Index of the earlier row whose bake and check this row reuses (same scene, atlas, cube
    /// and settings; in the full report, the Options table's `paper` and `best` rows).
    pub same_as: Option<usize>,
}

/// A finished report.
#[derive(Clone, Debug)]
pub struct Report {
    /// The command that made it.
    pub command: String,
    /// CPU, cores and memory.
    pub machine: String,
    /// `git` commit of the build, if known.
    pub commit: String,
    /// Scenes directory used.
    pub scenes: PathBuf,
    /// Pairs of each accuracy check.
    pub pairs: u64,
    /// What the heads scene was built from, when it was.
    pub heads: Option<String>,
    /// What the 3,700-face church was built from, when it was.
    pub church: Option<String>,
    /// Every row, in plan order.
    pub rows: Vec<Row>,
}

/// Runs the report: plans the rows, prepares the scenes, bakes and checks each row with `exe`
/// (the `cssm` binary), and writes the files into `args.out`. `command` is recorded in the
/// report as the command that made it; `cornell` is the directory of the Cornell box scene
/// (`cssm::builtin::cornell_box`).
pub fn run(
    args: &CompressionArgs,
    exe: &Path,
    command: &str,
    cornell: &Path,
) -> Result<Report, String> {
    if !args.out.is_dir() {
        return Err(format!(
            "--out {}: not a directory (create it first)",
            args.out.display()
        ));
    }
    let plans = plan(args);
    // Every row's options, checked by the bake library before anything runs; `--atlas` and
    // `--cube` set them.
    for plan in &plans {
        plan.bake_options()
            .check()
            .map_err(|e| cssm_output::flag_error(&e))?;
    }
    let work =
        tempfile::tempdir().map_err(|e| format!("cannot create a temporary directory: {e}"))?;
    let mut heads_note = None;
    let mut church_note = None;
    let mut scene_dirs: Vec<(SceneId, Result<PathBuf, String>)> = Vec::new();
    for scene in SceneId::ALL {
        if !plans.iter().any(|p| p.scene == scene) {
            continue;
        }
        let dir = match scene {
            SceneId::Cornell => Ok(cornell.to_path_buf()),
            SceneId::Heads => {
                let missing: Vec<String> = ["teapot", "bunny"]
                    .iter()
                    .map(|s| args.scenes.join(s))
                    .filter(|p| !p.is_dir())
                    .map(|p| p.display().to_string())
                    .collect();
                if missing.is_empty() {
                    heads::build(cornell, &args.scenes, &work.path().join("cornell-heads")).map(|h| {
                        heads_note = Some(format!(
                            "Cornell box ({} faces) + Utah teapot ({} faces, scaled 30x) + Stanford \
                             bunny simplified with meshoptimizer from {} to {} faces (scaled 1300x): \
                             {} faces",
                            h.faces[0],
                            h.faces[1],
                            h.bunny_faces_in,
                            h.faces[2],
                            h.faces.iter().sum::<usize>()
                        ));
                        h.dir
                    })
                } else {
                    Err(format!("not run: {} not found", missing.join(" and ")))
                }
            }
            SceneId::Church => {
                let d = args.scenes.join("sibenik");
                if d.is_dir() {
                    Ok(d)
                } else {
                    Err(format!("not run: {} not found", d.display()))
                }
            }
            SceneId::Church3700 => {
                let d = args.scenes.join("sibenik");
                if d.is_dir() {
                    church::build(&d, &work.path().join("church3700")).map(|c| {
                        church_note = Some(format!(
                            "the Sibenik cathedral simplified with meshoptimizer, material by \
                             material, from {} to {} faces (the paper's church had 3,700)",
                            c.faces_in, c.faces
                        ));
                        c.dir
                    })
                } else {
                    Err(format!("not run: {} not found", d.display()))
                }
            }
        };
        scene_dirs.push((scene, dir));
    }

    let bar = indicatif::ProgressBar::new(plans.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} report [{bar:32}] {pos}/{len} rows, {elapsed} elapsed: {msg}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    let mut rows = Vec::with_capacity(plans.len());
    let mut atlas_failures: Vec<(SceneId, u32, String)> = Vec::new();
    for (k, plan) in plans.into_iter().enumerate() {
        let label = plan.label();
        bar.set_message(label.clone());
        let start = Instant::now();
        let dir = scene_dirs
            .iter()
            .find(|(s, _)| *s == plan.scene)
            .map(|(_, d)| d.clone())
            .expect("every planned scene was prepared");
        // An atlas that could not be built for one variant cannot be for another (the atlas does
        // not depend on the bake options): say so instead of unwrapping it again.
        let known = atlas_failures
            .iter()
            .find(|(s, a, _)| *s == plan.scene && *a == plan.atlas)
            .map(|(_, _, e)| e.clone());
        // A row that bakes exactly what an earlier row baked takes that row's figures.
        let same_as = rows.iter().position(|r: &Row| {
            r.outcome.is_ok()
                && r.plan.scene == plan.scene
                && r.plan.atlas == plan.atlas
                && r.plan.cube == plan.cube
                && r.plan.variant.same_bake(&plan.variant)
        });
        let outcome = match same_as {
            Some(i) => rows[i].outcome.clone(),
            None => dir.and_then(|dir| match known {
                Some(e) => Err(e),
                None => bake_and_check(
                    exe,
                    &dir,
                    &plan,
                    &work.path().join(format!("row{k}.cssm")),
                    args.pairs,
                ),
            }),
        };
        if let Err(e) = &outcome
            && e.contains(": atlas: ")
        {
            atlas_failures.push((plan.scene, plan.atlas, e.clone()));
        }
        let wall_seconds = if same_as.is_some() {
            0.0
        } else {
            start.elapsed().as_secs_f64()
        };
        let line = match (&outcome, same_as) {
            (Ok(m), Some(i)) => format!(
                "{label}: the same bake as {}, ratio {:.1}",
                rows[i].plan.label(),
                m.ratio()
            ),
            (Ok(m), None) => format!(
                "{label}: {} maps, ratio {:.1} (file {:.1}), agreement {:.2}%, {:.1} s",
                m.maps,
                m.ratio(),
                m.file_ratio(),
                100.0 * m.agreement,
                m.seconds
            ),
            (Err(e), _) => format!("{label}: {e}"),
        };
        // One line per row on stderr, also when it is a log file (the bar is hidden then).
        if bar.is_hidden() {
            eprintln!("{line}");
        } else {
            bar.println(line);
        }
        bar.inc(1);
        rows.push(Row {
            plan,
            outcome,
            wall_seconds,
            same_as,
        });
    }
    bar.finish_and_clear();

    let report = Report {
        command: command.to_string(),
        machine: machine(),
        commit: commit(),
        scenes: args.scenes.clone(),
        pairs: args.pairs,
        heads: heads_note,
        church: church_note,
        rows,
    };
    write::write_all(&report, &args.out)?;
    Ok(report)
}

/// CPU model, cores and memory, as Linux reports them.
pub fn machine() -> String {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let cpu = cpuinfo
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .map_or("unknown CPU", str::trim)
        .to_string();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mem = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|m| {
            m.lines()
                .find(|l| l.starts_with("MemTotal:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|k| k.parse::<u64>().ok())
        })
        .map_or(String::new(), |kib| {
            format!(", {:.0} GiB memory", kib as f64 / (1 << 20) as f64)
        });
    format!("{cpu}, {cores} cores{mem}")
}

/// The checkout's commit (`git rev-parse --short HEAD`, `-dirty` with uncommitted changes).
pub fn commit() -> String {
    let repo = env!("CARGO_MANIFEST_DIR");
    let git = |args: &[&str]| {
        Command::new("git")
            .arg("-C")
            .arg(repo)
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    match git(&["rev-parse", "--short", "HEAD"]) {
        Some(hash) => {
            let dirty = git(&["status", "--porcelain", "--untracked-files=no"])
                .is_some_and(|s| !s.is_empty());
            if dirty { format!("{hash}-dirty") } else { hash }
        }
        None => "unknown (not a git checkout)".into(),
    }
}
