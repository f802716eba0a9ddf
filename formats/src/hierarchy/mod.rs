//! The texel hierarchy of §4.2: a binary tree over the atlas texels built by *median cut* over
//! their 3D positions, with a bounding sphere, an area-weighted mean normal, a normal cone and
//! the summed area per node, for the upper bounds of the refinement oracle (§4.3).
//!
//! The tree is stored as a linear array in depth-first (pre-)order for stack-less traversal
//! (§4.2.1): the child pointer of an inner node is implicit (its left child is the next node),
//! the skip pointer is stored. A subtree's nodes are contiguous, and so are its leaves in
//! [`Hierarchy::leaf_texels`]. A node of `count` leaves spans `2 * count - 1` nodes, so the
//! whole layout follows from the counts: node `i`'s skip is `i + 2 * count - 1` and the right
//! child of an inner node with `l` leaves on its left is `i + 2 * l`.
//!
//! Unlike the paper's 128-bit quantised node (§4.2.1), a node here is 64 bytes of full-precision
//! floats and integers ([`HierarchyNode`], laid out for a WGSL `array<struct>`).
//!
//! The module is split by what each part does: this file holds the data ([`HierarchyNode`],
//! [`Hierarchy`]); `build.rs` the median cut that orders the texels into the tree; `bounds.rs`
//! the bottom-up fit of every node's sphere, mean normal, cone, area and representative (shared
//! by the build and [`Hierarchy::refit`]); `validate.rs` the check of a loaded tree;
//! `traverse.rs` the queries over it (children, leaves, the stack-less cut of §4.3).

use serde::{Deserialize, Serialize};

mod bounds;
mod build;
#[cfg(test)]
mod tests;
mod traverse;
mod validate;

/// One node of the median-cut texel hierarchy, in depth-first (pre-)order (§4.2.1).
/// The left child of an inner node is the next node (`index + 1`); its right child is the left
/// child's `skip`.
///
/// 16 four-byte words (64 bytes, 16-byte aligned in a WGSL `array<struct>`): the 13 fields, then
/// [`_pad`](Self::_pad).
#[repr(C)]
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Serialize,
    Deserialize,
    bytemuck::Pod,
    bytemuck::Zeroable,
)]
pub struct HierarchyNode {
    /// Centre of the bounding sphere.
    pub center: [f32; 3],
    /// Radius of the bounding sphere: it contains every leaf texel's disk (centre = texel
    /// position, radius `sqrt(area / pi)`), so a leaf's sphere is its own disk's.
    pub radius: f32,
    /// Area-weighted mean of the unit texel normals (sum of area * normal / sum of area); its
    /// length is <= 1 (up to rounding) and shrinks where normals disagree. For a leaf: the
    /// texel's normal. (A subtree whose texels all have zero area takes the plain mean.)
    pub normal: [f32; 3],
    /// Cosine of the half-angle of the normal cone around `normalize(normal)` that contains every
    /// leaf normal; -1.0 when no cone narrower than a full sphere is known (e.g. mean normal
    /// ~ zero). Leaf: 1.0.
    pub cone_cos: f32,
    /// Sum of the texel areas of the subtree.
    pub area: f32,
    /// Node to continue with when this subtree is skipped (depth-first successor):
    /// `index + 2 * count - 1`; the node count for the subtrees on the right spine.
    pub skip: u32,
    /// First position of the subtree's leaves in [`Hierarchy::leaf_texels`] (the leaves of a
    /// subtree are contiguous there).
    pub first: u32,
    /// Number of leaves (texels) in the subtree; 1 for a leaf.
    pub count: u32,
    /// Texel index standing for the whole node (where a visibility query and distances are
    /// taken from when the node is a sender): the leaf texel nearest to `center`, ties to the
    /// lower texel index.
    pub representative: u32,
    /// Padding to 64 bytes (always zero), so that the node is 16-byte aligned as a WGSL struct.
    pub _pad: [u32; 3],
}

/// Size of a [`HierarchyNode`] in bytes (and of its WGSL twin).
pub const NODE_BYTES: usize = 64;
const _: () = assert!(std::mem::size_of::<HierarchyNode>() == NODE_BYTES);

/// The hierarchy over a file's texels (§4.2).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Hierarchy {
    /// `2 * texel_count - 1` nodes, root first, depth-first order.
    pub nodes: Vec<HierarchyNode>,
    /// Texel index of every leaf, in depth-first leaf order (a permutation of
    /// `0..texel_count`).
    pub leaf_texels: Vec<u32>,
}
