//! The bake variants of `cssm report compression`: the paper's method ([`PAPER`]), the options
//! that win at the same accuracy together ([`BEST`]), and the Options table's rows, every option
//! beyond the paper one at a time against the paper's method ([`OPTIONS`]).

use cssm_bake::{compress::RunValue, cubemap::SecondLayer, traverse::ChartOrder};
use cssm_formats::{
    Traversal,
    cssm::FileCoding,
    cube::{CubeFrame, PixelGrid},
};

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
