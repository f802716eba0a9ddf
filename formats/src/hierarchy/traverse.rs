//! Queries over a built hierarchy: whether a node is a leaf, its children, its leaves, and the
//! stack-less traversal of §4.3 (Fig. 10) that yields the cut of senders for one receiver.

use super::{Hierarchy, HierarchyNode};

impl Hierarchy {
    /// Whether node `i` is a leaf (one texel). `i` must be a node index.
    pub fn is_leaf(&self, i: usize) -> bool {
        self.nodes[i].count == 1
    }

    /// The left and right child of node `i`: `(i + 1, nodes[i + 1].skip)`; `None` for a leaf or
    /// an index past the nodes.
    pub fn children(&self, i: usize) -> Option<(usize, usize)> {
        let node = self.nodes.get(i)?;
        if node.count <= 1 {
            return None;
        }
        Some((i + 1, self.nodes.get(i + 1)?.skip as usize))
    }

    /// Texel indices of the leaves of node `i`. `i` must be a node index.
    pub fn leaves(&self, i: usize) -> &[u32] {
        let node = &self.nodes[i];
        &self.leaf_texels[node.first as usize..(node.first + node.count) as usize]
    }

    /// The stack-less traversal of §4.3 (Fig. 10), as the GPU runs it for one receiver: starting
    /// at the root, an inner node for which `refine(index, node)` says true is refined (go to its
    /// left child, `index + 1`); any other node, and every leaf (`refine` is not asked), is a
    /// sender of the cut (*gather*) and the traversal continues at its `skip`. Returns the
    /// senders in traversal order; their leaf ranges partition the leaves in order.
    ///
    /// ```
    /// use cssm_formats::{Texel, hierarchy::Hierarchy};
    ///
    /// let texels: Vec<Texel> = (0..8u16)
    ///     .map(|x| Texel {
    ///         position: [f32::from(x), 0.0, 0.0],
    ///         normal: [0.0, 0.0, 1.0],
    ///         area: 1.0,
    ///         material: 0,
    ///         chart: 0,
    ///         object: 0,
    ///         x,
    ///         y: 0,
    ///     })
    ///     .collect();
    /// let h = Hierarchy::build(&texels);
    /// let receiver = glam::Vec3::new(0.0, 0.0, 1.0);
    /// // Refine nodes that look large from the receiver (a distance / radius oracle).
    /// let cut = h.cut(|_, node| {
    ///     let d = glam::Vec3::from(node.center).distance(receiver);
    ///     node.radius > 0.5 * d
    /// });
    /// // Near the receiver single texels, far away whole subtrees; every texel exactly once.
    /// let covered: u32 = cut.iter().map(|&i| h.nodes[i].count).sum();
    /// assert_eq!(covered, 8);
    /// assert!(cut.len() < 8);
    /// ```
    pub fn cut(&self, mut refine: impl FnMut(usize, &HierarchyNode) -> bool) -> Vec<usize> {
        let mut out = Vec::new();
        let mut i = 0;
        while let Some(node) = self.nodes.get(i) {
            if node.count > 1 && refine(i, node) {
                i += 1; // Refine: the left child.
            } else {
                out.push(i); // Gather, then skip the subtree.
                i = node.skip as usize;
            }
        }
        out
    }
}
