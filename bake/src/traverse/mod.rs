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

mod chart_order;
mod greedy;
mod hilbert;
mod piloted;
mod spiral;
mod zigzag;

use cssm_formats::{Texel, Traversal};

pub use hilbert::gilbert_ranks;

use chart_order::{chart_by_chart, chart_by_chart_ends};
use greedy::greedy_order;
use hilbert::hilbert_chart;
use piloted::piloted_order;
use spiral::{CellIndex, DENSE_CELL_LIMIT, SpiralWalker};
use zigzag::zigzag_chart;

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
        Traversal::Piloted => piloted_order(texels, atlas_resolution, pilot, &by_chart),
        Traversal::Spiral => {
            let cells = CellIndex::new(texels, atlas_resolution, DENSE_CELL_LIMIT);
            let mut walker = SpiralWalker::new(texels, &cells);
            by_chart(&mut |_, rows, out| walker.spiral_chart(rows, out))
        }
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    /// A texel at atlas cell `(x, y)` of `chart` with 3D position `position`.
    pub(super) fn texel(x: u16, y: u16, chart: u32, position: [f32; 3]) -> Texel {
        Texel {
            position,
            normal: [0.0, 0.0, 1.0],
            area: 1.0,
            material: 0,
            chart,
            object: 0,
            x,
            y,
        }
    }

    /// Texels from an ASCII atlas: a digit is a texel of that chart, anything else undefined.
    /// Position: `(x, y, 10 * chart)`. Texels in row-major order.
    pub(super) fn atlas(rows: &[&str]) -> Vec<Texel> {
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
    pub(super) fn cells(texels: &[Texel], order: &[u32]) -> Vec<(u16, u16)> {
        order
            .iter()
            .map(|&i| (texels[i as usize].x, texels[i as usize].y))
            .collect()
    }

    /// Asserts that `order` is a permutation of `0..texels.len()`.
    pub(super) fn assert_permutation(texels: &[Texel], order: &[u32]) {
        let mut seen = vec![false; texels.len()];
        assert_eq!(order.len(), texels.len());
        for &i in order {
            assert!(!std::mem::replace(&mut seen[i as usize], true), "{i} twice");
        }
    }

    /// Asserts that every chart forms one contiguous block of `order`.
    pub(super) fn assert_charts_contiguous(texels: &[Texel], order: &[u32]) {
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

    pub(super) fn all_traversals_valid(texels: &[Texel], res: u32) {
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
    fn non_finite_positions_still_give_a_permutation() {
        let mut texels = atlas(&["0011", "0011"]);
        texels[1].position = [f32::NAN, 0.0, f32::INFINITY];
        all_traversals_valid(&texels, 4);
    }
}
