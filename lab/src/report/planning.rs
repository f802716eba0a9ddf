//! The plan of `cssm report compression`: its tables ([`TableId`]) and Table 3's scenes
//! ([`SceneId`]), the command line's arguments ([`CompressionArgs`]), and the rows they ask for
//! ([`plan`]: [`Plan`], each with the paper's figures where its settings are the paper's).

use std::path::PathBuf;

use cssm_bake::BakeOptions;
use cssm_formats::Traversal;

use super::{BEST, OPTIONS, PAPER, Variant, paper};

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
    /// The Sibenik cathedral simplified to the paper's 3,700 faces ([`super::church`]).
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

    pub(super) fn paper_rows(self) -> &'static [paper::Table3Row] {
        match self {
            SceneId::Cornell => &paper::CORNELL,
            SceneId::Heads => &paper::HEADS,
            SceneId::Church | SceneId::Church3700 => &paper::CHURCH,
        }
    }

    /// The paper's face count for the scene, as Table 3 prints it.
    pub(super) fn paper_faces(self) -> &'static str {
        match self {
            SceneId::Cornell => "34",
            SceneId::Heads => "19k",
            SceneId::Church | SceneId::Church3700 => "3700",
        }
    }
}

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
