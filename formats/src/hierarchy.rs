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

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::texel::Texel;

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

/// Per-node sums over the leaves, in f64, while building.
#[derive(Clone, Copy, Default)]
struct Sums {
    /// Sum of the areas.
    area: f64,
    /// Sum of area * normal.
    area_normal: DVec3,
    /// Sum of the normals (the mean of a subtree whose areas are all zero).
    normal: DVec3,
    /// Half-angle of the normal cone around the node's stored normal; infinite: none.
    half_angle: f64,
}

/// Mean normals shorter than this have no usable direction: their cone is the full sphere.
const MIN_AXIS_LEN: f64 = 1e-6;

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

    /// Recomputes every node's bounds (sphere, mean normal, normal cone, area, representative)
    /// for `texels` placed anew since the build, keeping the tree (leaf order, counts, skips):
    /// what rigid objects need when they move (§3.3), so that the oracle's bounds (§4.3) stay
    /// conservative around the texels where they are now. `texels` are the build's, each moved
    /// (same count, same order); refitting the build's own texels gives the build's nodes
    /// exactly. The median cut is not redone: a moved object's texels keep their subtrees,
    /// whose spheres grow where the objects drift apart (looser bounds refine more, never less).
    ///
    /// # Panics
    ///
    /// If `texels` is not as long as the hierarchy's leaf table.
    pub fn refit(&mut self, texels: &[Texel]) {
        assert_eq!(
            texels.len(),
            self.leaf_texels.len(),
            "refit with another texel count"
        );
        let order: Vec<([f32; 3], u32)> = self
            .leaf_texels
            .iter()
            .map(|&t| (texels[t as usize].position, t))
            .collect();
        fit_bounds(&mut self.nodes, &order, texels);
    }

    /// Checks the hierarchy for a file of `texel_count` texels: `2 * texel_count - 1` nodes,
    /// `leaf_texels` a permutation of `0..texel_count`, and the tree well-formed: the root
    /// covers every leaf and ends at the node count, every inner node `i` has its left child at
    /// `i + 1` starting at its first leaf and its right child at the left child's skip holding
    /// the rest of its leaves and skipping to where it does, every leaf has count 1 and skips to
    /// `i + 1`; all floats finite, radius and area >= 0, `cone_cos` in [-1, 1], and each
    /// representative one of its node's leaves. The error names the node.
    ///
    /// Iterative and O(n); it allocates only one `u32` per texel.
    pub fn validate(&self, texel_count: usize) -> Result<(), String> {
        let n = texel_count as u64;
        let m = self.nodes.len() as u64;
        let expected = (2 * n).saturating_sub(1);
        if m != expected {
            return Err(format!(
                "{m} nodes, expected 2 * {n} texels - 1 = {expected}"
            ));
        }
        if self.leaf_texels.len() as u64 != n {
            return Err(format!(
                "{} leaf_texels for {n} texels",
                self.leaf_texels.len()
            ));
        }
        // Position of every texel in the leaf order, u32::MAX where not (yet) seen.
        let mut position = vec![u32::MAX; texel_count];
        for (k, &t) in self.leaf_texels.iter().enumerate() {
            match position.get_mut(t as usize) {
                None => return Err(format!("leaf_texels[{k}] = {t} is not a texel index")),
                Some(p) if *p != u32::MAX => {
                    return Err(format!(
                        "leaf_texels[{k}] = {t} repeats a texel: not a permutation"
                    ));
                }
                Some(p) => *p = k as u32,
            }
        }
        if let Some(root) = self.nodes.first() {
            if root.first != 0 || u64::from(root.count) != n || u64::from(root.skip) != m {
                return Err(format!(
                    "root node: first {}, count {}, skip {}; expected 0, {n}, {m}",
                    root.first, root.count, root.skip
                ));
            }
        }
        // First each node on its own (so that the error names the node that is wrong)...
        for (i, node) in self.nodes.iter().enumerate() {
            let err = |what: String| Err(format!("node {i}: {what}"));
            let floats = node.center.iter().chain(&node.normal).chain([
                &node.radius,
                &node.cone_cos,
                &node.area,
            ]);
            if floats.clone().any(|v| !v.is_finite()) {
                return err("a non-finite value".into());
            }
            // The padding is zero in every file a bake writes: anything else is corruption.
            if node._pad != [0; 3] {
                return err(format!("padding {:?} is not zero", node._pad));
            }
            if node.radius < 0.0 {
                return err(format!("negative radius {}", node.radius));
            }
            if node.area < 0.0 {
                return err(format!("negative area {}", node.area));
            }
            if !(-1.0..=1.0).contains(&node.cone_cos) {
                return err(format!("cone_cos {} outside [-1, 1]", node.cone_cos));
            }
            let (first, count) = (u64::from(node.first), u64::from(node.count));
            if count == 0 || first + count > n {
                return err(format!("leaves {first}..{} outside 0..{n}", first + count));
            }
            let skip = i as u64 + 2 * count - 1;
            if skip > m {
                return err(format!(
                    "{count} leaves need nodes up to {skip}, past the {m} nodes"
                ));
            }
            if u64::from(node.skip) != skip {
                return err(format!(
                    "skip {}, expected {skip} for {count} leaves",
                    node.skip
                ));
            }
            match position.get(node.representative as usize) {
                Some(&p) if (first..first + count).contains(&u64::from(p)) => {}
                _ => {
                    return err(format!(
                        "representative {} is not one of its leaves",
                        node.representative
                    ));
                }
            }
        }
        // ... then against its children. With the root's range fixed, these local checks make
        // the nodes a tree whose every subtree spans `2 * count - 1` nodes from its index and
        // whose children split its leaf range: every node is reached exactly once from the
        // root, and the leaves of every cut partition the leaf order.
        for (i, node) in self.nodes.iter().enumerate() {
            let err = |what: String| Err(format!("node {i}: {what}"));
            let (first, count) = (u64::from(node.first), u64::from(node.count));
            if count == 1 {
                continue;
            }
            // skip <= m and count >= 2, so both children exist.
            let Some(left) = self.nodes.get(i + 1) else {
                return err("no left child".into());
            };
            if left.first != node.first || left.count >= node.count {
                return err(format!(
                    "left child {} has leaves {}+{}, not a first part of {first}+{count}",
                    i + 1,
                    left.first,
                    left.count
                ));
            }
            let r = left.skip as usize;
            let Some(right) = self.nodes.get(r).filter(|_| r > i + 1) else {
                return err(format!("right child {r} (left child's skip) out of range"));
            };
            if u64::from(right.first) != first + u64::from(left.count)
                || right.count != node.count - left.count
                || right.skip != node.skip
            {
                return err(format!(
                    "right child {r} has leaves {}+{} and skip {}, expected {}+{} and skip {}",
                    right.first,
                    right.count,
                    right.skip,
                    first + u64::from(left.count),
                    node.count - left.count,
                    node.skip
                ));
            }
        }
        Ok(())
    }

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

/// The bottom-up half of [`Hierarchy::build`] (children come after their parent in pre-order):
/// bounds, sums and cones of every node of `nodes`, whose leaf ranges and skips are set, over
/// `order`, the leaves' (position, texel index) in leaf order.
fn fit_bounds(nodes: &mut [HierarchyNode], order: &[([f32; 3], u32)], texels: &[Texel]) {
    let m = nodes.len();
    let mut sums = vec![Sums::default(); m];
    for i in (0..m).rev() {
        let (first, count) = (nodes[i].first as usize, nodes[i].count as usize);
        if count == 1 {
            let t = &texels[order[first].1 as usize];
            let nrm = dvec(t.normal);
            sums[i] = Sums {
                area: f64::from(t.area),
                area_normal: f64::from(t.area) * nrm,
                normal: nrm,
                // A normal without a direction has no cone to merge.
                half_angle: if nrm.length() > MIN_AXIS_LEN {
                    0.0
                } else {
                    f64::INFINITY
                },
            };
            let node = &mut nodes[i];
            node.center = t.position;
            node.radius = (t.area / std::f32::consts::PI).sqrt();
            node.normal = t.normal;
            node.cone_cos = 1.0;
            node.area = t.area;
            node.representative = order[first].1;
            continue;
        }
        let (l, r) = (i + 1, nodes[i + 1].skip as usize);
        let (a, b) = (nodes[l], nodes[r]);
        let (sa, sb) = (sums[l], sums[r]);
        let area = sa.area + sb.area;
        let area_normal = sa.area_normal + sb.area_normal;
        let normal_sum = sa.normal + sb.normal;
        let mean = if area > 0.0 {
            area_normal / area
        } else {
            normal_sum / count as f64
        };
        let normal = mean.as_vec3().to_array();
        // The cone around the normal as stored, so that it holds for what the GPU reads.
        let half_angle = merge_cones(dvec(normal), [(&a, sa), (&b, sb)]);
        sums[i] = Sums {
            area,
            area_normal,
            normal: normal_sum,
            half_angle,
        };
        let center = enclosing_center(&a, &b).as_vec3().to_array();
        // The radius around the f32 centre, rounded up: the children's spheres stay inside.
        let radius = [&a, &b]
            .iter()
            .map(|c| dvec(center).distance(dvec(c.center)) + f64::from(c.radius))
            .fold(0.0, f64::max);
        let leaves = &order[first..first + count];
        let node = &mut nodes[i];
        node.center = center;
        node.radius = f32_up(radius);
        node.normal = normal;
        node.cone_cos = if half_angle < std::f64::consts::PI {
            f32_down(half_angle.cos()).clamp(-1.0, 1.0)
        } else {
            -1.0
        };
        node.area = area as f32;
        node.representative = nearest(leaves, dvec(center));
    }
}

fn dvec(v: [f32; 3]) -> DVec3 {
    DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
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

/// Centre of the smallest sphere enclosing the spheres of `a` and `b`.
fn enclosing_center(a: &HierarchyNode, b: &HierarchyNode) -> DVec3 {
    let (ca, cb) = (dvec(a.center), dvec(b.center));
    let (ra, rb) = (f64::from(a.radius), f64::from(b.radius));
    let d = ca.distance(cb);
    if d + rb <= ra {
        return ca;
    }
    if d + ra <= rb {
        return cb;
    }
    // d > |ra - rb| >= 0 here: the sphere touches both far sides.
    let r = 0.5 * (d + ra + rb);
    ca + (cb - ca) * ((r - ra) / d)
}

/// Half-angle of a cone around `normal` containing the cones of both children (their stored
/// normals, half-angles in their [`Sums`]); infinite where there is none narrower than the
/// sphere (a child without one, or a mean normal without a direction).
fn merge_cones(normal: DVec3, children: [(&HierarchyNode, Sums); 2]) -> f64 {
    let len = normal.length();
    if len.is_nan() || len <= MIN_AXIS_LEN {
        return f64::INFINITY;
    }
    let axis = normal / len;
    let mut half = 0.0f64;
    for (child, sums) in children {
        let c = dvec(child.normal);
        let c_len = c.length();
        if !(sums.half_angle.is_finite() && c_len > MIN_AXIS_LEN) {
            return f64::INFINITY;
        }
        let between = (axis.dot(c) / c_len).clamp(-1.0, 1.0).acos();
        half = half.max(between + sums.half_angle);
    }
    if half >= std::f64::consts::PI {
        return f64::INFINITY;
    }
    half
}

/// Texel of `leaves` (position, texel) nearest to `center`; ties to the lower texel index.
fn nearest(leaves: &[([f32; 3], u32)], center: DVec3) -> u32 {
    let mut best = (f64::INFINITY, u32::MAX);
    for &(p, t) in leaves {
        let d = dvec(p).distance_squared(center);
        if (d, t) < best {
            best = (d, t);
        }
    }
    best.1
}

/// `x` as `f32`, rounded up (never below `x`).
fn f32_up(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) >= x || !y.is_finite() {
        return y;
    }
    if y == 0.0 {
        return f32::from_bits(1);
    }
    let bits = y.to_bits();
    f32::from_bits(if y > 0.0 { bits + 1 } else { bits - 1 })
}

/// `x` as `f32`, rounded down (never above `x`).
fn f32_down(x: f64) -> f32 {
    -f32_up(-x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SplitMix64: a tiny deterministic generator.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        /// Uniform in `[0, 1)`.
        fn unit(&mut self) -> f32 {
            (self.next() >> 40) as f32 / (1u64 << 24) as f32
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
    }

    /// `n` random texels: positions in a unit cube (or on a few shared points when
    /// `duplicates`), random unit normals (or a few shared ones), random areas, some zero.
    pub(crate) fn random_texels(n: usize, seed: u64, duplicates: bool) -> Vec<Texel> {
        let mut rng = Rng(seed);
        let points: Vec<[f32; 3]> = (0..4)
            .map(|_| [rng.unit(), rng.unit(), rng.unit()])
            .collect();
        (0..n)
            .map(|i| {
                let position = if duplicates {
                    points[rng.below(points.len())]
                } else {
                    [rng.unit(), rng.unit(), rng.unit()]
                };
                let normal = if rng.below(3) == 0 {
                    [[0.0, 1.0, 0.0], [0.0, 0.0, -1.0]][rng.below(2)]
                } else {
                    let v = glam::Vec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5);
                    v.try_normalize().unwrap_or(glam::Vec3::X).to_array()
                };
                let area = if rng.below(10) == 0 {
                    0.0
                } else {
                    1e-4 * rng.unit()
                };
                Texel {
                    position,
                    normal,
                    area,
                    material: 0,
                    chart: 0,
                    object: 0,
                    x: (i % 1024) as u16,
                    y: (i / 1024) as u16,
                }
            })
            .collect()
    }

    /// Checks every documented property of `h` over `texels`.
    pub(crate) fn check(h: &Hierarchy, texels: &[Texel]) {
        let n = texels.len();
        h.validate(n).unwrap();
        assert_eq!(h.nodes.len(), (2 * n).saturating_sub(1));
        let mut ancestors: Vec<usize> = Vec::new();
        for (i, node) in h.nodes.iter().enumerate() {
            // Ancestors of i: those whose node range [j, skip) contains i.
            while let Some(&j) = ancestors.last() {
                if (h.nodes[j].skip as usize) <= i {
                    ancestors.pop();
                } else {
                    break;
                }
            }
            let leaves = h.leaves(i);
            assert!(leaves.contains(&node.representative), "node {i}");
            let sum: f64 = leaves
                .iter()
                .map(|&t| f64::from(texels[t as usize].area))
                .sum();
            assert!(
                (f64::from(node.area) - sum).abs() <= 1e-5 * sum + 1e-12,
                "node {i}: area {} vs {sum}",
                node.area
            );
            assert!(node.normal_len() <= 1.0 + 1e-5, "node {i}");
            // The representative is the nearest leaf, ties to the lower index.
            let c = dvec(node.center);
            let d = |t: u32| dvec(texels[t as usize].position).distance_squared(c);
            for &t in leaves {
                let (dt, dr) = (d(t), d(node.representative));
                assert!(
                    dr < dt || (dr == dt && node.representative <= t),
                    "node {i}"
                );
            }
            if h.is_leaf(i) {
                let t = &texels[leaves[0] as usize];
                assert_eq!(node.center, t.position);
                assert_eq!(node.radius, (t.area / std::f32::consts::PI).sqrt());
                assert_eq!(node.normal, t.normal);
                assert_eq!(node.cone_cos, 1.0);
                assert_eq!(h.children(i), None);
            } else {
                let (l, r) = h.children(i).unwrap();
                assert_eq!(l, i + 1);
                for child in [l, r] {
                    let ch = &h.nodes[child];
                    let dist = dvec(ch.center).distance(c);
                    assert!(
                        dist + f64::from(ch.radius) <= f64::from(node.radius) * (1.0 + 1e-6) + 1e-9,
                        "node {i} does not contain child {child}"
                    );
                }
            }
            // Every leaf's disk lies in every ancestor's sphere, every leaf normal in its cone.
            if h.is_leaf(i) {
                let t = &texels[leaves[0] as usize];
                let disk = f64::from((t.area / std::f32::consts::PI).sqrt());
                let n = glam::Vec3::from(t.normal).normalize();
                for &j in ancestors.iter().chain([&i]) {
                    let a = &h.nodes[j];
                    let dist = dvec(t.position).distance(dvec(a.center));
                    assert!(
                        dist + disk <= f64::from(a.radius) * (1.0 + 1e-6) + 1e-9,
                        "leaf {i} outside ancestor {j}"
                    );
                    if a.cone_cos > -1.0 {
                        let axis = glam::Vec3::from(a.normal).normalize();
                        assert!(
                            n.dot(axis) >= a.cone_cos - 1e-5,
                            "leaf {i} normal outside the cone of {j}: {} < {}",
                            n.dot(axis),
                            a.cone_cos
                        );
                    }
                }
            }
            ancestors.push(i);
        }
        // The leaves of the root: all texels; the full cut is the leaves, the empty one the root.
        if n > 0 {
            assert_eq!(h.cut(|_, _| false), vec![0]);
            let all = h.cut(|_, _| true);
            assert_eq!(all.len(), n);
            assert!(all.iter().all(|&i| h.is_leaf(i)));
        }
    }

    impl HierarchyNode {
        fn normal_len(&self) -> f32 {
            glam::Vec3::from(self.normal).length()
        }
    }

    #[test]
    fn refit_of_the_build_texels_is_the_build_and_moved_texels_keep_every_property() {
        let texels = random_texels(500, 7, false);
        let built = Hierarchy::build(&texels);
        let mut refitted = built.clone();
        refitted.refit(&texels);
        assert_eq!(refitted, built);
        // Half of the texels carried away and turned (a rigid object moving, §3.3): the same
        // tree, every bound recomputed around the texels where they are now.
        let turn = glam::Quat::from_rotation_z(1.0);
        let moved: Vec<Texel> = texels
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let mut m = *t;
                if i % 2 == 0 {
                    m.position = (turn * t.pos() + glam::Vec3::new(5.0, -3.0, 2.0)).to_array();
                    m.normal = (turn * t.nrm()).to_array();
                }
                m
            })
            .collect();
        refitted.refit(&moved);
        assert_eq!(refitted.leaf_texels, built.leaf_texels);
        for (a, b) in refitted.nodes.iter().zip(&built.nodes) {
            assert_eq!((a.skip, a.first, a.count), (b.skip, b.first, b.count));
        }
        assert_ne!(refitted.nodes[0].center, built.nodes[0].center);
        check(&refitted, &moved);
    }

    /// Leaf ranges of a cut partition `0..n` in order.
    fn assert_partition(h: &Hierarchy, cut: &[usize]) {
        let mut next = 0;
        for &i in cut {
            assert_eq!(h.nodes[i].first, next, "cut node {i}");
            next += h.nodes[i].count;
        }
        assert_eq!(next as usize, h.leaf_texels.len());
    }

    #[test]
    fn random_sets_have_every_property() {
        for (n, duplicates) in [
            (1, false),
            (2, false),
            (3, false),
            (17, false),
            (1000, false),
            (2, true),
            (17, true),
            (1000, true),
        ] {
            for seed in 0..3 {
                let texels = random_texels(n, seed, duplicates);
                let h = Hierarchy::build(&texels);
                check(&h, &texels);
            }
        }
    }

    #[test]
    fn empty_input_gives_an_empty_hierarchy() {
        let h = Hierarchy::build(&[]);
        assert!(h.nodes.is_empty() && h.leaf_texels.is_empty());
        h.validate(0).unwrap();
        assert!(h.cut(|_, _| true).is_empty());
        assert!(h.validate(1).is_err());
    }

    #[test]
    fn one_texel_is_a_leaf_root() {
        let texels = random_texels(1, 5, false);
        let h = Hierarchy::build(&texels);
        assert_eq!(h.nodes.len(), 1);
        assert_eq!(h.leaf_texels, vec![0]);
        let root = h.nodes[0];
        assert_eq!(
            (root.first, root.count, root.skip, root.representative),
            (0, 1, 1, 0)
        );
        assert_eq!(h.cut(|_, _| true), vec![0]);
    }

    #[test]
    fn median_cut_splits_the_longest_axis() {
        // Eight texels on a line along y, given in scrambled order: the root splits at the
        // median y, the left half holding the four lowest.
        let ys = [5.0, 1.0, 7.0, 0.0, 3.0, 6.0, 2.0, 4.0];
        let texels: Vec<Texel> = ys
            .iter()
            .enumerate()
            .map(|(i, &y)| Texel {
                position: [0.1 * i as f32 % 0.3, y, 0.0],
                normal: [0.0, 0.0, 1.0],
                area: 1.0,
                material: 0,
                chart: 0,
                object: 0,
                x: i as u16,
                y: 0,
            })
            .collect();
        let h = Hierarchy::build(&texels);
        check(&h, &texels);
        let y_of = |t: &u32| ys[*t as usize];
        let order: Vec<f32> = h.leaf_texels.iter().map(y_of).collect();
        assert_eq!(order, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        let (l, r) = h.children(0).unwrap();
        assert_eq!((l, r), (1, 8));
        assert_eq!((h.nodes[r].first, h.nodes[r].count), (4, 4));
        // Same normals and areas: the mean normal is the normal, the cone a line.
        assert_eq!(h.nodes[0].normal, [0.0, 0.0, 1.0]);
        assert_eq!(h.nodes[0].cone_cos, 1.0);
        assert_eq!(h.nodes[0].area, 8.0);
    }

    #[test]
    fn opposite_normals_have_no_cone() {
        let mut texels = random_texels(2, 1, false);
        texels[0].normal = [0.0, 0.0, 1.0];
        texels[1].normal = [0.0, 0.0, -1.0];
        texels[1].area = texels[0].area;
        let h = Hierarchy::build(&texels);
        check(&h, &texels);
        assert_eq!(h.nodes[0].cone_cos, -1.0);
        assert!(h.nodes[0].normal_len() < 1e-6);
    }

    #[test]
    fn build_is_deterministic_and_independent_of_input_order_ties() {
        let texels = random_texels(500, 9, true);
        assert_eq!(Hierarchy::build(&texels), Hierarchy::build(&texels));
    }

    #[test]
    fn cuts_partition_the_leaves() {
        let texels = random_texels(1000, 3, false);
        let h = Hierarchy::build(&texels);
        let mut rng = Rng(11);
        for _ in 0..50 {
            let receiver = DVec3::new(
                f64::from(rng.unit()),
                f64::from(rng.unit()),
                f64::from(rng.unit()),
            );
            let ratio = 0.05 + f64::from(rng.unit());
            let mut asked = Vec::new();
            let cut = h.cut(|i, node| {
                asked.push(i);
                f64::from(node.radius) > ratio * dvec(node.center).distance(receiver)
            });
            assert_partition(&h, &cut);
            assert!(
                asked.iter().all(|&i| !h.is_leaf(i)),
                "leaves are never refined"
            );
        }
        // A random oracle too.
        let cut = h.cut(|_, _| rng.below(2) == 0);
        assert_partition(&h, &cut);
    }

    #[test]
    fn validate_refuses_broken_trees() {
        let texels = random_texels(17, 2, false);
        let good = Hierarchy::build(&texels);
        let refused = |h: &Hierarchy, needle: &str| {
            let err = h.validate(17).unwrap_err();
            assert!(err.contains(needle), "expected `{needle}` in: {err}");
        };
        let (l, r) = good.children(0).unwrap();
        let mut h = good.clone();
        h.nodes[l].skip += 1;
        refused(&h, &format!("node {l}: skip"));
        let mut h = good.clone();
        h.nodes[0].skip -= 1;
        refused(&h, "root node");
        let mut h = good.clone();
        h.nodes[r].first += 1;
        refused(&h, &format!("node {r}: leaves"));
        // The rightmost leaf moved onto its left neighbour's leaf: fine on its own, not as the
        // right child of its parent.
        let (last, parent) = (h.nodes.len() - 1, h.nodes.len() - 3);
        let mut h = good.clone();
        h.nodes[last].first -= 1;
        h.nodes[last].representative = h.leaf_texels[h.nodes[last].first as usize];
        refused(&h, &format!("node {parent}: right child {last}"));
        let mut h = good.clone();
        h.leaf_texels[3] = h.leaf_texels[4];
        refused(&h, "not a permutation");
        let mut h = good.clone();
        h.leaf_texels[3] = 17;
        refused(&h, "not a texel index");
        let mut h = good.clone();
        h.nodes.pop();
        refused(&h, "32 nodes, expected");
        let mut h = good.clone();
        h.leaf_texels.pop();
        refused(&h, "16 leaf_texels");
        let mut h = good.clone();
        h.nodes[5].radius = f32::NAN;
        refused(&h, "node 5: a non-finite value");
        let mut h = good.clone();
        h.nodes[5].radius = -1.0;
        refused(&h, "node 5: negative radius");
        let mut h = good.clone();
        h.nodes[6].area = -1.0;
        refused(&h, "node 6: negative area");
        let mut h = good.clone();
        h.nodes[7].cone_cos = 1.5;
        refused(&h, "node 7: cone_cos");
        let mut h = good.clone();
        h.nodes[7].representative = 99;
        refused(&h, "node 7: representative");
        let mut h = good.clone();
        h.nodes[0].representative = h.leaf_texels[0];
        h.nodes[r].representative = h.leaf_texels[0];
        refused(&h, &format!("node {r}: representative"));
        let mut h = good.clone();
        h.nodes[1].count = 0;
        refused(&h, "node 1: leaves");
        let mut h = good.clone();
        h.nodes[l].count = h.nodes[0].count;
        refused(
            &h,
            &format!("node {l}: 17 leaves need nodes up to 34, past the 33"),
        );
        let mut h = good.clone();
        let last = h.nodes.len() - 1;
        h.nodes[last].count = 2;
        h.nodes[last].first -= 1;
        h.nodes[last].skip += 2;
        refused(&h, &format!("node {last}: 2 leaves need nodes up to"));
        assert!(good.validate(16).is_err());
        good.validate(17).unwrap();
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        #[test]
        fn random_texel_sets_have_every_property(
            n in 1usize..300,
            seed in proptest::prelude::any::<u64>(),
            duplicates in proptest::prelude::any::<bool>(),
        ) {
            let texels = random_texels(n, seed, duplicates);
            let h = Hierarchy::build(&texels);
            check(&h, &texels);
            let mut rng = Rng(seed ^ 0x5555);
            assert_partition(&h, &h.cut(|_, _| rng.below(3) != 0));
        }

        /// A hostile hierarchy (random words written over its nodes and leaf order) is
        /// refused or is a tree: validation never panics, and traversing whatever passes
        /// terminates with a partition of the leaves.
        #[test]
        fn validate_never_panics_and_what_passes_is_a_tree(
            n in 1usize..40,
            seed in proptest::prelude::any::<u64>(),
            writes in proptest::collection::vec(
                (proptest::prelude::any::<proptest::sample::Index>(), 0usize..17, 0u32..80),
                1..4,
            ),
        ) {
            let texels = random_texels(n, seed, false);
            let mut h = Hierarchy::build(&texels);
            for (at, field, value) in writes {
                if h.nodes.is_empty() {
                    break;
                }
                let i = at.index(h.nodes.len());
                let node = &mut h.nodes[i];
                match field {
                    0 => node.skip = value,
                    1 => node.first = value,
                    2 => node.count = value,
                    3 => node.representative = value,
                    4 => node.radius = f32::from_bits(value.wrapping_mul(0x0101_0101)),
                    5 => node.cone_cos = value as f32 / 40.0 - 1.0,
                    6 => h.leaf_texels[at.index(n)] = value,
                    7 => {
                        h.nodes.truncate(value as usize);
                    }
                    _ => node.skip = node.skip.wrapping_add(value),
                }
            }
            if h.validate(n).is_ok() {
                let mut rng = Rng(seed);
                let mut steps = 0;
                let cut = h.cut(|_, _| {
                    steps += 1;
                    assert!(steps <= h.nodes.len(), "the traversal does not end");
                    rng.below(2) == 0
                });
                assert_partition(&h, &cut);
            }
        }
    }

    /// Timing on 200,000 random texels (run with `--ignored --nocapture` in release) of the
    /// build, the validation and a refit over the texels moved (what a moving object costs the
    /// runtime per move): wall time, and on Linux the time the thread was on a CPU
    /// (`/proc/thread-self/schedstat`), which a busy machine does not inflate.
    #[test]
    #[ignore]
    fn build_time_200k() {
        let on_cpu_ns = || -> Option<u64> {
            let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
            s.split_whitespace().next()?.parse().ok()
        };
        let texels = random_texels(200_000, 1, false);
        let (t0, c0) = (std::time::Instant::now(), on_cpu_ns());
        let h = Hierarchy::build(&texels);
        let (built, c1) = (t0.elapsed(), on_cpu_ns());
        let t0 = std::time::Instant::now();
        h.validate(texels.len()).unwrap();
        let validated = t0.elapsed();
        // What a moving object costs the runtime per move (§3.3): the refit over moved texels.
        let moved: Vec<Texel> = texels
            .iter()
            .map(|t| Texel {
                position: (t.pos() + glam::Vec3::ONE).to_array(),
                ..*t
            })
            .collect();
        let mut refitted = h.clone();
        let (t0, c2) = (std::time::Instant::now(), on_cpu_ns());
        refitted.refit(&moved);
        let (refit, c3) = (t0.elapsed(), on_cpu_ns());
        let cpu = |a: Option<u64>, b: Option<u64>| match (a, b) {
            (Some(a), Some(b)) => format!(", {:.1} ms on the CPU", (b - a) as f64 / 1e6),
            _ => String::new(),
        };
        println!(
            "build of 200,000 texels: {:.1} ms{}; validate: {:.1} ms; refit: {:.1} ms{}",
            built.as_secs_f64() * 1e3,
            cpu(c0, c1),
            validated.as_secs_f64() * 1e3,
            refit.as_secs_f64() * 1e3,
            cpu(c2, c3)
        );
    }
}
