//! Coherent atlas traversal (§3.2.3 "Coherent Depth Cube Maps through Atlas Traversal").
//!
//! The depth cube maps of a CSSM are baked and compressed as one sequence; the compression only
//! works well when consecutive depth maps are *coherent*, i.e. when their texels are close on the
//! surface. §3.2.3 therefore visits the atlas *one chart after the other* (Zig-Zag or Spiral inside
//! a chart, then on to the chart with the closest 3D position), and, where no parametrization is
//! used, greedily walks the surface samples nearest-first.
//!
//! [`traverse`] returns that order as a permutation of the texel indices. Everything here is
//! deterministic: no hash-map iteration, no randomness, no threads; every tie is broken by an
//! index (texel index or chart id).
//!
//! Conventions:
//! - Atlas rows grow downwards (`y` = row), columns to the right (`x` = column).
//! - The *first* texel of a chart is its smallest `(y, x)` texel (row-major first). It is where
//!   both Zig-Zag and Spiral enter the chart, and it is the chart's 3D position when choosing the
//!   next chart.
//! - Non-finite position coordinates are treated as `0.0` for the distance computations.

use cssm_formats::{Texel, Traversal};

/// Order in which the depth maps are baked (§3.2.3): a permutation of `0..texels.len()`.
///
/// - [`Traversal::Zigzag`]: chart by chart; inside a chart, the rows of its bounding box from top
///   to bottom, alternately left-to-right and right-to-left, skipping cells of other charts.
/// - [`Traversal::Spiral`]: chart by chart; inside a chart, a walk along the border of the
///   unvisited region keeping it on the left hand, stepping back recursively when stuck
///   (see `SpiralWalker::spiral_chart`), which typically visits the chart from the outside in.
/// - [`Traversal::Hilbert`] (beyond the paper): chart by chart; inside a chart, the order in which
///   the generalised Hilbert curve over the chart's bounding rectangle (starting at its top-left
///   corner, along its longer side) meets the chart's texels.
/// - [`Traversal::Piloted`] (beyond the paper): chart by chart; inside each chart the Hilbert
///   order or the Spiral walk, whichever a pilot says makes fewer runs ([`traverse_piloted`]).
/// - [`Traversal::Greedy`]: ignores the atlas; from the row-major first texel, always on to the
///   nearest not-yet-visited texel in 3D (ties: smaller texel index).
///
/// For Zig-Zag and Spiral the first chart is the one holding the row-major first texel (smallest
/// `(y, x)`, then smallest index); after a chart, the next one is the not-yet-visited chart whose
/// first texel is closest in 3D to the last visited texel (ties: smaller chart id). Every chart's
/// texels form one contiguous block of the result.
///
/// `atlas_resolution` is the side of the square atlas; it sizes the cell lookup used by the
/// Spiral walk (coordinates beyond it are still handled). Runs in `O(n log n)` for `n` texels.
pub fn traverse(texels: &[Texel], atlas_resolution: u32, traversal: Traversal) -> Vec<u32> {
    traverse_with(texels, atlas_resolution, traversal, ChartOrder::Nearest)
}

/// A chart visit: `(chart id, the chart's texels in row-major order, output)`; must append
/// exactly those texels, in any order.
type VisitChart<'a> = dyn FnMut(u32, &[u32], &mut Vec<u32>) + 'a;

/// How the chart-by-chart traversals pick the next chart.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ChartOrder {
    /// §3.2.3: the unvisited chart whose first texel is closest in 3D to the last texel visited;
    /// every chart is walked from its first texel.
    #[default]
    Nearest,
    /// Beyond the paper: the unvisited chart with an *end* (the first or the last texel of its
    /// own walk) closest to the last texel visited, walked backwards when that end is its last.
    /// The walk then crosses into the chart across the border where the previous one ended,
    /// instead of jumping to wherever the next chart's walk happens to start.
    Ends,
}

impl ChartOrder {
    /// Every choice, default first.
    pub const ALL: [ChartOrder; 2] = [ChartOrder::Nearest, ChartOrder::Ends];

    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ChartOrder::Nearest => "nearest",
            ChartOrder::Ends => "ends",
        }
    }
}

impl std::fmt::Display for ChartOrder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for ChartOrder {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "nearest" => Ok(ChartOrder::Nearest),
            "ends" => Ok(ChartOrder::Ends),
            other => Err(format!(
                "unknown chart order '{other}': expected nearest or ends"
            )),
        }
    }
}

/// [`traverse`] with the next chart chosen as `chart_order` says (no effect on Greedy).
/// [`Traversal::Piloted`] without a pilot is the Hilbert order; see [`traverse_piloted`].
pub fn traverse_with(
    texels: &[Texel],
    atlas_resolution: u32,
    traversal: Traversal,
    chart_order: ChartOrder,
) -> Vec<u32> {
    traverse_piloted(texels, atlas_resolution, traversal, chart_order, &|_| 0)
}

/// A pilot for [`Traversal::Piloted`]: given candidate orders of one chart's texels, the index of
/// the order to keep (out-of-range answers keep the first).
pub type Pilot<'a> = dyn Fn(&[&[u32]]) -> usize + 'a;

/// [`traverse_with`], where [`Traversal::Piloted`] asks `pilot` to choose, chart by chart,
/// between the chart's Hilbert order (candidate 0) and its Spiral walk (candidate 1). Other
/// traversals ignore the pilot.
pub fn traverse_piloted(
    texels: &[Texel],
    atlas_resolution: u32,
    traversal: Traversal,
    chart_order: ChartOrder,
    pilot: &Pilot,
) -> Vec<u32> {
    if texels.is_empty() {
        return Vec::new();
    }
    let by_chart = |visit: &mut VisitChart| match chart_order {
        ChartOrder::Nearest => chart_by_chart(texels, visit),
        ChartOrder::Ends => chart_by_chart_ends(texels, visit),
    };
    match traversal {
        Traversal::Greedy => greedy_order(texels),
        Traversal::Zigzag => by_chart(&mut |_, rows, out| zigzag_chart(texels, rows, out)),
        Traversal::Hilbert => by_chart(&mut |_, rows, out| hilbert_chart(texels, rows, out)),
        Traversal::Piloted => {
            let cells = CellIndex::new(texels, atlas_resolution, DENSE_CELL_LIMIT);
            let mut walker = SpiralWalker::new(texels, &cells);
            let (mut hilbert, mut spiral) = (Vec::new(), Vec::new());
            by_chart(&mut |_, rows, out| {
                hilbert.clear();
                spiral.clear();
                hilbert_chart(texels, rows, &mut hilbert);
                walker.spiral_chart(rows, &mut spiral);
                let chosen = if hilbert == spiral {
                    0
                } else {
                    pilot(&[&hilbert, &spiral])
                };
                out.extend_from_slice(if chosen == 1 { &spiral } else { &hilbert });
            })
        }
        Traversal::Spiral => {
            let cells = CellIndex::new(texels, atlas_resolution, DENSE_CELL_LIMIT);
            let mut walker = SpiralWalker::new(texels, &cells);
            by_chart(&mut |_, rows, out| walker.spiral_chart(rows, out))
        }
    }
}

/// Upper bound on the number of cells of the dense atlas lookup used by the Spiral walk (§3.2.3);
/// larger (or sparser) atlases use a sorted lookup instead. The effective limit is at least four
/// cells per texel.
const DENSE_CELL_LIMIT: usize = 1 << 24;

/// Sentinel for "no texel / no node".
const NONE: u32 = u32::MAX;

/// Texel indices sorted row-major (`(y, x)`, then index) with the smallest one first: the texel
/// where the Greedy walk and the first chart of Zig-Zag / Spiral start (§3.2.3).
fn first_texel(texels: &[Texel]) -> u32 {
    (0..texels.len() as u32)
        .min_by_key(|&i| {
            let t = &texels[i as usize];
            (t.y, t.x, i)
        })
        .expect("non-empty texel slice")
}

/// 3D position of a texel with non-finite coordinates replaced by `0.0`, so that the distance
/// comparisons of the chart ordering and of the Greedy walk (§3.2.3) are total.
fn sanitized_position(t: &Texel) -> [f32; 3] {
    t.position.map(|c| if c.is_finite() { c } else { 0.0 })
}

/// Squared Euclidean distance, always summed in the same order so that the k-d tree's box bound
/// is exactly a lower bound in floating point.
#[inline]
fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    let dx = a[0] - b[0];
    let dy = a[1] - b[1];
    let dz = a[2] - b[2];
    dx * dx + dy * dy + dz * dz
}

/// Drives the chart-by-chart strategies of §3.2.3 ("one chart after the other is visited").
///
/// Groups the texels by chart (each chart's texels in row-major order), starts with the chart of
/// the row-major first texel, lets `visit_chart(chart_id, rows, out)` append that chart's order,
/// and then moves to the unvisited chart whose first texel is closest in 3D to the last texel
/// appended (ties: smaller chart id). The nearest-chart queries use a [`NearestSet`] over the
/// charts' first texels, so this costs `O(n log n + c log c)` for `n` texels and `c` charts.
///
/// `visit_chart` must append exactly the texels of `rows` (in any order).
fn chart_by_chart(texels: &[Texel], visit_chart: &mut VisitChart) -> Vec<u32> {
    let n = texels.len();
    let (sorted, runs) = chart_runs(texels);
    let entries: Vec<[f32; 3]> = runs
        .iter()
        .map(|&(_, s, _)| sanitized_position(&texels[sorted[s] as usize]))
        .collect();
    let mut remaining = NearestSet::new(&entries);

    let first_chart = texels[first_texel(texels) as usize].chart;
    let mut current = runs
        .binary_search_by_key(&first_chart, |r| r.0)
        .expect("the first texel's chart has a run") as u32;
    let mut out = Vec::with_capacity(n);
    loop {
        let (chart, s, e) = runs[current as usize];
        let before = out.len();
        visit_chart(chart, &sorted[s..e], &mut out);
        debug_assert_eq!(
            out.len() - before,
            e - s,
            "a chart visit must emit its texels"
        );
        remaining.remove(current);
        let last = sanitized_position(&texels[*out.last().expect("charts are non-empty") as usize]);
        match remaining.nearest(last) {
            Some(next) => current = next,
            None => break,
        }
    }
    out
}

/// The chart order of [`ChartOrder::Ends`]: every chart's own walk is computed first (in chart
/// id order), then charts are strung together starting with the chart of the row-major first
/// texel (walked forwards), always moving to the unvisited chart with an end nearest to the last
/// texel emitted (ties: smaller chart id, then its first end), walked backwards when that end is
/// its last texel. `O(n log n + c log c)`.
fn chart_by_chart_ends(texels: &[Texel], visit_chart: &mut VisitChart) -> Vec<u32> {
    let n = texels.len();
    let (sorted, runs) = chart_runs(texels);
    let mut walks = Vec::with_capacity(n);
    let mut ranges = Vec::with_capacity(runs.len());
    for &(chart, s, e) in &runs {
        let before = walks.len();
        visit_chart(chart, &sorted[s..e], &mut walks);
        debug_assert_eq!(
            walks.len() - before,
            e - s,
            "a chart visit must emit its texels"
        );
        ranges.push(before..walks.len());
    }
    // Point 2k is chart run k's first texel, point 2k + 1 its last.
    let pos = |i: u32| sanitized_position(&texels[i as usize]);
    let ends: Vec<[f32; 3]> = ranges
        .iter()
        .flat_map(|r| [pos(walks[r.start]), pos(walks[r.end - 1])])
        .collect();
    let mut remaining = NearestSet::new(&ends);
    let first_chart = texels[first_texel(texels) as usize].chart;
    let mut current = runs
        .binary_search_by_key(&first_chart, |r| r.0)
        .expect("the first texel's chart has a run");
    let mut backwards = false;
    let mut out = Vec::with_capacity(n);
    loop {
        let walk = &walks[ranges[current].clone()];
        if backwards {
            out.extend(walk.iter().rev());
        } else {
            out.extend_from_slice(walk);
        }
        remaining.remove(2 * current as u32);
        remaining.remove(2 * current as u32 + 1);
        let last = pos(*out.last().expect("charts are non-empty"));
        match remaining.nearest(last) {
            Some(end) => {
                current = (end / 2) as usize;
                backwards = end % 2 == 1;
            }
            None => break,
        }
    }
    out
}

/// All texels sorted by `(chart, y, x, index)` (charts become contiguous, each row-major), and
/// the runs of equal chart `(chart id, start, end)` in increasing chart id.
fn chart_runs(texels: &[Texel]) -> (Vec<u32>, Vec<(u32, usize, usize)>) {
    let n = texels.len();
    // All texels sorted by (chart, y, x, index): charts become contiguous runs, each row-major.
    let mut sorted: Vec<u32> = (0..n as u32).collect();
    sorted.sort_unstable_by_key(|&i| {
        let t = &texels[i as usize];
        (t.chart, t.y, t.x, i)
    });
    // Runs of equal chart id: (chart id, start, end) in increasing chart id.
    let mut runs: Vec<(u32, usize, usize)> = Vec::new();
    let mut start = 0;
    while start < n {
        let chart = texels[sorted[start] as usize].chart;
        let mut end = start + 1;
        while end < n && texels[sorted[end] as usize].chart == chart {
            end += 1;
        }
        runs.push((chart, start, end));
        start = end;
    }
    (sorted, runs)
}

/// Zig-Zag inside one chart (§3.2.3): "visit all texels inside the box in a zig-zag pattern from
/// top to bottom", skipping cells that are undefined or belong to another chart.
///
/// `rows` are the chart's texels in row-major order. Row `r` of the chart's bounding box (counted
/// from its top row, empty rows included) is visited left-to-right when `r` is even and
/// right-to-left when `r` is odd.
fn zigzag_chart(texels: &[Texel], rows: &[u32], out: &mut Vec<u32>) {
    let Some(&first) = rows.first() else {
        return;
    };
    let top = texels[first as usize].y;
    let mut start = 0;
    while start < rows.len() {
        let y = texels[rows[start] as usize].y;
        let mut end = start + 1;
        while end < rows.len() && texels[rows[end] as usize].y == y {
            end += 1;
        }
        if (y - top) % 2 == 0 {
            out.extend_from_slice(&rows[start..end]);
        } else {
            out.extend(rows[start..end].iter().rev());
        }
        start = end;
    }
}

/// Hilbert order inside one chart (beyond §3.2.3, which keeps the CSM's Hilbert pattern for
/// square depth-map grids only): the chart's texels sorted by their position along the
/// generalised Hilbert curve over the chart's bounding rectangle ([`gilbert_ranks`]). The curve
/// visits one half or quadrant of the rectangle before the next, so consecutive texels stay
/// close in both atlas directions, which shortens the depth drift inside a run compared with
/// long Zig-Zag rows; unlike a power-of-two Hilbert curve over the bounding square it fits long
/// thin charts without wandering outside them (Cornell box, atlas 128, cube 32: 3% fewer runs).
fn hilbert_chart(texels: &[Texel], rows: &[u32], out: &mut Vec<u32>) {
    let Some(&first) = rows.first() else {
        return;
    };
    let t0 = &texels[first as usize];
    let (mut x0, mut y0, mut x1, mut y1) = (t0.x, t0.y, t0.x, t0.y);
    for &i in rows {
        let t = &texels[i as usize];
        (x0, y0, x1, y1) = (x0.min(t.x), y0.min(t.y), x1.max(t.x), y1.max(t.y));
    }
    let (width, height) = (u32::from(x1 - x0) + 1, u32::from(y1 - y0) + 1);
    if u64::from(width) * u64::from(height) > MAX_CURVE_CELLS {
        // Only hand-made texels spread this far (an atlas is at most 1024 x 1024): keep memory
        // bounded and take them row by row.
        out.extend_from_slice(rows);
        return;
    }
    let rank = gilbert_ranks(width, height);
    let mut keyed: Vec<(u32, u32)> = rows
        .iter()
        .map(|&i| {
            let t = &texels[i as usize];
            let cell = u32::from(t.y - y0) * width + u32::from(t.x - x0);
            (rank[cell as usize], i)
        })
        .collect();
    keyed.sort_unstable();
    out.extend(keyed.iter().map(|&(_, i)| i));
}

/// Largest bounding rectangle, in cells, that [`hilbert_chart`] lays a curve over (64 MiB of
/// ranks; sixteen times the largest atlas).
const MAX_CURVE_CELLS: u64 = 1 << 24;

/// Position of every cell of a `width x height` grid (row-major) along the generalised Hilbert
/// curve over it ("gilbert", J. Červený): the Hilbert curve's recursive quadrant split, adapted to
/// any rectangle, every step to a 4-neighbour (one diagonal step at most, when a side is odd);
/// on a long strip it degenerates into a serpentine across the short side.
pub fn gilbert_ranks(width: u32, height: u32) -> Vec<u32> {
    let mut ranks = vec![0; (width * height) as usize];
    let mut next = 0;
    let (w, h) = (width as i64, height as i64);
    let mut visit = |x: i64, y: i64| {
        ranks[(y * w + x) as usize] = next;
        next += 1;
    };
    if w >= h {
        gilbert(0, 0, w, 0, 0, h, &mut visit);
    } else {
        gilbert(0, 0, 0, h, w, 0, &mut visit);
    }
    ranks
}

/// One block of the generalised Hilbert curve: from `(x, y)`, major axis `(ax, ay)`, minor axis
/// `(bx, by)`.
fn gilbert(x: i64, y: i64, ax: i64, ay: i64, bx: i64, by: i64, visit: &mut impl FnMut(i64, i64)) {
    let (w, h) = ((ax + ay).abs(), (bx + by).abs());
    let (dax, day) = (ax.signum(), ay.signum());
    let (dbx, dby) = (bx.signum(), by.signum());
    if h == 1 || w == 1 {
        let (n, sx, sy) = if h == 1 { (w, dax, day) } else { (h, dbx, dby) };
        for i in 0..n {
            visit(x + i * sx, y + i * sy);
        }
        return;
    }
    let (mut ax2, mut ay2) = (ax.div_euclid(2), ay.div_euclid(2));
    let (mut bx2, mut by2) = (bx.div_euclid(2), by.div_euclid(2));
    let (w2, h2) = ((ax2 + ay2).abs(), (bx2 + by2).abs());
    if 2 * w > 3 * h {
        if w2 % 2 == 1 && w > 2 {
            (ax2, ay2) = (ax2 + dax, ay2 + day);
        }
        gilbert(x, y, ax2, ay2, bx, by, visit);
        gilbert(x + ax2, y + ay2, ax - ax2, ay - ay2, bx, by, visit);
    } else {
        if h2 % 2 == 1 && h > 2 {
            (bx2, by2) = (bx2 + dbx, by2 + dby);
        }
        gilbert(x, y, bx2, by2, ax2, ay2, visit);
        gilbert(x + bx2, y + by2, ax, ay, bx - bx2, by - by2, visit);
        gilbert(
            x + (ax - dax) + (bx2 - dbx),
            y + (ay - day) + (by2 - dby),
            -bx2,
            -by2,
            -(ax - ax2),
            -(ay - ay2),
            visit,
        );
    }
}

/// Cell → texel lookup over the atlas grid for the Spiral walk (§3.2.3), which needs the
/// 4-neighbours of a texel.
///
/// Dense (one `u32` per cell of `max(resolution, max x + 1) × max(resolution, max y + 1)`) when
/// that is at most `max(dense_limit, 4 n)` cells, otherwise a sorted `(cell key, texel)` table
/// searched by bisection. If several texels claim one cell (which valid atlases never do), the
/// lookup keeps the smallest index; the others are still emitted by the Spiral's restarts.
#[derive(Debug)]
enum CellIndex {
    /// Row-major grid of texel indices, [`NONE`] for undefined cells.
    Dense {
        /// Grid width in cells.
        width: u32,
        /// Grid height in cells.
        height: u32,
        /// `cells[y * width + x]`.
        cells: Vec<u32>,
    },
    /// `(y << 16 | x, texel)` sorted by key, one entry per key.
    Sparse(Vec<(u32, u32)>),
}

impl CellIndex {
    /// Builds the lookup for `texels` (see the type's docs for the dense / sparse choice).
    fn new(texels: &[Texel], resolution: u32, dense_limit: usize) -> Self {
        let max_x = texels.iter().map(|t| u32::from(t.x)).max().unwrap_or(0);
        let max_y = texels.iter().map(|t| u32::from(t.y)).max().unwrap_or(0);
        let width = resolution.max(max_x + 1);
        let height = resolution.max(max_y + 1);
        let area = width as usize * height as usize;
        if area <= dense_limit.max(4 * texels.len()) {
            let mut cells = vec![NONE; area];
            for (i, t) in texels.iter().enumerate() {
                let c = &mut cells[t.y as usize * width as usize + t.x as usize];
                if *c == NONE {
                    *c = i as u32;
                }
            }
            CellIndex::Dense {
                width,
                height,
                cells,
            }
        } else {
            let mut table: Vec<(u32, u32)> = texels
                .iter()
                .enumerate()
                .map(|(i, t)| ((u32::from(t.y) << 16) | u32::from(t.x), i as u32))
                .collect();
            table.sort_unstable();
            table.dedup_by_key(|e| e.0);
            CellIndex::Sparse(table)
        }
    }

    /// Texel at cell `(x, y)`, if any (coordinates outside the grid give `None`).
    #[inline]
    fn get(&self, x: i32, y: i32) -> Option<u32> {
        if x < 0 || y < 0 {
            return None;
        }
        let (x, y) = (x as u32, y as u32);
        match self {
            CellIndex::Dense {
                width,
                height,
                cells,
            } => {
                if x >= *width || y >= *height {
                    return None;
                }
                let c = cells[y as usize * *width as usize + x as usize];
                (c != NONE).then_some(c)
            }
            CellIndex::Sparse(table) => {
                if x > 0xFFFF || y > 0xFFFF {
                    return None;
                }
                let key = (y << 16) | x;
                table
                    .binary_search_by_key(&key, |e| e.0)
                    .ok()
                    .map(|p| table[p].1)
            }
        }
    }
}

/// Headings of the Spiral walk, numbered counter-clockwise as seen on the atlas (rows grow
/// downwards): `+1` is a left turn. Offsets `(dx, dy)` for east, north, west, south.
const HEADING_OFFSETS: [(i32, i32); 4] = [(1, 0), (0, -1), (-1, 0), (0, 1)];
/// Heading east: the start heading of a Spiral walk, whose start cell (row-major first unvisited
/// cell) has no unvisited chart cell above it, i.e. on its left.
const EAST: u8 = 0;
/// Turn order of the Spiral walk relative to the current heading: left, straight, right, back.
const TURNS: [u8; 4] = [1, 0, 3, 2];

/// State of the Spiral strategy (§3.2.3) shared by all charts: visited flags and the path stack.
struct SpiralWalker<'a> {
    /// The texel table.
    texels: &'a [Texel],
    /// Atlas cell lookup.
    cells: &'a CellIndex,
    /// Per texel: already emitted.
    visited: Vec<bool>,
    /// The visited path, `(texel, heading on arrival)`; its top is the current cell.
    stack: Vec<(u32, u8)>,
}

impl<'a> SpiralWalker<'a> {
    /// A walker with nothing visited.
    fn new(texels: &'a [Texel], cells: &'a CellIndex) -> Self {
        SpiralWalker {
            texels,
            cells,
            visited: vec![false; texels.len()],
            stack: Vec::new(),
        }
    }

    /// Spiral inside one chart (§3.2.3): "moves along the border of each chart, marking each
    /// visited texel … walking along left hand side of the border as long as possible. If there is
    /// no free texel in the neighborhood, we step back recursively until a free neighbor is
    /// available."
    ///
    /// `rows` are the chart's texels in row-major order. The walk starts at the first one (a
    /// border texel) heading east, so the outside is on the left. From the current cell and
    /// heading it tries the 4-neighbours turning left, straight, right, then back, and moves to the
    /// first unvisited cell of the same chart, emitting it. When none is free it steps back along
    /// the visited path (a stack; stepped-back cells are not emitted again) and resumes from the
    /// first cell with a free neighbour, with the heading it had when it arrived there. When the
    /// path is exhausted but the chart still has unvisited texels (a chart split in the atlas
    /// grid), it restarts at the row-major first unvisited texel. Linear in the chart size.
    fn spiral_chart(&mut self, rows: &[u32], out: &mut Vec<u32>) {
        let Some(&first) = rows.first() else {
            return;
        };
        let chart = self.texels[first as usize].chart;
        let mut cursor = 0;
        loop {
            while cursor < rows.len() && self.visited[rows[cursor] as usize] {
                cursor += 1;
            }
            let Some(&start) = rows.get(cursor) else {
                break;
            };
            self.visited[start as usize] = true;
            out.push(start);
            self.stack.push((start, EAST));
            while let Some(&(cur, heading)) = self.stack.last() {
                match self.free_neighbour(cur, heading, chart) {
                    Some((next, dir)) => {
                        self.visited[next as usize] = true;
                        out.push(next);
                        self.stack.push((next, dir));
                    }
                    None => {
                        self.stack.pop();
                    }
                }
            }
        }
    }

    /// First unvisited 4-neighbour of `cur` in `chart`, trying left, straight, right, back relative
    /// to `heading` (the left-hand rule of §3.2.3's Spiral), with the heading that reaches it.
    #[inline]
    fn free_neighbour(&self, cur: u32, heading: u8, chart: u32) -> Option<(u32, u8)> {
        let t = &self.texels[cur as usize];
        let (x, y) = (i32::from(t.x), i32::from(t.y));
        TURNS.iter().find_map(|&turn| {
            let dir = (heading + turn) % 4;
            let (dx, dy) = HEADING_OFFSETS[dir as usize];
            let nb = self.cells.get(x + dx, y + dy)?;
            (self.texels[nb as usize].chart == chart && !self.visited[nb as usize])
                .then_some((nb, dir))
        })
    }
}

/// Greedy traversal (§3.2.3: "a traversal that greedily walks a number of random samples that
/// were distributed evenly across the surface"), here over the texel positions themselves.
///
/// Starts at the row-major first texel and repeatedly moves to the nearest unvisited texel in 3D
/// (ties: smaller texel index), using a [`NearestSet`]; `O(n log n)` in practice.
fn greedy_order(texels: &[Texel]) -> Vec<u32> {
    let points: Vec<[f32; 3]> = texels.iter().map(sanitized_position).collect();
    let mut set = NearestSet::new(&points);
    let mut out = Vec::with_capacity(texels.len());
    let mut current = first_texel(texels);
    loop {
        out.push(current);
        set.remove(current);
        match set.nearest(points[current as usize]) {
            Some(next) => current = next,
            None => break,
        }
    }
    out
}

/// Leaf size of the [`NearestSet`] k-d tree.
const LEAF_SIZE: usize = 8;

/// One node of the [`NearestSet`] k-d tree.
#[derive(Clone, Copy, Debug)]
struct KdNode {
    /// Lower corner of the bounding box of the node's points (as built; not shrunk on removal).
    lo: [f32; 3],
    /// Upper corner of the bounding box.
    hi: [f32; 3],
    /// Range `start..end` of the node's points in the tree's point order.
    start: u32,
    /// End of the point range.
    end: u32,
    /// Children (`NONE` for a leaf).
    children: [u32; 2],
    /// Parent (`NONE` for the root).
    parent: u32,
    /// Number of points of the node not yet removed.
    alive: u32,
}

/// A set of 3D points supporting "nearest remaining point" queries and removal: the spatial
/// structure behind the next-chart choice and the Greedy walk of §3.2.3.
///
/// A static k-d tree (median splits on the widest axis, leaves of up to [`LEAF_SIZE`] points) with
/// per-node counts of remaining points, so exhausted subtrees are skipped. Queries return the
/// point minimising `(squared distance, point index)`, which makes them deterministic and
/// independent of the tree layout. Points must be finite.
#[derive(Debug)]
struct NearestSet {
    /// Nodes; node 0 is the root (absent when there are no points).
    nodes: Vec<KdNode>,
    /// Points in tree order.
    points: Vec<[f32; 3]>,
    /// Original index of each point in tree order.
    ids: Vec<u32>,
    /// Per tree-order slot: not yet removed.
    alive: Vec<bool>,
    /// Per original index: its tree-order slot.
    slot_of: Vec<u32>,
    /// Per tree-order slot: its leaf node.
    leaf_of: Vec<u32>,
    /// Reusable traversal stack of `(node, squared box distance)`.
    stack: Vec<(u32, f32)>,
}

impl NearestSet {
    /// Builds the set holding all of `points` (indices `0..points.len()`).
    fn new(points: &[[f32; 3]]) -> Self {
        let n = points.len();
        let mut ids: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n / LEAF_SIZE + 2);
        let mut leaf_of = vec![NONE; n];
        if n > 0 {
            // Explicit work list instead of recursion: (node index, start, end).
            nodes.push(Self::make_node(points, &ids, 0, n, NONE));
            let mut work = vec![0u32];
            while let Some(node) = work.pop() {
                let KdNode {
                    lo, hi, start, end, ..
                } = nodes[node as usize];
                let (start, end) = (start as usize, end as usize);
                if end - start <= LEAF_SIZE {
                    leaf_of[start..end].fill(node);
                    continue;
                }
                let axis = (0..3)
                    .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])).then(b.cmp(&a)))
                    .expect("three axes");
                let mid = start + (end - start) / 2;
                ids[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
                    points[a as usize][axis]
                        .total_cmp(&points[b as usize][axis])
                        .then(a.cmp(&b))
                });
                let left = nodes.len() as u32;
                nodes.push(Self::make_node(points, &ids, start, mid, node));
                nodes.push(Self::make_node(points, &ids, mid, end, node));
                nodes[node as usize].children = [left, left + 1];
                work.push(left + 1);
                work.push(left);
            }
        }
        let mut slot_of = vec![NONE; n];
        for (slot, &id) in ids.iter().enumerate() {
            slot_of[id as usize] = slot as u32;
        }
        NearestSet {
            nodes,
            points: ids.iter().map(|&id| points[id as usize]).collect(),
            ids,
            alive: vec![true; n],
            slot_of,
            leaf_of,
            stack: Vec::new(),
        }
    }

    /// A node over `ids[start..end]` with its bounding box, no children, all points alive.
    fn make_node(
        points: &[[f32; 3]],
        ids: &[u32],
        start: usize,
        end: usize,
        parent: u32,
    ) -> KdNode {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for &id in &ids[start..end] {
            let p = points[id as usize];
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        KdNode {
            lo,
            hi,
            start: start as u32,
            end: end as u32,
            children: [NONE; 2],
            parent,
            alive: (end - start) as u32,
        }
    }

    /// Removes point `id` (no effect if already removed).
    fn remove(&mut self, id: u32) {
        let slot = self.slot_of[id as usize] as usize;
        if !std::mem::replace(&mut self.alive[slot], false) {
            return;
        }
        let mut node = self.leaf_of[slot];
        while node != NONE {
            let n = &mut self.nodes[node as usize];
            n.alive -= 1;
            node = n.parent;
        }
    }

    /// Squared distance from `q` to the bounding box of `node` (0 inside); never larger than the
    /// [`dist2`] of `q` to any point of the node, also in floating point.
    #[inline]
    fn box_dist2(&self, node: u32, q: [f32; 3]) -> f32 {
        let n = &self.nodes[node as usize];
        let mut d = [0.0f32; 3];
        for a in 0..3 {
            d[a] = if q[a] < n.lo[a] {
                n.lo[a] - q[a]
            } else if q[a] > n.hi[a] {
                q[a] - n.hi[a]
            } else {
                0.0
            };
        }
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    }

    /// The remaining point minimising `(dist2(point, q), index)`, or `None` when empty.
    fn nearest(&mut self, q: [f32; 3]) -> Option<u32> {
        if self.nodes.first().is_none_or(|root| root.alive == 0) {
            return None;
        }
        let mut best_d = f32::INFINITY;
        let mut best_id = NONE;
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        stack.push((0, 0.0));
        while let Some((node, bound)) = stack.pop() {
            // Equal bounds may still hold an equally near point with a smaller index.
            if bound > best_d {
                continue;
            }
            let n = self.nodes[node as usize];
            if n.children[0] == NONE {
                for slot in n.start as usize..n.end as usize {
                    if !self.alive[slot] {
                        continue;
                    }
                    let d = dist2(self.points[slot], q);
                    let id = self.ids[slot];
                    if d < best_d || (d == best_d && id < best_id) {
                        best_d = d;
                        best_id = id;
                    }
                }
                continue;
            }
            let [a, b] = n.children;
            let da = self.box_dist2(a, q);
            let db = self.box_dist2(b, q);
            // Push the farther child first so the nearer one is searched first.
            let (near, dn, far, df) = if db < da {
                (b, db, a, da)
            } else {
                (a, da, b, db)
            };
            if self.nodes[far as usize].alive > 0 && df <= best_d {
                stack.push((far, df));
            }
            if self.nodes[near as usize].alive > 0 && dn <= best_d {
                stack.push((near, dn));
            }
        }
        self.stack = stack;
        (best_id != NONE).then_some(best_id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gilbert_visits_every_cell_once_in_neighbouring_steps() {
        let sizes = (1..=24).flat_map(|w| (1..=24).map(move |h| (w, h)));
        for (w, h) in sizes.chain([(12, 40), (33, 17), (64, 64), (100, 3)]) {
            let ranks = gilbert_ranks(w, h);
            let mut cells = vec![(0i64, 0i64); (w * h) as usize];
            let mut seen = vec![false; (w * h) as usize];
            for (cell, &r) in ranks.iter().enumerate() {
                assert!(!seen[r as usize], "{w}x{h}: rank {r} twice");
                seen[r as usize] = true;
                cells[r as usize] = ((cell as u32 % w) as i64, (cell as u32 / w) as i64);
            }
            // Steps to a 4-neighbour, with at most one diagonal step, only when a side is odd.
            let diagonal = cells
                .windows(2)
                .map(|p| {
                    let (dx, dy) = ((p[1].0 - p[0].0).abs(), (p[1].1 - p[0].1).abs());
                    assert!(dx <= 1 && dy <= 1 && dx + dy >= 1, "{w}x{h}: {:?}", p);
                    usize::from(dx + dy == 2)
                })
                .sum::<usize>();
            assert!(
                diagonal <= usize::from(w % 2 == 1 || h % 2 == 1),
                "{w}x{h}: {diagonal}"
            );
        }
    }

    /// A texel at atlas cell `(x, y)` of `chart` with 3D position `position`.
    fn texel(x: u16, y: u16, chart: u32, position: [f32; 3]) -> Texel {
        Texel {
            position,
            normal: [0.0, 0.0, 1.0],
            area: 1.0,
            material: 0,
            chart,
            x,
            y,
        }
    }

    /// Texels from an ASCII atlas: a digit is a texel of that chart, anything else undefined.
    /// Position: `(x, y, 10 * chart)`. Texels in row-major order.
    fn atlas(rows: &[&str]) -> Vec<Texel> {
        let mut out = Vec::new();
        for (y, row) in rows.iter().enumerate() {
            for (x, c) in row.chars().enumerate() {
                if let Some(chart) = c.to_digit(10) {
                    let p = [x as f32, y as f32, 10.0 * chart as f32];
                    out.push(texel(x as u16, y as u16, chart, p));
                }
            }
        }
        out
    }

    /// The `(x, y)` cells of a traversal.
    fn cells(texels: &[Texel], order: &[u32]) -> Vec<(u16, u16)> {
        order
            .iter()
            .map(|&i| (texels[i as usize].x, texels[i as usize].y))
            .collect()
    }

    /// Asserts that `order` is a permutation of `0..texels.len()`.
    fn assert_permutation(texels: &[Texel], order: &[u32]) {
        let mut seen = vec![false; texels.len()];
        assert_eq!(order.len(), texels.len());
        for &i in order {
            assert!(!std::mem::replace(&mut seen[i as usize], true), "{i} twice");
        }
    }

    /// Asserts that every chart forms one contiguous block of `order`.
    fn assert_charts_contiguous(texels: &[Texel], order: &[u32]) {
        let mut finished = std::collections::BTreeSet::new();
        let mut prev = None;
        for &i in order {
            let c = texels[i as usize].chart;
            if prev != Some(c) {
                if let Some(p) = prev {
                    finished.insert(p);
                }
                assert!(!finished.contains(&c), "chart {c} visited twice");
                prev = Some(c);
            }
        }
    }

    fn all_traversals_valid(texels: &[Texel], res: u32) {
        for t in Traversal::ALL {
            let order = traverse(texels, res, t);
            assert_permutation(texels, &order);
            if t != Traversal::Greedy {
                assert_charts_contiguous(texels, &order);
            }
        }
    }

    #[test]
    fn empty_input() {
        for t in Traversal::ALL {
            assert!(traverse(&[], 16, t).is_empty());
        }
    }

    #[test]
    fn single_texel() {
        let texels = [texel(3, 5, 0, [1.0, 2.0, 3.0])];
        for t in Traversal::ALL {
            assert_eq!(traverse(&texels, 8, t), vec![0]);
        }
    }

    #[test]
    fn zigzag_rectangle_is_serpentine() {
        let texels = atlas(&["", " 00000", " 00000", " 00000", " 00000"]);
        let order = traverse(&texels, 8, Traversal::Zigzag);
        let mut expected = Vec::new();
        for y in 1..5u16 {
            let xs: Vec<u16> = if y % 2 == 1 {
                (1..6).collect()
            } else {
                (1..6).rev().collect()
            };
            expected.extend(xs.into_iter().map(|x| (x, y)));
        }
        assert_eq!(cells(&texels, &order), expected);
    }

    #[test]
    fn spiral_rectangle_is_outside_in() {
        let texels = atlas(&["0000", "0000", "0000"]);
        let order = traverse(&texels, 4, Traversal::Spiral);
        let expected = [
            (0, 0),
            (1, 0),
            (2, 0),
            (3, 0),
            (3, 1),
            (3, 2),
            (2, 2),
            (1, 2),
            (0, 2),
            (0, 1),
            (1, 1),
            (2, 1),
        ];
        assert_eq!(cells(&texels, &order), expected);
    }

    #[test]
    fn spiral_l_shape_follows_the_border() {
        let texels = atlas(&["00", "00", "00000", "00000"]);
        let order = traverse(&texels, 8, Traversal::Spiral);
        let expected = [
            (0, 0),
            (1, 0),
            (1, 1),
            (1, 2),
            (2, 2),
            (3, 2),
            (4, 2),
            (4, 3),
            (3, 3),
            (2, 3),
            (1, 3),
            (0, 3),
            (0, 2),
            (0, 1),
        ];
        assert_eq!(cells(&texels, &order), expected);
        all_traversals_valid(&texels, 8);
    }

    #[test]
    fn zigzag_l_shape() {
        let texels = atlas(&["00", "00", "00000", "00000"]);
        let order = traverse(&texels, 8, Traversal::Zigzag);
        let expected = [
            (0, 0),
            (1, 0),
            (1, 1),
            (0, 1),
            (0, 2),
            (1, 2),
            (2, 2),
            (3, 2),
            (4, 2),
            (4, 3),
            (3, 3),
            (2, 3),
            (1, 3),
            (0, 3),
        ];
        assert_eq!(cells(&texels, &order), expected);
    }

    #[test]
    fn spiral_around_a_hole() {
        let texels = atlas(&["00000", "00000", "00.00", "00000", "00000"]);
        let order = traverse(&texels, 5, Traversal::Spiral);
        let expected = [
            // Outer ring.
            (0, 0),
            (1, 0),
            (2, 0),
            (3, 0),
            (4, 0),
            (4, 1),
            (4, 2),
            (4, 3),
            (4, 4),
            (3, 4),
            (2, 4),
            (1, 4),
            (0, 4),
            (0, 3),
            (0, 2),
            (0, 1),
            // Inner ring around the hole.
            (1, 1),
            (2, 1),
            (3, 1),
            (3, 2),
            (3, 3),
            (2, 3),
            (1, 3),
            (1, 2),
        ];
        assert_eq!(cells(&texels, &order), expected);
        // Zig-Zag skips the hole.
        let zz = traverse(&texels, 5, Traversal::Zigzag);
        assert_eq!(
            cells(&texels, &zz[10..14]),
            [(0, 2), (1, 2), (3, 2), (4, 2)]
        );
        all_traversals_valid(&texels, 5);
    }

    #[test]
    fn spiral_steps_back_from_dead_ends() {
        // A comb: the teeth are dead ends; stepped-back cells are not emitted again.
        let texels = atlas(&["00000", "0.0.0"]);
        let order = traverse(&texels, 5, Traversal::Spiral);
        let expected = [
            (0, 0),
            (1, 0),
            (2, 0),
            (3, 0),
            (4, 0),
            (4, 1),
            (2, 1),
            (0, 1),
        ];
        assert_eq!(cells(&texels, &order), expected);
    }

    #[test]
    fn disconnected_chart_restarts_at_first_unvisited_cell() {
        let texels = atlas(&["00.0", "...0", "0..."]);
        let spiral = traverse(&texels, 4, Traversal::Spiral);
        assert_eq!(
            cells(&texels, &spiral),
            [(0, 0), (1, 0), (3, 0), (3, 1), (0, 2)]
        );
        let zigzag = traverse(&texels, 4, Traversal::Zigzag);
        assert_eq!(
            cells(&texels, &zigzag),
            [(0, 0), (1, 0), (3, 0), (3, 1), (0, 2)]
        );
    }

    #[test]
    fn two_far_charts_are_each_contiguous() {
        // Interleaved in atlas row order, far apart in 3D (z = 0 and z = 10).
        let texels = atlas(&["000.111", "000.111", "000.111"]);
        for t in [Traversal::Zigzag, Traversal::Spiral, Traversal::Greedy] {
            let order = traverse(&texels, 8, t);
            assert_permutation(&texels, &order);
            assert_charts_contiguous(&texels, &order);
            assert_eq!(texels[order[0] as usize].chart, 0);
        }
    }

    #[test]
    fn next_chart_is_the_closest_in_3d() {
        // Atlas order 0, 1, 2; in 3D chart 0 is at z = 0, chart 1 at z = 100, chart 2 at z = 1.
        let mut texels = atlas(&["0.1.2", "0.1.2"]);
        for t in &mut texels {
            t.position[2] = [0.0, 100.0, 1.0][t.chart as usize];
        }
        for t in [Traversal::Zigzag, Traversal::Spiral] {
            let order = traverse(&texels, 8, t);
            let charts: Vec<u32> = order.iter().map(|&i| texels[i as usize].chart).collect();
            assert_eq!(charts, [0, 0, 2, 2, 1, 1], "{t}");
        }
    }

    #[test]
    fn chart_ties_go_to_the_smaller_chart_id() {
        // Charts 1 and 2 are equally far from chart 0's last texel.
        let texels = vec![
            texel(0, 0, 0, [0.0, 0.0, 0.0]),
            texel(2, 0, 2, [0.0, 0.0, 5.0]),
            texel(4, 0, 1, [0.0, 0.0, -5.0]),
        ];
        for t in [Traversal::Zigzag, Traversal::Spiral] {
            assert_eq!(traverse(&texels, 8, t), vec![0, 2, 1], "{t}");
        }
    }

    #[test]
    fn first_chart_is_the_row_major_first_texels_chart_regardless_of_slice_order() {
        let mut texels = atlas(&["..11", "0011"]);
        texels.reverse();
        for t in Traversal::ALL {
            let order = traverse(&texels, 4, t);
            let first = &texels[order[0] as usize];
            assert_eq!((first.x, first.y), (2, 0), "{t}");
        }
    }

    #[test]
    fn greedy_walks_nearest_first() {
        // On a line: start at the row-major first texel (x = 5), then nearest-first.
        let xs = [5.0, 0.0, 6.0, 2.0, 9.0, 5.5];
        let texels: Vec<Texel> = xs
            .iter()
            .enumerate()
            .map(|(i, &x)| texel(i as u16, 0, 0, [x, 0.0, 0.0]))
            .collect();
        let order = traverse(&texels, 8, Traversal::Greedy);
        // 5 -> 5.5 -> 6 -> 9 (3 away, 2 is 4 away) -> 2 -> 0.
        assert_eq!(order, vec![0, 5, 2, 4, 3, 1]);
    }

    #[test]
    fn greedy_ties_go_to_the_smaller_index() {
        let texels = vec![
            texel(0, 0, 0, [0.0, 0.0, 0.0]),
            texel(1, 0, 0, [1.0, 0.0, 0.0]),
            texel(2, 0, 0, [-1.0, 0.0, 0.0]),
            texel(3, 0, 0, [0.0, 1.0, 0.0]),
        ];
        assert_eq!(traverse(&texels, 4, Traversal::Greedy), vec![0, 1, 3, 2]);
    }

    #[test]
    fn non_finite_positions_still_give_a_permutation() {
        let mut texels = atlas(&["0011", "0011"]);
        texels[1].position = [f32::NAN, 0.0, f32::INFINITY];
        all_traversals_valid(&texels, 4);
    }

    #[test]
    fn coordinates_beyond_the_resolution_and_sparse_lookup() {
        let texels = atlas(&["0000", "0000", "0000"]);
        // Resolution smaller than the coordinates: the grid grows.
        assert_eq!(
            traverse(&texels, 1, Traversal::Spiral),
            traverse(&texels, 4, Traversal::Spiral)
        );
        // Dense and sparse lookups agree.
        let dense = CellIndex::new(&texels, 4, usize::MAX);
        assert!(matches!(dense, CellIndex::Dense { .. }));
        // At least four cells per texel stay dense whatever the limit.
        assert!(matches!(
            CellIndex::new(&texels, 4, 0),
            CellIndex::Dense { .. }
        ));
        let sparse = CellIndex::new(&texels, 1000, 0);
        assert!(matches!(sparse, CellIndex::Sparse(_)));
        for y in -1..5 {
            for x in -1..6 {
                assert_eq!(dense.get(x, y), sparse.get(x, y), "({x}, {y})");
            }
        }
        // Far-out coordinates use the sparse lookup and still work.
        let far: Vec<Texel> = texels
            .iter()
            .map(|t| texel(t.x + 60000, t.y + 60000, t.chart, t.position))
            .collect();
        assert_eq!(
            cells(&far, &traverse(&far, 1024, Traversal::Spiral))
                .iter()
                .map(|&(x, y)| (x - 60000, y - 60000))
                .collect::<Vec<_>>(),
            cells(&texels, &traverse(&texels, 4, Traversal::Spiral))
        );
    }

    #[test]
    fn nearest_set_matches_brute_force() {
        // Deterministic pseudo-random points with many exact ties (coarse coordinates).
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) % 7) as f32
        };
        let points: Vec<[f32; 3]> = (0..300).map(|_| [next(), next(), next()]).collect();
        let mut set = NearestSet::new(&points);
        let mut alive = vec![true; points.len()];
        let mut q = [3.0, 3.0, 3.0];
        for step in 0..points.len() {
            let expected = (0..points.len() as u32)
                .filter(|&i| alive[i as usize])
                .min_by(|&a, &b| {
                    dist2(points[a as usize], q)
                        .total_cmp(&dist2(points[b as usize], q))
                        .then(a.cmp(&b))
                });
            let got = set.nearest(q);
            assert_eq!(got, expected, "step {step}");
            let id = got.unwrap();
            alive[id as usize] = false;
            set.remove(id);
            set.remove(id); // idempotent
            q = [next() + 0.5, next(), next() - 0.25];
        }
        assert_eq!(set.nearest(q), None);
    }
}
