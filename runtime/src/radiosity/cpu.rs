//! CPU references of the radiosity iteration.
//!
//! - [`radiosity`]: the GPU iteration step for step (`gather.wgsl`, `pull.wgsl`) with the CPU
//!   visibility query, its twin.
//! - [`brute_force`]: radiosity over the same texels with no hierarchy (every texel gathers
//!   from every other) and exact ray-cast visibility: the ground truth the hierarchy and the
//!   CSSM approximate.

use cssm_formats::{CssmFile, visibility::VisibilityQuery};
use cssm_raycast::SceneBvh;
use glam::Vec3;
use rayon::prelude::*;

use super::transfer::{irradiance_bound, irradiance_from, irradiance_from_texel, tone_mapped};
use crate::gpu_types::GpuNode;

const PI: f32 = std::f32::consts::PI;

/// The result of an iteration.
#[derive(Clone, Debug, PartialEq)]
pub struct CpuRadiosity {
    /// Mean radiance per node (direct + the bounces).
    pub node_radiance: Vec<Vec3>,
    /// Indirect irradiance per texel of the last iteration (texel order).
    pub texel_irradiance: Vec<Vec3>,
    /// Nodes gathered from, summed over the receivers of the last iteration (the work the
    /// threshold trades against error).
    pub gathered: u64,
}

/// The oracle's and the gather's constants (the GPU's `TraversalParams`).
#[derive(Clone, Copy, Debug)]
pub struct Traversal {
    /// Refinement threshold on the tone-mapped bound.
    pub threshold: f32,
    /// Exposure of the oracle's tone mapper.
    pub exposure: f32,
}

/// `gather.wgsl::gather_texel`: irradiance at texel `receiver` (position `p`, normal `n`,
/// largest albedo channel `rho`), and the number of nodes gathered from (the cut size).
#[allow(clippy::too_many_arguments)]
pub fn gather_texel(
    query: &VisibilityQuery,
    nodes: &[GpuNode],
    radiance: &[Vec3],
    traversal: &Traversal,
    receiver: u32,
    p: Vec3,
    n: Vec3,
    rho: f32,
) -> (Vec3, u32) {
    let texels = &query.file().texels;
    let mut e = Vec3::ZERO;
    let mut cut = 0;
    let mut s = 0usize;
    while s < nodes.len() {
        let node = &nodes[s];
        let l = radiance[s];
        if node.count > 1
            && tone_mapped(
                irradiance_bound(p, n, node, l) * (rho / PI),
                traversal.exposure,
            ) > traversal.threshold
        {
            s += 1;
            continue;
        }
        cut += 1;
        let sender = node.representative;
        if sender != receiver && l.cmpgt(Vec3::ZERO).any() {
            let y = &texels[sender as usize];
            // A single texel's footprint is integrated in its near field.
            let (unoccluded, _) = if node.count == 1 {
                irradiance_from_texel(p, n, y.pos(), y.nrm(), node.area, l)
            } else {
                irradiance_from(p, n, y.pos(), Vec3::from(node.normal), node.area, l)
            };
            if unoccluded.cmpgt(Vec3::ZERO).any() {
                // Both ends' cube maps when the options ask (QueryOptions::both_ends).
                let visibility = query
                    .visibility_between(
                        &[(receiver, 1.0)],
                        p,
                        n,
                        &[(sender, 1.0)],
                        y.pos(),
                        y.nrm(),
                    )
                    .unwrap_or(1.0);
                e += unoccluded * visibility;
            }
        }
        s = node.skip as usize;
    }
    (e, cut)
}

/// `pull.wgsl`: every inner node's radiance becomes the area-weighted mean of its children's
/// (children come after their parent, so a reverse sweep sees them done).
pub fn pull(nodes: &[GpuNode], radiance: &mut [Vec3]) {
    for i in (0..nodes.len()).rev() {
        if nodes[i].count > 1 {
            let (l, r) = (i + 1, nodes[i + 1].skip as usize);
            let (al, ar) = (nodes[l].area, nodes[r].area);
            let total = al + ar;
            radiance[i] = if total > 0.0 {
                (radiance[l] * al + radiance[r] * ar) / total
            } else {
                0.5 * (radiance[l] + radiance[r])
            };
        }
    }
}

/// The GPU iteration on the CPU: the direct light `direct` (radiance per texel) pulled into
/// the tree, then `iterations` bounces of gather and pull.
pub fn radiosity(
    query: &VisibilityQuery,
    direct: &[Vec3],
    albedo: &[Vec3],
    traversal: &Traversal,
    iterations: u32,
) -> CpuRadiosity {
    let file = query.file();
    let nodes = &file.hierarchy.nodes;
    let leaf_texels = &file.hierarchy.leaf_texels;
    let leaf_nodes: Vec<(u32, usize)> = nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| n.count == 1)
        .map(|(i, n)| (leaf_texels[n.first as usize], i))
        .collect();
    let mut radiance = vec![Vec3::ZERO; nodes.len()];
    for &(t, i) in &leaf_nodes {
        radiance[i] = direct[t as usize];
    }
    pull(nodes, &mut radiance);
    let mut irradiance = vec![Vec3::ZERO; file.texels.len()];
    let mut gathered_total = 0;
    for _ in 0..iterations {
        let gathered: Vec<(u32, usize, Vec3, u32)> = leaf_nodes
            .par_iter()
            .map(|&(t, i)| {
                let texel = &file.texels[t as usize];
                let a = albedo[t as usize];
                let (e, cut) = gather_texel(
                    query,
                    nodes,
                    &radiance,
                    traversal,
                    t,
                    texel.pos(),
                    texel.nrm(),
                    a.max_element(),
                );
                (t, i, e, cut)
            })
            .collect();
        gathered_total = gathered.iter().map(|g| g.3 as u64).sum();
        let mut next = radiance.clone();
        for (t, i, e, _) in gathered {
            irradiance[t as usize] = e;
            next[i] = direct[t as usize] + albedo[t as usize] / PI * e;
        }
        pull(nodes, &mut next);
        radiance = next;
    }
    CpuRadiosity {
        node_radiance: radiance,
        texel_irradiance: irradiance,
        gathered: gathered_total,
    }
}

/// Ground truth over the same texels: `iterations` Jacobi bounces where every texel gathers
/// from every other texel with the same transfer ([`super::transfer::irradiance_from_texel`]:
/// the texel's footprint in its near field, a clamped point beyond) and exact visibility (a ray cast between the two
/// points, each lifted off its surface by `1e-4` of the scene diameter). Returns the indirect
/// irradiance per texel. Quadratic in the texel count: for small atlases.
pub fn brute_force(
    file: &CssmFile,
    bvh: &SceneBvh,
    diameter: f32,
    direct: &[Vec3],
    albedo: &[Vec3],
    iterations: u32,
) -> Vec<Vec3> {
    let texels = &file.texels;
    let eps = 1e-4 * diameter;
    let count = texels.len();
    // Visibility is the same every bounce: cast it once (a bit per pair).
    let visible: Vec<Vec<bool>> = (0..count)
        .into_par_iter()
        .map(|r| {
            let (p, n) = (texels[r].pos(), texels[r].nrm());
            (0..count)
                .map(|s| {
                    let (y, m) = (texels[s].pos(), texels[s].nrm());
                    s != r
                        && n.dot(y - p) > 0.0
                        && m.dot(p - y) > 0.0
                        && bvh.segment_clear(p + n * eps, y + m * eps)
                })
                .collect()
        })
        .collect();
    let mut radiance = direct.to_vec();
    let mut irradiance = vec![Vec3::ZERO; count];
    for _ in 0..iterations {
        irradiance = (0..count)
            .into_par_iter()
            .map(|r| {
                let (p, n) = (texels[r].pos(), texels[r].nrm());
                (0..count)
                    .filter(|&s| visible[r][s])
                    .map(|s| {
                        let t = &texels[s];
                        irradiance_from_texel(p, n, t.pos(), t.nrm(), t.area, radiance[s]).0
                    })
                    .sum()
            })
            .collect();
        radiance = (0..count)
            .map(|t| direct[t] + albedo[t] / PI * irradiance[t])
            .collect();
    }
    irradiance
}
