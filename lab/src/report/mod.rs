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

pub mod church;
pub mod compare;
pub mod compare_html;
pub mod error;
pub mod error_write;
pub mod heads;
pub mod paper;
mod write;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use cssm_bake::{BakeOptions, compress::RunValue, cubemap::SecondLayer, traverse::ChartOrder};
use cssm_formats::{
    Traversal,
    cssm::FileCoding,
    cube::{CubeFrame, PixelGrid},
};

use cssm_bake::summary::{BakeSummary, CheckSummary};

/// Tables of the report.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum TableId {
    /// The paper's Table 2: traversals on the Cornell box.
    Table2,
    /// The paper's Table 3: three scenes, atlas 64 to 512.
    Table3,
    /// Options beyond the paper, one row each.
    Options,
}

/// Scenes of Table 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum SceneId {
    /// The built-in Cornell box (`scenes/cornell-box`).
    Cornell,
    /// The Cornell box with the teapot and a simplified bunny (built from `--scenes`).
    Heads,
    /// The Sibenik cathedral (`--scenes`/sibenik), standing in for the paper's church.
    Church,
    /// The Sibenik cathedral simplified to the paper's 3,700 faces ([`church`]).
    #[value(name = "church3700")]
    Church3700,
}

impl SceneId {
    /// Every scene, in report order.
    pub const ALL: [SceneId; 4] = [
        SceneId::Cornell,
        SceneId::Heads,
        SceneId::Church,
        SceneId::Church3700,
    ];

    /// Short name used in the tables and the CSV.
    pub fn name(self) -> &'static str {
        match self {
            SceneId::Cornell => "cornell",
            SceneId::Heads => "heads",
            SceneId::Church => "church",
            SceneId::Church3700 => "church3700",
        }
    }

    /// Title as in the paper's Table 3.
    pub fn title(self) -> &'static str {
        match self {
            SceneId::Cornell => "Cornell Box",
            SceneId::Heads => "Cornell Heads",
            SceneId::Church => "Cornell Church (Sibenik)",
            SceneId::Church3700 => "Cornell Church (Sibenik, 3,700 faces)",
        }
    }

    fn paper_rows(self) -> &'static [paper::Table3Row] {
        match self {
            SceneId::Cornell => &paper::CORNELL,
            SceneId::Heads => &paper::HEADS,
            SceneId::Church | SceneId::Church3700 => &paper::CHURCH,
        }
    }

    /// The paper's face count for the scene, as Table 3 prints it.
    fn paper_faces(self) -> &'static str {
        match self {
            SceneId::Cornell => "34",
            SceneId::Heads => "19k",
            SceneId::Church | SceneId::Church3700 => "3700",
        }
    }
}

/// One combination of bake options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Variant {
    /// Name in the tables.
    pub name: &'static str,
    /// What it changes against the paper's method.
    pub about: &'static str,
    /// Texel order.
    pub traversal: Traversal,
    /// Next-chart rule of the chart-by-chart traversals.
    pub chart_order: ChartOrder,
    /// Stored code inside each run's interval.
    pub run_value: RunValue,
    /// Lossy short-run merging (0: off).
    pub merge_short_runs: u32,
    /// How the file codes the runs (the entropy stage; no effect on the GPU-resident data).
    pub file_coding: FileCoding,
    /// Which intersection closes a pixel's interval.
    pub second_layer: SecondLayer,
    /// Where each texel's pixels sit.
    pub pixel_grid: PixelGrid,
    /// How the cube maps lie in the world.
    pub cube_frame: CubeFrame,
}

impl Variant {
    /// Whether `self` and `other` bake the same file (they differ at most in name and words).
    pub fn same_bake(&self, other: &Variant) -> bool {
        let settings = |v: &Variant| Variant {
            name: "",
            about: "",
            ..*v
        };
        settings(self) == settings(other)
    }
}

/// The paper's method: Spiral traversal, middle codes, lossless runs.
pub const PAPER: Variant = Variant {
    name: "paper",
    about: "the paper's method: spiral traversal, lossless runs storing the middle code; file: zstd only",
    traversal: Traversal::Spiral,
    chart_order: ChartOrder::Nearest,
    run_value: RunValue::Middle,
    merge_short_runs: 0,
    file_coding: FileCoding::Plain,
    second_layer: SecondLayer::Any,
    pixel_grid: PixelGrid::Centred,
    cube_frame: CubeFrame::World,
};

/// The options that win at the same accuracy, together (see the Options table of the report for
/// how each one measured alone). Lossless: the lossy short-run merge has a row of its own.
///
/// The chart order stays the paper's (next chart by nearest first texel): with the pilot and
/// `exchange`, `chart-ends` cost the Cornell box enough agreement to take the combination to the
/// line of "the same accuracy" for a gain of a fraction of a percent
/// (`reports/figures-from-docs.md` keeps the figures).
pub const BEST: Variant = Variant {
    name: "best",
    about: "inside each chart the Hilbert or the Spiral order, whichever a pilot bake at cube 8 compresses better; intervals bounded only by surfaces that face the texel (exchange: per pixel, the same answer for every pair that exchanges light); cube maps turned against the world; file: entropy stage",
    traversal: Traversal::Piloted,
    chart_order: ChartOrder::Nearest,
    run_value: RunValue::Middle,
    merge_short_runs: 0,
    file_coding: FileCoding::Packed,
    second_layer: SecondLayer::Exchange,
    pixel_grid: PixelGrid::Centred,
    cube_frame: CubeFrame::Turned,
};

/// Every option beyond the paper, one row each in the Options table (the first is the baseline).
pub const OPTIONS: [Variant; 16] = [
    PAPER,
    Variant {
        name: "entropy",
        about: "file only: entropy stage before zstd (run counts and lengths as varints, depths as differences to the neighbouring pixel)",
        file_coding: FileCoding::Packed,
        ..PAPER
    },
    Variant {
        name: "zigzag",
        about: "Zig-Zag traversal (paper)",
        traversal: Traversal::Zigzag,
        ..PAPER
    },
    Variant {
        name: "greedy",
        about: "Greedy traversal (paper)",
        traversal: Traversal::Greedy,
        ..PAPER
    },
    Variant {
        name: "hilbert",
        about: "Hilbert order inside charts (the generalised Hilbert curve over each chart's bounding rectangle)",
        traversal: Traversal::Hilbert,
        ..PAPER
    },
    Variant {
        name: "piloted",
        about: "inside each chart the Hilbert or the Spiral order, whichever a pilot bake of the chart at cube 8 compresses into fewer runs",
        traversal: Traversal::Piloted,
        ..PAPER
    },
    Variant {
        name: "chart-ends",
        about: "next chart: the one with an end (first or last texel) nearest, walked from it",
        chart_order: ChartOrder::Ends,
        ..PAPER
    },
    Variant {
        name: "balanced",
        about: "run value with equal relative margins (harmonic mean of the layers)",
        run_value: RunValue::Balanced,
        ..PAPER
    },
    Variant {
        name: "merge-1",
        about: "lossy: runs of 1 map merged into agreeing neighbours (Hilbert)",
        traversal: Traversal::Hilbert,
        merge_short_runs: 1,
        ..PAPER
    },
    Variant {
        name: "facing",
        about: "second layer: the nearest surface beyond the first that faces the texel (surfaces facing away exchange no light with it)",
        second_layer: SecondLayer::Facing,
        ..PAPER
    },
    Variant {
        name: "exchange",
        about: "facing, and a first surface that faces away sets no lower bound (nothing in front of it exchanges light with the texel); a pixel whose ray and neighbours meet no facing surface is don't care",
        second_layer: SecondLayer::Exchange,
        ..PAPER
    },
    Variant {
        name: "staggered",
        about: "each texel's pixel grid shifted by an eighth of a pixel, the signs by its atlas cell's parity (interleaved sampling)",
        pixel_grid: PixelGrid::Staggered,
        ..PAPER
    },
    Variant {
        name: "turned",
        about: "every cube map turned so that the world's up axis runs along the cube's diagonal (no world axis along a face axis)",
        cube_frame: CubeFrame::Turned,
        ..PAPER
    },
    BEST,
    Variant {
        name: "best-merge-2",
        about: "best, and lossy: runs of at most 2 maps merged into agreeing neighbours",
        merge_short_runs: 2,
        ..BEST
    },
    Variant {
        name: "spiral-merge-2",
        about: "lossy: runs of at most 2 maps merged (Spiral)",
        merge_short_runs: 2,
        ..PAPER
    },
];

/// What to run, as given on the command line of `cssm report compression`.
#[derive(clap::Args, Clone, Debug)]
pub struct CompressionArgs {
    /// Directory of the third-party scenes (teapot/, bunny/, sibenik/). Rows whose scene is
    /// absent are listed as not run, with the reason.
    #[arg(long, default_value = "../shared/scenes")]
    pub scenes: PathBuf,
    /// Directory to write compression.md, compression.csv and compression.svg into.
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
    /// A small grid for a smoke test: atlas 32 and 64, cube 8, the Cornell box only.
    #[arg(long)]
    pub quick: bool,
    /// Atlas resolutions to run instead of the paper's (comma-separated), for every table.
    #[arg(long, value_delimiter = ',')]
    pub atlas: Vec<u32>,
    /// Cube-map resolution to run instead of the paper's, for every table.
    #[arg(long)]
    pub cube: Option<u32>,
    /// Tables to run (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "table2,table3,options")]
    pub tables: Vec<TableId>,
    /// Scenes of Table 3 to run (comma-separated).
    #[arg(
        long = "scene",
        value_delimiter = ',',
        default_value = "cornell,heads,church,church3700"
    )]
    pub scene_ids: Vec<SceneId>,
    /// Random surface point pairs of each accuracy check.
    #[arg(long, default_value_t = 100_000)]
    pub pairs: u64,
}

/// Where the paper's figure for a row comes from.
#[derive(Clone, Copy, Debug)]
pub enum PaperFigures {
    /// Table 2's ratio.
    Table2(f64),
    /// A Table 3 row.
    Table3(paper::Table3Row),
    /// No figure in the paper.
    None,
}

impl PaperFigures {
    /// The paper's ratio, if it has one.
    pub fn ratio(&self) -> Option<f64> {
        match self {
            PaperFigures::Table2(r) => Some(*r),
            PaperFigures::Table3(row) => Some(row.ratio),
            PaperFigures::None => None,
        }
    }
}

/// One planned bake.
#[derive(Clone, Debug)]
pub struct Plan {
    /// Table it belongs to.
    pub table: TableId,
    /// Scene.
    pub scene: SceneId,
    /// Atlas resolution.
    pub atlas: u32,
    /// Cube-map resolution.
    pub cube: u32,
    /// Bake options.
    pub variant: Variant,
    /// The paper's figures for the row.
    pub paper: PaperFigures,
}

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

/// The rows `args` asks for, in report order.
pub fn plan(args: &CompressionArgs) -> Vec<Plan> {
    let atlas_override: Vec<u32> = if args.quick && args.atlas.is_empty() {
        vec![32, 64]
    } else {
        args.atlas.clone()
    };
    let cube_override = args.cube.or(args.quick.then_some(8));
    let scenes: Vec<SceneId> = if args.quick {
        vec![SceneId::Cornell]
    } else {
        args.scene_ids.clone()
    };
    let pick = |paper: Vec<u32>| {
        if atlas_override.is_empty() {
            paper
        } else {
            atlas_override.clone()
        }
    };
    let mut plans = Vec::new();
    let mut tables = args.tables.clone();
    tables.sort();
    tables.dedup();
    for table in tables {
        match table {
            TableId::Table2 => {
                for atlas in pick(vec![32, 64, 128]) {
                    for traversal in Traversal::ALL {
                        plans.push(Plan {
                            table,
                            scene: SceneId::Cornell,
                            atlas,
                            cube: cube_override.unwrap_or(paper::TABLE2_CUBE),
                            variant: Variant {
                                name: traversal.name(),
                                traversal,
                                ..PAPER
                            },
                            // The paper's figure only where the settings are the paper's.
                            paper: paper::table2(atlas, traversal)
                                .filter(|_| cube_override.is_none_or(|c| c == paper::TABLE2_CUBE))
                                .map_or(PaperFigures::None, PaperFigures::Table2),
                        });
                    }
                }
            }
            TableId::Table3 => {
                let mut ids = scenes.clone();
                ids.sort();
                ids.dedup();
                for scene in ids {
                    for atlas in pick(vec![64, 128, 256, 512]) {
                        let row = scene.paper_rows().iter().find(|r| r.atlas == atlas);
                        let cube = cube_override.unwrap_or(row.map_or(64, |r| r.cube));
                        // The paper's figures only where the settings are the paper's.
                        let row = row.filter(|r| r.cube == cube);
                        for variant in [PAPER, BEST] {
                            plans.push(Plan {
                                table,
                                scene,
                                atlas,
                                cube,
                                variant,
                                paper: row.map_or(PaperFigures::None, |r| PaperFigures::Table3(*r)),
                            });
                        }
                    }
                }
            }
            TableId::Options => {
                let atlas = pick(vec![128]).into_iter().max().unwrap_or(128);
                for variant in OPTIONS {
                    plans.push(Plan {
                        table,
                        scene: SceneId::Cornell,
                        atlas,
                        cube: cube_override.unwrap_or(64),
                        variant,
                        paper: PaperFigures::None,
                    });
                }
            }
        }
    }
    plans
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
            .map_err(|e| cssm_bake::flag_error(&e))?;
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

impl Plan {
    /// The row in words: table, scene, atlas, cube and variant.
    pub fn label(&self) -> String {
        format!(
            "{} {} atlas {} cube {} {}",
            self.table_name(),
            self.scene.name(),
            self.atlas,
            self.cube,
            self.variant.name
        )
    }

    /// What the row's `cssm bake` bakes, as the bake library takes it (the file coding is the
    /// writer's: [`Variant::file_coding`]).
    pub fn bake_options(&self) -> BakeOptions {
        let v = &self.variant;
        BakeOptions {
            atlas_resolution: self.atlas,
            cube_resolution: self.cube,
            traversal: v.traversal,
            chart_order: v.chart_order,
            near: None,
            run_value: v.run_value,
            merge_short_runs: v.merge_short_runs,
            second_layer: v.second_layer,
            cube_renderer: Default::default(),
            device: Default::default(),
            pixel_grid: v.pixel_grid,
            cube_frame: v.cube_frame,
        }
    }

    /// Name of the plan's table.
    pub fn table_name(&self) -> &'static str {
        match self.table {
            TableId::Table2 => "table2",
            TableId::Table3 => "table3",
            TableId::Options => "options",
        }
    }
}

/// Runs `cssm bake` and `cssm check` for one row in child processes.
fn bake_and_check(
    exe: &Path,
    scene: &Path,
    plan: &Plan,
    file: &Path,
    pairs: u64,
) -> Result<Measured, String> {
    let v = &plan.variant;
    let bake: BakeSummary = child_json(
        Command::new(exe)
            .arg("bake")
            .arg(scene)
            .arg("-o")
            .arg(file)
            .args(["--atlas", &plan.atlas.to_string()])
            .args(["--cube", &plan.cube.to_string()])
            .args(["--traversal", v.traversal.name()])
            .args(["--chart-order", v.chart_order.name()])
            .args(["--run-value", v.run_value.name()])
            .args(["--merge-short-runs", &v.merge_short_runs.to_string()])
            .args(["--file-coding", v.file_coding.name()])
            .args(["--second-layer", v.second_layer.name()])
            .args(["--pixel-grid", v.pixel_grid.name()])
            .args(["--cube-frame", v.cube_frame.name()])
            .arg("--json"),
        "bake",
    )?;
    let check = child_json::<CheckSummary>(
        Command::new(exe)
            .arg("check")
            .arg(file)
            .arg("--scene")
            .arg(scene)
            .args(["--pairs", &pairs.to_string()])
            .arg("--json"),
        "check",
    );
    let _ = std::fs::remove_file(file);
    let check = check?;
    Ok(Measured {
        faces: bake.triangles,
        charts: bake.charts.into(),
        maps: bake.defined_texels,
        runs: bake.runs,
        uncompressed: bake.uncompressed_bytes,
        gpu: bake.gpu_bytes,
        file: bake.file_bytes,
        seconds: bake.total_seconds,
        peak_rss: bake.peak_rss_bytes,
        agreement: check.exchanging_agreement,
        agreement_all: check.agreement,
        exchanging_pairs: check.exchanging_pairs,
        false_visible: check.exchanging_false_visible_rate,
        false_occluded: check.exchanging_false_occluded_rate,
    })
}

/// Runs a child `cssm` command and reads its JSON summary ([`crate::summary`]); a failure gives
/// its last error line.
fn child_json<T: serde::de::DeserializeOwned>(cmd: &mut Command, what: &str) -> Result<T, String> {
    let out = cmd
        .output()
        .map_err(|e| format!("cannot run {:?}: {e}", cmd.get_program()))?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let last = stderr
            .lines()
            .rev()
            .find(|l| l.starts_with("error"))
            .or_else(|| stderr.lines().last())
            .unwrap_or("no message");
        return Err(format!("{what} failed ({}): {last}", out.status));
    }
    // The summary is the last line (a library might print above it).
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .rev()
        .find(|l| l.starts_with('{'))
        .ok_or_else(|| format!("{what} --json printed no JSON object"))?;
    serde_json::from_str(line).map_err(|e| format!("{what} --json: {e}"))
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
