//! The light transfer between a hierarchy node and a receiver point, and the oracle's upper
//! bound of it (§4.3, §4.4): the CPU twin of `transfer.wgsl`, function by function, used by the
//! CPU references of the radiosity gather and of the final gather.
//!
//! Model (conventions in `docs/architecture.md`):
//! - A sender node is a Lambertian emitter of area `A` with the area-weighted mean radiance `L`
//!   of its texels and their area-weighted mean normal `n_s` (length <= 1: for a cluster whose
//!   texels all face the receiver, `A * dot(n_s, w)` is exactly the summed projected area).
//! - A cluster (more than one texel) shows towards a receiver the area
//!   [`cluster_projected_area`]: half of its net projected area `-A * dot(n_s, w)` plus the
//!   root of `A * w^T M w` (`M` the second moment of its normals, [`node_spreads`]), exact for
//!   a flat cluster and within about 15% above the truth for a sphere's or a column's spread of
//!   normals, where the net area alone counts the backs against the fronts and loses most of
//!   the light (the nave of reports/final-gather.md).
//! - It sits at its representative texel, so that visibility is always asked between two
//!   surface points; where the representative faces away from the receiver, the visibility is
//!   asked of the node's texel facing the most away from the representative instead
//!   ([`visibility_sender`]): a representative's own back would block every cluster seen from
//!   its other side. The final gather with jittering (§4.5) takes instead a random texel of the
//!   node ([`jitter_leaf`]) and a random point of that texel's footprint, a disk of the texel's
//!   area ([`jitter_in_disk`]), so that even a cut of single texels converges. The radiosity
//!   iteration does not jitter: its diffuse receivers show no VPL bias.
//! - Irradiance at `p` (normal `n`): `L * A * cos_r * cos_s / (d² + A / pi)`. The `A / pi` is the
//!   clamping near the sender (§4.4, §5 "clamping is used"): it is the exact on-axis irradiance
//!   from a disk of area `A` (`pi L a² / (h² + a²)`), so a close sender gives a finite disk's
//!   light instead of a point's singularity. A single texel within [`NEAR_FIELD_SIZES`] texel
//!   sizes of the receiver sends instead from its footprint, integrated exactly
//!   ([`irradiance_from_footprint`]): the clamp is right on the sender's axis only, and beside a
//!   crease, where most of the light comes from texels seen edge-on, a point loses it.
//!
//! Oracle (§4.3): an upper bound of the radiance the receiver would reflect from the whole node,
//! `Σ L_i A_i cos cos / d_i² <= L A · max cos_r · max cos_s / d_min²` with the cosine maxima over
//! the node's bounding sphere and normal cone; the node is refined while the tone-mapped bound
//! exceeds the threshold.

use cssm_formats::{hierarchy::Hierarchy, texel::Texel};
use glam::{DVec3, Vec3};

use crate::gpu_types::{GpuNode, GpuNodeSpread, NODE_ALL_EMITTERS, NODE_EMITTER};

const PI: f32 = std::f32::consts::PI;

/// Stands for an unbounded bound (the receiver inside the sender's sphere).
pub const UNBOUNDED: f32 = 3.0e38;

/// The largest cosine between the unit `axis` and any direction from the apex into the sphere
/// (`to_center` = centre - apex, `radius`), widened by `spread` radians (a normal cone's
/// half-angle); 1 when the apex is inside the sphere. `transfer.wgsl`: `cos_bound`.
pub fn cos_bound(axis: Vec3, spread: f32, to_center: Vec3, radius: f32) -> f32 {
    let dist = to_center.length();
    if dist <= radius {
        return 1.0;
    }
    let theta = (axis.dot(to_center) / dist).clamp(-1.0, 1.0).acos();
    let alpha = (radius / dist).min(1.0).asin();
    let phi = (theta - alpha - spread).max(0.0);
    if phi >= 0.5 * PI { 0.0 } else { phi.cos() }
}

/// Tone-mapped value of a radiance for the oracle: the paper's simple gamma tone mapper on the
/// largest channel (§4.3). `transfer.wgsl`: `tone_mapped`.
pub fn tone_mapped(radiance: Vec3, exposure: f32) -> f32 {
    (exposure * radiance.max_element()).max(0.0).powf(1.0 / 2.2)
}

/// Upper bound of the irradiance at `p` (normal `n`) from every texel of `node`, whose mean
/// radiance is `radiance`. `transfer.wgsl`: `irradiance_bound`.
pub fn irradiance_bound(p: Vec3, n: Vec3, node: &GpuNode, radiance: Vec3) -> Vec3 {
    let center = Vec3::from(node.center);
    let to_center = center - p;
    let d_min = to_center.length() - node.radius;
    if d_min <= 0.0 {
        return Vec3::splat(UNBOUNDED);
    }
    let cos_r = cos_bound(n, 0.0, to_center, node.radius);
    let mean = Vec3::from(node.normal);
    let len = mean.length();
    let cos_s = if node.cone_cos <= -1.0 || len < 1e-6 {
        1.0
    } else {
        let spread = node.cone_cos.clamp(-1.0, 1.0).acos();
        cos_bound(-mean / len, spread, to_center, node.radius)
    };
    radiance * (node.area * cos_r * cos_s / (d_min * d_min))
}

/// Largest value of the normalised Phong BRDF (`light.wgsl`) at a point with normal `n`, view
/// direction `v` (towards the eye), for light arriving from anywhere in the sphere.
/// `transfer.wgsl`: `brdf_bound`.
pub fn brdf_bound(
    n: Vec3,
    v: Vec3,
    albedo: Vec3,
    ks: Vec3,
    ns: f32,
    to_center: Vec3,
    radius: f32,
) -> Vec3 {
    let mirror = (-v).reflect(n);
    let c = cos_bound(mirror, 0.0, to_center, radius);
    albedo / PI + ks * ((ns + 2.0) / (2.0 * PI) * c.powf(ns))
}

/// The normalised Phong BRDF of `light.wgsl` for light from the unit direction `w`.
/// `transfer.wgsl`: `brdf`.
pub fn brdf(n: Vec3, v: Vec3, w: Vec3, albedo: Vec3, ks: Vec3, ns: f32) -> Vec3 {
    albedo / PI + ks * phong_lobe(n, v, w, ns)
}

/// The normalised Phong lobe of [`brdf`] without Ks: what a gather weights its glossy plane
/// with, so that the reflection takes the full-resolution Ks after filtering.
/// `transfer.wgsl`: `phong_lobe`.
pub fn phong_lobe(n: Vec3, v: Vec3, w: Vec3, ns: f32) -> f32 {
    let r = (-w).reflect(n);
    (ns + 2.0) / (2.0 * PI) * r.dot(v).max(0.0).powf(ns)
}

/// Unoccluded irradiance at `p` (normal `n`) from a sender at `y` with mean normal
/// `sender_normal`, area `area` and radiance `radiance` (clamped near the sender), and the unit
/// direction towards it. `transfer.wgsl`: `irradiance_from`.
pub fn irradiance_from(
    p: Vec3,
    n: Vec3,
    y: Vec3,
    sender_normal: Vec3,
    area: f32,
    radiance: Vec3,
) -> (Vec3, Vec3) {
    let d = y - p;
    let dist2 = d.dot(d);
    if dist2 <= 0.0 {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    let w = d / dist2.sqrt();
    let cos_r = n.dot(w).max(0.0);
    let cos_s = (-sender_normal.dot(w)).max(0.0);
    (radiance * (area * cos_r * cos_s / (dist2 + area / PI)), w)
}

/// The area a cluster of texels shows towards `-w` (`w` the unit direction from the receiver
/// to it): half of its net projected area plus the root of `A * w^T M w`, `M` its normals'
/// second moment. Exact when the texels are coplanar (`A * max(0, -dot(n, w))`); for normals
/// spread over a sphere or around a column it overestimates the summed `A_i max(0, cos_i)` by
/// about 15% and 11%, where the net area alone would give zero. `transfer.wgsl`:
/// `cluster_projected_area`.
///
/// ```
/// use cssm_runtime::{gpu_types::{GpuNode, GpuNodeSpread}, radiosity::transfer::cluster_projected_area};
/// use glam::Vec3;
/// // Two texels of area 1 back to back (normals +z and -z): no net area, one texel's worth
/// // seen from either side.
/// let node = GpuNode { normal: [0.0; 3], area: 2.0, count: 2, ..Default::default() };
/// let spread = GpuNodeSpread { moment_a: [0.0, 0.0, 2.0, 0.0], ..Default::default() };
/// assert!((cluster_projected_area(&node, &spread, Vec3::Z) - 1.0).abs() < 1e-6);
/// assert!((cluster_projected_area(&node, &spread, -Vec3::Z) - 1.0).abs() < 1e-6);
/// ```
pub fn cluster_projected_area(node: &GpuNode, spread: &GpuNodeSpread, w: Vec3) -> f32 {
    let net = -node.area * Vec3::from(node.normal).dot(w);
    let [xx, yy, zz, xy] = spread.moment_a;
    let [xz, yz] = spread.moment_b;
    let q = xx * w.x * w.x
        + yy * w.y * w.y
        + zz * w.z * w.z
        + 2.0 * (xy * w.x * w.y + xz * w.x * w.z + yz * w.y * w.z);
    (0.5 * (net + (node.area * q).max(0.0).sqrt())).max(0.0)
}

/// Unoccluded irradiance at `p` (normal `n`) from the cluster `node` (more than one texel) sat
/// at `y`, of mean radiance `radiance` (clamped near it as [`irradiance_from`] is), and the unit
/// direction towards it. `transfer.wgsl`: `irradiance_from_cluster`.
pub fn irradiance_from_cluster(
    p: Vec3,
    n: Vec3,
    y: Vec3,
    node: &GpuNode,
    spread: &GpuNodeSpread,
    radiance: Vec3,
) -> (Vec3, Vec3) {
    let d = y - p;
    let dist2 = d.dot(d);
    if dist2 <= 0.0 {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    let w = d / dist2.sqrt();
    let cos_r = n.dot(w).max(0.0);
    let area = cluster_projected_area(node, spread, w);
    (radiance * (area * cos_r / (dist2 + node.area / PI)), w)
}

/// Whether the texel `t` faces the point `p` (`p` strictly in front of its plane).
pub fn faces(t: &Texel, p: Vec3) -> bool {
    (p - t.pos()).dot(t.nrm()) > 0.0
}

/// The texel whose visibility stands for `node`'s towards a receiver at `p`, `texels` where
/// they stand: its representative, unless that faces away from `p` and the node's texel facing
/// the most away from it ([`GpuNodeSpread::other`]) faces `p`. `gather.wgsl` and
/// `final_gather.wgsl` make the same choice.
pub fn visibility_sender(node: &GpuNode, spread: &GpuNodeSpread, texels: &[Texel], p: Vec3) -> u32 {
    let representative = node.representative;
    if node.count > 1
        && !faces(&texels[representative as usize], p)
        && faces(&texels[spread.other as usize], p)
    {
        spread.other
    } else {
        representative
    }
}

/// Every node's [`GpuNodeSpread`] over `texels` (where they stand now: a refitted hierarchy
/// takes the posed texels): the second moment of its texels' normals, summed in `f64` bottom
/// up, its texel whose normal is the most opposite to its representative's (the lowest
/// texel index among equals, so every build picks the same), and whether it holds texels
/// whose material emits (`emitting`, per material: [`super::emitting_materials`]; a
/// material past its end emits nothing): [`NODE_EMITTER`], [`NODE_ALL_EMITTERS`].
pub fn node_spreads(
    hierarchy: &Hierarchy,
    texels: &[Texel],
    emitting: &[bool],
) -> Vec<GpuNodeSpread> {
    let nodes = &hierarchy.nodes;
    let leaves = &hierarchy.leaf_texels;
    // [xx, yy, zz, xy, xz, yz] per node.
    let mut moments = vec![[0f64; 6]; nodes.len()];
    for i in (0..nodes.len()).rev() {
        let node = &nodes[i];
        if node.count == 1 {
            let t = &texels[leaves[node.first as usize] as usize];
            let n: DVec3 = t.nrm().as_dvec3();
            let a = f64::from(t.area);
            moments[i] = [
                a * n.x * n.x,
                a * n.y * n.y,
                a * n.z * n.z,
                a * n.x * n.y,
                a * n.x * n.z,
                a * n.y * n.z,
            ];
        } else {
            let (l, r) = (moments[i + 1], moments[nodes[i + 1].skip as usize]);
            moments[i] = std::array::from_fn(|k| l[k] + r[k]);
        }
    }
    nodes
        .iter()
        .zip(&moments)
        .map(|(node, m)| {
            let facing = texels[node.representative as usize].nrm();
            let range = node.first as usize..(node.first + node.count) as usize;
            let other = leaves[range]
                .iter()
                .copied()
                .min_by(|&a, &b| {
                    let (da, db) = (
                        texels[a as usize].nrm().dot(facing),
                        texels[b as usize].nrm().dot(facing),
                    );
                    da.total_cmp(&db).then(a.cmp(&b))
                })
                .unwrap_or(node.representative);
            let emits = |&t: &u32| {
                let material = texels[t as usize].material as usize;
                emitting.get(material).copied().unwrap_or(false)
            };
            let range = node.first as usize..(node.first + node.count) as usize;
            let flags = if leaves[range.clone()].iter().all(emits) {
                NODE_EMITTER | NODE_ALL_EMITTERS
            } else if leaves[range].iter().any(emits) {
                NODE_EMITTER
            } else {
                0
            };
            GpuNodeSpread {
                moment_a: [m[0] as f32, m[1] as f32, m[2] as f32, m[3] as f32],
                moment_b: [m[4] as f32, m[5] as f32],
                other,
                flags,
            }
        })
        .collect()
}

/// Within this many texel sizes (`sqrt(A)`) of a single texel, the transfer integrates the
/// texel's footprint ([`irradiance_from_footprint`]) instead of clamping a point
/// ([`irradiance_from`]): the clamp is the exact value on the sender's axis only, and a receiver
/// beside a crease, whose nearest senders lie across it almost in its own plane, gets a point's
/// zero (`cos_s` = 0 at the texel's centre) where the texel's footprint above the crease lights it.
/// At three sizes both agree within 4% of a facing sender's light, the most where the
/// footprint straddles the receiver's horizon (`near_field_and_far_field_meet_at_its_edge`).
pub const NEAR_FIELD_SIZES: f32 = 3.0;

/// Whether a receiver at `p` is in the near field of the texel at `y` of area `area`.
/// `transfer.wgsl`: `in_near_field`.
pub fn in_near_field(p: Vec3, y: Vec3, area: f32) -> bool {
    (y - p).length_squared() < NEAR_FIELD_SIZES * NEAR_FIELD_SIZES * area
}

/// The share of a single texel's light that `lightcuts`' per-pixel near field takes, at
/// distance `dist` from the receiver (`radius`: the near field's reach,
/// [`crate::lightcuts::near_radius`]): 1 within half the reach, 0 beyond it, a smoothstep
/// between. The texture-space final gather splits every transfer in two by it: the atlas
/// gathers `1 - w` of each sender at the texel centres, where what is left is smooth enough to
/// interpolate, and each pixel gathers `w` of its own near senders. The weight depends on the
/// distance alone, so the two halves sum to the whole transfer wherever the receiver is.
/// `transfer.wgsl`: `near_split_weight`.
pub fn near_split_weight(dist: f32, radius: f32) -> f32 {
    if radius <= 0.0 {
        return 0.0;
    }
    let t = ((dist - 0.5 * radius) / (0.5 * radius)).clamp(0.0, 1.0);
    1.0 - t * t * (3.0 - 2.0 * t)
}

/// Receivers closer than this many texel sizes to a texel's plane are in it
/// ([`irradiance_from_footprint`]).
const COPLANAR: f32 = 1e-3;

/// Corners of the regular octagon of unit area (circumradius `1 / sqrt(2 sqrt 2)`), counter-
/// clockwise about the normal in its tangent frame: a texel's footprint, its area and centre
/// kept (the atlas stores no texel's shape, and the octagon is as isotropic as the disk of
/// [`jitter_in_disk`] at eight corners).
const OCTAGON: [(f32, f32); 8] = {
    const R: f32 = 0.594_603_55; // 1 / sqrt(2 sqrt 2)
    const D: f32 = R * std::f32::consts::FRAC_1_SQRT_2;
    [
        (R, 0.0),
        (D, D),
        (0.0, R),
        (-D, D),
        (-R, 0.0),
        (-D, -D),
        (0.0, -R),
        (D, -D),
    ]
};

/// Unoccluded irradiance at `p` (normal `n`) from a texel at `y` (unit normal `sender_normal`,
/// area `area`, radiance `radiance`), integrated exactly over its footprint: Lambert's formula
/// for a uniformly emitting polygon, `E = L/2 Σ Θ_i n·Γ_i` over the edges of the octagon of the
/// texel's area, clipped to the receiver's upper hemisphere (Sutherland-Hodgman against its
/// tangent plane); zero behind the sender (one-sided). The unit direction returned is towards
/// the centre. `transfer.wgsl`: `irradiance_from_footprint`.
pub fn irradiance_from_footprint(
    p: Vec3,
    n: Vec3,
    y: Vec3,
    sender_normal: Vec3,
    area: f32,
    radiance: Vec3,
) -> (Vec3, Vec3) {
    let d = y - p;
    let scale = area.max(0.0).sqrt();
    // In front of the sender by a margin: a receiver in the texel's own plane (its neighbour
    // on the same surface) gets nothing, whatever the rounding, even where a tilted shading
    // normal (a normal map) puts the texel above its horizon.
    if d.length_squared() <= 0.0 || sender_normal.dot(-d) <= COPLANAR * scale {
        return (Vec3::ZERO, Vec3::ZERO);
    }
    let (t, s) = tangent_frame(sender_normal);
    let corner = |k: usize| d + (t * OCTAGON[k].0 + s * OCTAGON[k].1) * scale;
    // Clip to the receiver's hemisphere: at most one corner more than the octagon's eight.
    let mut clipped = [Vec3::ZERO; 9];
    let mut count = 0;
    for k in 0..8 {
        let a = corner(k);
        let b = corner((k + 1) % 8);
        let (da, db) = (a.dot(n), b.dot(n));
        if da >= 0.0 {
            clipped[count] = a;
            count += 1;
        }
        if (da >= 0.0) != (db >= 0.0) {
            clipped[count] = a + (b - a) * (da / (da - db));
            count += 1;
        }
    }
    let mut sum = 0.0;
    for i in 0..count {
        let a = clipped[i];
        let b = clipped[(i + 1) % count];
        let c = a.cross(b);
        let len = c.length();
        if len > 0.0 {
            sum += len.atan2(a.dot(b)) * n.dot(c) / len;
        }
    }
    // Counter-clockwise about the sender's normal is clockwise seen from its front: -Σ.
    let e = (-0.5 * sum).max(0.0);
    (radiance * e, d.normalize())
}

/// The transfer from a single texel: [`irradiance_from_footprint`] in its near field,
/// [`irradiance_from`] beyond. `transfer.wgsl`: `irradiance_from_texel`.
pub fn irradiance_from_texel(
    p: Vec3,
    n: Vec3,
    y: Vec3,
    sender_normal: Vec3,
    area: f32,
    radiance: Vec3,
) -> (Vec3, Vec3) {
    if in_near_field(p, y, area) {
        irradiance_from_footprint(p, n, y, sender_normal, area, radiance)
    } else {
        irradiance_from(p, n, y, sender_normal, area, radiance)
    }
}

// The jitter's random numbers on both sides (`transfer.wgsl` imports `cssm::random`).
use crate::common::random::pcg_hash;

/// The jitter's random word for (`seed`, `receiver`, `node_index`): one draw per frame,
/// receiver and node. `transfer.wgsl`: `jitter_hash`.
pub fn jitter_hash(seed: u32, receiver: u32, node_index: u32) -> u32 {
    pcg_hash(seed ^ pcg_hash(receiver ^ pcg_hash(node_index)))
}

/// Leaf (in leaf order) standing for `node` as seen by `receiver`: with `jitter` a random leaf
/// of the node (§4.5), else none (the caller takes the representative).
/// `transfer.wgsl`: `jitter_leaf`.
pub fn jitter_leaf(seed: u32, receiver: u32, node_index: u32, node: &GpuNode) -> u32 {
    node.first + jitter_hash(seed, receiver, node_index) % node.count.max(1)
}

/// A random point of the disk of area `area` around `center`, in the plane normal to the unit
/// `normal`: §4.5 associates "an approximate area with every VPL from which we pick a random
/// location"; the approximate area of a texel is a disk of its own area. Uniform over the disk.
/// `transfer.wgsl`: `jitter_in_disk`.
pub fn jitter_in_disk(
    seed: u32,
    receiver: u32,
    node_index: u32,
    center: Vec3,
    normal: Vec3,
    area: f32,
) -> Vec3 {
    let a = pcg_hash(jitter_hash(seed, receiver, node_index));
    let b = pcg_hash(a);
    let u = (a >> 8) as f32 / 16_777_216.0;
    let v = (b >> 8) as f32 / 16_777_216.0;
    let r = (area / PI).sqrt() * u.sqrt();
    let phi = 2.0 * PI * v;
    let (t, s) = tangent_frame(normal);
    center + t * (r * phi.cos()) + s * (r * phi.sin())
}

/// Two unit tangents completing the unit `n` to an orthonormal frame, without a branch on a
/// near-zero axis (Duff et al. 2017). `transfer.wgsl`: `tangent_frame`.
pub fn tangent_frame(n: Vec3) -> (Vec3, Vec3) {
    // The same construction as a coherent shadow map's image plane.
    cssm_formats::csm::image_frame(n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Texels of random positions, areas and normals (a few planes, or spread over the
    /// sphere), as the atlas would give them.
    fn texels(count: usize, planes: usize, seed: u64) -> Vec<Texel> {
        let mut rng = cssm_raycast::SplitMix64(seed);
        let mut r = || rng.next_f64() as f32;
        let normals: Vec<Vec3> = (0..planes.max(1))
            .map(|_| Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize())
            .collect();
        (0..count)
            .map(|k| {
                let n = if planes == 0 {
                    Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5).normalize()
                } else {
                    normals[k % planes]
                };
                Texel {
                    position: [r(), r(), r()],
                    normal: n.to_array(),
                    area: 0.01 + r(),
                    material: 0,
                    chart: 0,
                    object: 0,
                    x: k as u16,
                    y: 0,
                }
            })
            .collect()
    }

    /// What a cluster shows towards `-w`: the sum of its texels' `A max(0, -dot(n, w))`.
    fn summed_projected_area(leaves: &[u32], texels: &[Texel], w: Vec3) -> f32 {
        leaves
            .iter()
            .map(|&t| texels[t as usize].area * (-texels[t as usize].nrm().dot(w)).max(0.0))
            .sum()
    }

    /// The moment's estimate is never below the summed projected area (Cauchy-Schwarz:
    /// `sum A |cos| <= sqrt(A sum A cos^2)`), equals it for a flat cluster, and stays within
    /// 30% of it for 100 texels or more drawn over the sphere (15.5% for a uniform sphere),
    /// where the net area alone loses about all of it.
    #[test]
    fn cluster_projected_area_bounds_the_summed_one() {
        for (planes, seed) in [(1usize, 1u64), (2, 2), (3, 3), (0, 4)] {
            let texels = texels(200, planes, seed);
            let hierarchy = Hierarchy::build(&texels);
            let spreads = node_spreads(&hierarchy, &texels, &[]);
            let mut rng = cssm_raycast::SplitMix64(seed + 100);
            for (i, node) in hierarchy.nodes.iter().enumerate() {
                let leaves = hierarchy.leaves(i);
                for _ in 0..8 {
                    let mut r = || rng.next_f64() as f32 - 0.5;
                    let w = Vec3::new(r(), r(), r()).normalize();
                    let truth = summed_projected_area(leaves, &texels, w);
                    let model = cluster_projected_area(node, &spreads[i], w);
                    let scale = 1e-4 * node.area;
                    assert!(
                        model >= truth - scale,
                        "{planes} planes, node {i}: {model} < {truth}"
                    );
                    if planes == 1 {
                        assert!((model - truth).abs() <= scale, "flat: {model} vs {truth}");
                    }
                    if planes == 0 && node.count >= 100 {
                        assert!(model <= 1.3 * truth + scale, "sphere: {model} vs {truth}");
                    }
                }
            }
        }
    }

    /// A node is flagged as holding an emitter when one of its texels' material emits, and
    /// as all emitters when every one's does; a material past `emitting`'s end emits nothing.
    #[test]
    fn emitter_flags_follow_the_texels_materials() {
        let mut texels = texels(96, 3, 11);
        for (k, t) in texels.iter_mut().enumerate() {
            // Materials 0 (dark), 1 (emits) and 2 (past the table's end).
            t.material = [0, 1, 2][(k % 7) % 3];
        }
        let hierarchy = Hierarchy::build(&texels);
        let spreads = node_spreads(&hierarchy, &texels, &[false, true]);
        let (mut mixed, mut pure) = (0, 0);
        for (i, spread) in spreads.iter().enumerate() {
            let emits: Vec<bool> = hierarchy
                .leaves(i)
                .iter()
                .map(|&t| texels[t as usize].material == 1)
                .collect();
            let any = emits.iter().any(|&e| e);
            let all = emits.iter().all(|&e| e);
            assert_eq!(spread.flags & NODE_EMITTER != 0, any, "node {i}");
            assert_eq!(spread.flags & NODE_ALL_EMITTERS != 0, all, "node {i}");
            mixed += usize::from(any && !all);
            pure += usize::from(all);
        }
        assert!(mixed > 0 && pure > 0, "{mixed} mixed, {pure} pure");
        // No table: nothing emits.
        let none = node_spreads(&hierarchy, &texels, &[]);
        assert!(none.iter().all(|s| s.flags == 0));
    }

    /// The other-side texel has the normal most opposite to the representative's.
    #[test]
    fn other_side_texel_faces_away_from_the_representative() {
        let texels = texels(64, 0, 7);
        let hierarchy = Hierarchy::build(&texels);
        let spreads = node_spreads(&hierarchy, &texels, &[]);
        for (i, node) in hierarchy.nodes.iter().enumerate() {
            let facing = texels[node.representative as usize].nrm();
            let other = spreads[i].other;
            assert!(hierarchy.leaves(i).contains(&other));
            let least = hierarchy
                .leaves(i)
                .iter()
                .map(|&t| texels[t as usize].nrm().dot(facing))
                .fold(f32::INFINITY, f32::min);
            assert_eq!(texels[other as usize].nrm().dot(facing), least);
            // Seen from behind the representative, the other side answers if it faces.
            let p = texels[other as usize].pos() + texels[other as usize].nrm();
            let sender = visibility_sender(node, &spreads[i], &texels, p);
            if node.count > 1 && !faces(&texels[node.representative as usize], p) {
                assert_eq!(sender, other);
            } else {
                assert_eq!(sender, node.representative);
            }
        }
    }

    #[test]
    fn jitter_in_disk_stays_in_the_disk_and_covers_it() {
        let normal = Vec3::new(0.3, -0.8, 0.52).normalize();
        let (t, s) = tangent_frame(normal);
        assert!(t.dot(s).abs() < 1e-6 && t.dot(normal).abs() < 1e-6 && s.dot(normal).abs() < 1e-6);
        assert!((t.length() - 1.0).abs() < 1e-6 && (s.length() - 1.0).abs() < 1e-6);
        let (center, area) = (Vec3::new(1.0, 2.0, 3.0), 0.5);
        let radius = (area / PI).sqrt();
        let mut outer = 0;
        let n = 20_000;
        let mut mean = Vec3::ZERO;
        for frame in 0..n {
            let p = jitter_in_disk(frame, 7, 11, center, normal, area);
            let d = p - center;
            assert!(d.dot(normal).abs() < 1e-5, "off the plane: {d}");
            assert!(
                d.length() <= radius * 1.0001,
                "outside the disk: {}",
                d.length()
            );
            // Uniform over the area: the outer ring (r > radius / sqrt 2) holds half of it.
            outer += usize::from(d.length() > radius / 2f32.sqrt());
            mean += d;
        }
        let outer = outer as f32 / n as f32;
        assert!(
            (outer - 0.5).abs() < 0.02,
            "outer half of the area got {outer}"
        );
        assert!(
            (mean / n as f32).length() < 0.02 * radius,
            "biased: {}",
            mean / n as f32
        );
    }

    #[test]
    fn cos_bound_is_an_upper_bound_of_sampled_cosines() {
        let mut state = 1u32;
        let mut rnd = || {
            state = pcg_hash(state);
            state as f32 / u32::MAX as f32
        };
        for _ in 0..2000 {
            let axis = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
            let center = Vec3::new(rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0, rnd() * 4.0 - 2.0);
            let radius = rnd();
            let spread = rnd() * 0.5;
            let bound = cos_bound(axis, spread, center, radius);
            for _ in 0..20 {
                let q = center
                    + Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize() * radius * rnd();
                let d = q.normalize();
                assert!(axis.dot(d) <= bound + 1e-4, "{} > {bound}", axis.dot(d));
            }
        }
    }

    /// Irradiance from the octagon of `area` around `y` by a midpoint rule over a fine grid of
    /// its tangent plane: the footprint's definition, summed instead of integrated.
    fn octagon_by_quadrature(p: Vec3, n: Vec3, y: Vec3, normal: Vec3, area: f32) -> f32 {
        let (t, s) = tangent_frame(normal);
        let r = 0.594_603_55 * area.sqrt();
        let steps = 600;
        let h = 2.0 * r / steps as f32;
        let inside = |u: f32, v: f32| {
            // The octagon: |u|, |v| <= r cos(pi/8) and |u| + |v| <= sqrt 2 r cos(pi/8).
            let apothem = r * (PI / 8.0).cos();
            u.abs() <= apothem
                && v.abs() <= apothem
                && u.abs() + v.abs() <= std::f32::consts::SQRT_2 * apothem
        };
        let mut sum = 0.0f64;
        for i in 0..steps {
            for j in 0..steps {
                let (u, v) = (-r + (i as f32 + 0.5) * h, -r + (j as f32 + 0.5) * h);
                if !inside(u, v) {
                    continue;
                }
                let d = y + t * u + s * v - p;
                let dist2 = d.length_squared();
                let w = d / dist2.sqrt();
                let cos_r = n.dot(w).max(0.0);
                let cos_s = (-normal.dot(w)).max(0.0);
                sum += (cos_r * cos_s / dist2 * h * h) as f64;
            }
        }
        sum as f32
    }

    #[test]
    fn footprint_is_the_octagons_integral_wherever_the_receiver_is() {
        let mut state = 3u32;
        let mut rnd = || {
            state = pcg_hash(state);
            state as f32 / u32::MAX as f32
        };
        let area: f32 = 0.04;
        let mut checked = 0;
        while checked < 40 {
            let normal = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
            let n = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
            let y = Vec3::new(1.0, -2.0, 0.5);
            // In front of the sender, from a fifth of a texel size to four sizes away.
            let offset = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5) * 0.8;
            let p = y + offset;
            if (p - y).dot(normal) < 0.2 * area.sqrt() {
                continue;
            }
            let (e, _) = irradiance_from_footprint(p, n, y, normal, area, Vec3::ONE);
            let expected = octagon_by_quadrature(p, n, y, normal, area);
            let scale = area / (p - y).length_squared();
            assert!(
                (e.x - expected).abs() <= 0.01 * expected + 1e-3 * scale,
                "p {p} n {n} normal {normal}: {} vs quadrature {expected}",
                e.x
            );
            checked += 1;
        }
    }

    #[test]
    fn footprint_lights_a_receiver_at_the_foot_of_a_wall() {
        // A floor point at the crease, a wall texel standing on the crease: the texel's
        // centre is in the receiver's plane (cos_s = 0 at it), its footprint is not.
        let (area, size) = (0.01, 0.1);
        let p = Vec3::ZERO;
        let y = Vec3::new(0.0, 0.5 * size, 0.0);
        let (point, _) = irradiance_from(p, Vec3::Y, y, Vec3::NEG_X, area, Vec3::ONE);
        let (footprint, _) = irradiance_from_footprint(
            p - Vec3::new(0.01 * size, 0.0, 0.0),
            Vec3::Y,
            y,
            Vec3::NEG_X,
            area,
            Vec3::ONE,
        );
        assert!(point.x < 1e-6, "a point's light: {point}");
        assert!(footprint.x > 0.5, "the footprint's light: {footprint}");
        // Behind the sender: nothing.
        let (behind, _) = irradiance_from_footprint(
            Vec3::new(0.05, 0.0, 0.0),
            Vec3::Y,
            y,
            Vec3::NEG_X,
            area,
            Vec3::ONE,
        );
        assert_eq!(behind, Vec3::ZERO);
    }

    #[test]
    fn near_field_and_far_field_meet_at_its_edge() {
        // On the edge of the near field the footprint and the clamped point agree within 4% of
        // a facing sender's light in every orientation (3.7% measured, where the footprint
        // straddles the receiver's horizon and its centre lies below it).
        let mut state = 5u32;
        let mut rnd = || {
            state = pcg_hash(state);
            state as f32 / u32::MAX as f32
        };
        let area: f32 = 0.25;
        let y = Vec3::ZERO;
        let mut worst = 0.0f32;
        for _ in 0..2000 {
            let dir = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
            let p = dir * (NEAR_FIELD_SIZES * area.sqrt());
            let normal = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
            let n = Vec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
            let (near, _) = irradiance_from_footprint(p, n, y, normal, area, Vec3::ONE);
            let (far, _) = irradiance_from(p, n, y, normal, area, Vec3::ONE);
            let facing = area / p.length_squared();
            worst = worst.max((near.x - far.x).abs() / facing);
            assert!(
                (near.x - far.x).abs() <= 0.04 * facing,
                "{near} vs {far} (facing {facing})"
            );
        }
        assert!(worst > 0.0, "the two models are not the same");
    }

    #[test]
    fn close_sender_stays_finite_and_far_sender_is_a_point() {
        let n = Vec3::Y;
        let (e, _) = irradiance_from(Vec3::ZERO, n, Vec3::new(0.0, 1e-6, 0.0), -n, 1.0, Vec3::ONE);
        assert!(
            (e.x - PI).abs() < 1e-3,
            "a disk touching the receiver gives pi L: {e}"
        );
        let (e, _) = irradiance_from(
            Vec3::ZERO,
            n,
            Vec3::new(0.0, 100.0, 0.0),
            -n,
            1.0,
            Vec3::ONE,
        );
        assert!((e.x - 1e-4).abs() < 1e-8);
    }
}
