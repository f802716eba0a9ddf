//! Building the hierarchy of §4.2 by median cut: the top-down half of [`Hierarchy::build`],
//! which orders the texels into leaves and fixes every node's leaf range and skip pointer; the
//! bottom-up fit of the bounds is in `bounds.rs`.

use super::bounds::fit_bounds;
use super::{Hierarchy, HierarchyNode};
use crate::texel::Texel;

impl Hierarchy {
    /// Builds the hierarchy over `texels` by median cut (§4.2): starting from all texels, a set
    /// is split along the longest axis of the bounding box of its positions (ties to the lower
    /// axis, x < y < z), its lower `count / 2` texels by (coordinate, texel index) going left,
    /// until every leaf holds one texel. Deterministic (no threads, every tie broken by the texel
    /// index) and O(n log n) (the ignored test `build_time_200k` times it). No recursion: a stack of at most the tree's depth (~log2 n) pending
    /// subtrees.
    ///
    /// Bounds are merged bottom-up: an inner node's sphere is the smallest one enclosing its
    /// children's spheres (with the radius rounded up so that it contains them in `f32`), its
    /// normal cone the cone around its mean normal containing both children's cones (rounded
    /// wider). An empty slice gives an empty hierarchy.
    ///
    /// # Panics
    ///
    /// If there are more than 2^31 texels (the node indices would not fit `u32`).
    pub fn build(texels: &[Texel]) -> Hierarchy {
        let n = texels.len();
        if n == 0 {
            return Hierarchy::default();
        }
        assert!(n <= 1 << 31, "{n} texels: too many for a u32 hierarchy");
        let m = 2 * n - 1;
        let mut nodes = vec![HierarchyNode::default(); m];
        // (position, texel index), permuted in place into leaf order: the median cut works on
        // contiguous memory instead of gathering positions from the texel table.
        let mut order: Vec<([f32; 3], u32)> = texels
            .iter()
            .enumerate()
            .map(|(i, t)| (t.position, i as u32))
            .collect();

        // Top-down: the median cut fixes every node's leaf range and pointers.
        let mut stack = vec![(0usize, 0usize, n)];
        while let Some((i, first, count)) = stack.pop() {
            let node = &mut nodes[i];
            node.first = first as u32;
            node.count = count as u32;
            node.skip = (i + 2 * count - 1) as u32;
            if count == 1 {
                continue;
            }
            let set = &mut order[first..first + count];
            let axis = longest_axis(set);
            let left = count / 2;
            set.select_nth_unstable_by(left, |a, b| {
                a.0[axis].total_cmp(&b.0[axis]).then(a.1.cmp(&b.1))
            });
            // Pushed right first so that the left subtree is done first (bounded stack).
            stack.push((i + 2 * left, first + left, count - left));
            stack.push((i + 1, first, left));
        }

        fit_bounds(&mut nodes, &order, texels);
        Hierarchy {
            nodes,
            leaf_texels: order.into_iter().map(|(_, t)| t).collect(),
        }
    }
}

/// Axis (0, 1, 2) along which the positions of `set` (position, texel) spread most; ties to the
/// lower axis.
fn longest_axis(set: &[([f32; 3], u32)]) -> usize {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for &(p, _) in set {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let extent = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let mut axis = 0;
    for k in 1..3 {
        if extent[k] > extent[axis] {
            axis = k;
        }
    }
    axis
}
