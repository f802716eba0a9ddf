//! The bounds of every node for the refinement oracle's upper bounds (§4.3): bounding sphere,
//! area-weighted mean normal, normal cone, summed area and representative texel, fitted
//! bottom-up over a fixed tree. The build (`build.rs`) runs it once over the median cut;
//! [`Hierarchy::refit`] reruns it when rigid objects move (§3.3).

use glam::DVec3;

use super::{Hierarchy, HierarchyNode};
use crate::texel::Texel;

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
}

/// The bottom-up half of [`Hierarchy::build`] (children come after their parent in pre-order):
/// bounds, sums and cones of every node of `nodes`, whose leaf ranges and skips are set, over
/// `order`, the leaves' (position, texel index) in leaf order.
pub(super) fn fit_bounds(nodes: &mut [HierarchyNode], order: &[([f32; 3], u32)], texels: &[Texel]) {
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

pub(super) fn dvec(v: [f32; 3]) -> DVec3 {
    DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]))
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
