//! [`Traversal::Piloted`](cssm_formats::Traversal::Piloted) (beyond the paper): chart by chart,
//! the chart's Hilbert order or its Spiral walk, whichever the pilot chooses.

use cssm_formats::Texel;

use super::hilbert::hilbert_chart;
use super::spiral::{CellIndex, DENSE_CELL_LIMIT, SpiralWalker};
use super::{Pilot, VisitChart};

/// The order of [`Traversal::Piloted`](cssm_formats::Traversal::Piloted): `by_chart` strings the
/// charts together; inside each, `pilot` chooses between the chart's Hilbert order (candidate 0)
/// and its Spiral walk (candidate 1), and is not asked when the two are the same.
pub(super) fn piloted_order(
    texels: &[Texel],
    atlas_resolution: u32,
    pilot: &Pilot,
    by_chart: &dyn Fn(&mut VisitChart) -> Vec<u32>,
) -> Vec<u32> {
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
