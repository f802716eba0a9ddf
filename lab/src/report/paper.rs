//! The paper's published figures (Ritschel et al. 2008, §5, Tables 2 and 3), transcribed from
//! `shared/papers/cssm-ritschel-2008.md`. They are quoted next to our measurements, never used
//! as measurements.

use cssm_formats::Traversal;

/// Table 2: compression factors for the Cornell box at cube `6 x 32 x 32`: `(atlas, traversal,
/// ratio)`.
pub const TABLE2: [(u32, Traversal, f64); 9] = [
    (32, Traversal::Greedy, 5.6),
    (32, Traversal::Zigzag, 7.1),
    (32, Traversal::Spiral, 7.4),
    (64, Traversal::Greedy, 8.8),
    (64, Traversal::Zigzag, 11.2),
    (64, Traversal::Spiral, 11.7),
    (128, Traversal::Greedy, 12.8),
    (128, Traversal::Zigzag, 15.7),
    (128, Traversal::Spiral, 16.9),
];

/// Cube resolution of Table 2.
pub const TABLE2_CUBE: u32 = 32;

/// The paper's ratio for a Table 2 cell.
pub fn table2(atlas: u32, traversal: Traversal) -> Option<f64> {
    TABLE2
        .iter()
        .find(|r| r.0 == atlas && r.1 == traversal)
        .map(|r| r.2)
}

/// One row of Table 3 (cube `6 x 64 x 64` unless `cube` says otherwise).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Table3Row {
    /// Atlas resolution.
    pub atlas: u32,
    /// Cube-map resolution the paper used for this row.
    pub cube: u32,
    /// Number of depth maps.
    pub maps: u64,
    /// Uncompressed size as printed (MB or GB; the paper's own unit).
    pub uncompressed: &'static str,
    /// Compressed size as printed.
    pub compressed: &'static str,
    /// Compression ratio.
    pub ratio: f64,
    /// Bake time as printed.
    pub time: &'static str,
    /// Bake time in seconds (for comparisons).
    pub seconds: f64,
}

// One argument per column of the paper's table, in its order.
#[allow(clippy::too_many_arguments)]
const fn row(
    atlas: u32,
    cube: u32,
    maps: u64,
    uncompressed: &'static str,
    compressed: &'static str,
    ratio: f64,
    time: &'static str,
    seconds: f64,
) -> Table3Row {
    Table3Row {
        atlas,
        cube,
        maps,
        uncompressed,
        compressed,
        ratio,
        time,
        seconds,
    }
}

/// Table 3, Cornell box (34 faces in the paper).
pub const CORNELL: [Table3Row; 4] = [
    row(64, 64, 2592, "127.4 MB", "8.0 MB", 15.9, "43 s", 43.0),
    row(128, 64, 10701, "525.9 MB", "21.5 MB", 24.4, "3 min", 180.0),
    row(256, 64, 42226, "2.0 GB", "62.1 MB", 33.4, "13 min", 780.0),
    row(512, 64, 170770, "8.4 GB", "202 MB", 41.5, "55 min", 3300.0),
];

/// Table 3, Cornell Heads (19k faces). The paper prints "411.2 GB" for the 128 row, a typo for
/// MB (8,367 maps of 6x64x64 16-bit pixels are 411 MB).
pub const HEADS: [Table3Row; 4] = [
    row(64, 64, 2002, "98.4 MB", "10.1 MB", 9.6, "52 s", 52.0),
    row(
        128,
        64,
        8367,
        "411.2 GB [sic]",
        "40.7 MB",
        10.1,
        "5 min",
        300.0,
    ),
    row(256, 64, 32964, "1.6 GB", "120.2 MB", 13.5, "18 min", 1080.0),
    row(
        512, 64, 129599, "6.3 GB", "249.9 MB", 25.4, "64 min", 3840.0,
    ),
];

/// Table 3, Cornell Church (3,700 faces in the paper). Its 512 row used `6 x 32 x 32` maps
/// (footnote 1: the GPU could not address more texels); the 128 row's "485.1 GB" is a typo for
/// MB.
pub const CHURCH: [Table3Row; 4] = [
    row(64, 64, 2479, "121.9 MB", "34.8 MB", 3.5, "47 s", 47.0),
    row(
        128,
        64,
        9869,
        "485.1 GB [sic]",
        "81.7 MB",
        5.9,
        "4 min",
        240.0,
    ),
    row(256, 64, 39751, "2.1 GB", "173.0 MB", 11.3, "14 min", 840.0),
    row(512, 32, 158969, "2.1 GB", "(91 MB)", 21.4, "73 min", 4380.0),
];
