//! CPU references of the radiosity iteration.
//!
//! - [`radiosity`]: the GPU iteration step for step (`gather.wgsl`, `pull.wgsl`) with the CPU
//!   visibility query, its twin; [`radiosity_over`] the same over a [`TwinScene`] whose rigid
//!   objects have moved (§3.3: their texels where they stand now, the hierarchy refitted, the
//!   moving objects' query).
//! - [`brute_force`]: radiosity over the same texels with no hierarchy (every texel gathers
//!   from every other) and exact ray-cast visibility: the ground truth the hierarchy and the
//!   CSSM approximate.

use std::borrow::Cow;

use cssm_formats::{
    CssmFile,
    hierarchy::Hierarchy,
    moving::{MovingQuery, ObjectPoint, posed_texels},
    texel::Texel,
    visibility::VisibilityQuery,
};
use cssm_raycast::SceneBvh;
use glam::{Affine3A, Vec3};
use rayon::prelude::*;

use super::transfer::{
    irradiance_bound, irradiance_from_cluster, irradiance_from_texel, near_split_weight,
    node_spreads, tone_mapped, visibility_sender,
};
use crate::{
    common::converge::{BouncePlan, Convergence, run_plan},
    gpu_types::{GpuNode, GpuNodeSpread, NODE_EMITTER},
};

pub use super::cpu_links::{
    Link, Links, build_links, cut_is_stale, far_field_with_links, link_product,
    radiosity_with_links, receiver_links, recut_links,
};

const PI: f32 = std::f32::consts::PI;

/// The visibility a twin gathers with: the CSSM query of a scene as baked, or the moving
/// objects' query (§3.3), whose objects stand where its poses put them (the GPU's
/// `moving_visibility_between`).
#[derive(Clone, Copy)]
pub enum TwinVisibility<'q, 'a> {
    /// Every object where it was baked: `VisibilityQuery::visibility_between`.
    Baked(&'q VisibilityQuery<'a>),
    /// Objects posed: `MovingQuery::visibility_between`.
    Moving(&'q MovingQuery<'a>),
}

impl<'a> TwinVisibility<'_, 'a> {
    /// The CSSM query (texels, atlas, sender filter).
    pub fn cssm(&self) -> &VisibilityQuery<'a> {
        match self {
            TwinVisibility::Baked(q) => q,
            TwinVisibility::Moving(q) => q.cssm(),
        }
    }

    /// Clear fraction between `a` (its texels, position, normal, object) and `b`, both where
    /// the objects stand now; `None` where neither end has texels.
    pub fn between(&self, a: &ObjectPoint, b: &ObjectPoint) -> Option<f32> {
        self.between_counted(a, b, &mut cssm_formats::visibility::QueryWork::default())
    }

    /// [`Self::between`], telling `tally` of the CSSM query's loads (issue 48's counters). The
    /// moving objects' query is not counted: with objects posed, `tally` hears nothing.
    pub fn between_counted(
        &self,
        a: &ObjectPoint,
        b: &ObjectPoint,
        tally: &mut impl cssm_formats::visibility::QueryTally,
    ) -> Option<f32> {
        match self {
            TwinVisibility::Baked(q) => q.visibility_between_counted(
                a.senders, a.position, a.normal, b.senders, b.position, b.normal, tally,
            ),
            TwinVisibility::Moving(q) => q.visibility_between(a, b),
        }
    }
}

/// What the CPU twins gather over: the visibility, the texels where their objects stand now
/// and the hierarchy fitted to them (the GPU's `posed.wgsl` and `MovingTexels`).
pub struct TwinScene<'q, 'a> {
    /// The visibility query.
    pub visibility: TwinVisibility<'q, 'a>,
    /// Every texel where its object stands now.
    pub texels: Cow<'q, [Texel]>,
    /// The hierarchy over them.
    pub hierarchy: Cow<'q, Hierarchy>,
    /// Every node's normals' spread and other-side texel over `texels` as they stand
    /// ([`super::transfer::node_spreads`]; the GPU's `HierarchyGpu::spreads`).
    pub spreads: Vec<GpuNodeSpread>,
}

impl<'q, 'a> TwinScene<'q, 'a> {
    /// The scene as baked: the file's texels and hierarchy, the CSSM query; `emitting`, per
    /// material, whether it emits ([`super::emitting_materials`]; the nodes' flags).
    pub fn baked(query: &'q VisibilityQuery<'a>, emitting: &[bool]) -> Self {
        let file = query.file();
        Self {
            visibility: TwinVisibility::Baked(query),
            texels: Cow::Borrowed(&file.texels),
            hierarchy: Cow::Borrowed(&file.hierarchy),
            spreads: node_spreads(&file.hierarchy, &file.texels, emitting),
        }
    }

    /// The objects of `query`'s file moved by `motions` (per object, its transform now times
    /// the inverse of its transform as loaded; `query`'s poses the same transforms): texels
    /// carried (`moving::posed_texels`), hierarchy refitted ([`Hierarchy::refit`]), the moving
    /// objects' query; `emitting` as [`Self::baked`] takes it.
    pub fn moving(query: &'q MovingQuery<'a>, motions: &[Affine3A], emitting: &[bool]) -> Self {
        let file = query.cssm().file();
        let texels = posed_texels(&file.texels, motions);
        let mut hierarchy = file.hierarchy.clone();
        hierarchy.refit(&texels);
        Self {
            visibility: TwinVisibility::Moving(query),
            spreads: node_spreads(&hierarchy, &texels, emitting),
            texels: Cow::Owned(texels),
            hierarchy: Cow::Owned(hierarchy),
        }
    }
}

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
    /// How many bounces ran.
    pub convergence: Convergence,
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
    scene: &TwinScene,
    nodes: &[GpuNode],
    radiance: &[Vec3],
    traversal: &Traversal,
    receiver: u32,
    p: Vec3,
    n: Vec3,
    rho: f32,
) -> (Vec3, u32) {
    let mut none = cssm_formats::visibility::QueryWork::default();
    gather_texel_counted(
        scene, nodes, radiance, traversal, receiver, p, n, rho, &mut none,
    )
}

/// [`gather_texel`], telling `tally` of every node the walk visits, every one it queries, and
/// every load of the CSSM query (issue 48's counters; `crate::work::passes`).
#[allow(clippy::too_many_arguments)]
pub fn gather_texel_counted(
    scene: &TwinScene,
    nodes: &[GpuNode],
    radiance: &[Vec3],
    traversal: &Traversal,
    receiver: u32,
    p: Vec3,
    n: Vec3,
    rho: f32,
    tally: &mut impl crate::work::GatherTally,
) -> (Vec3, u32) {
    gather_texel_split(
        scene,
        nodes,
        radiance,
        traversal,
        FarSplit::WHOLE,
        receiver,
        p,
        n,
        rho,
        tally,
    )
}

/// What the far field of `lightcuts`' texture-space final gather leaves to the pixels (the
/// GPU's `params.near_radius` and `params.emitters`, read with `params.gather` 2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FarSplit {
    /// The near field's reach (world units; 0: no split, the whole gather): every node
    /// reaching within it is refined, every leaf sends `1 - near_split_weight` of its light.
    pub near_radius: f32,
    /// The emitters' light left out too: every node holding an emitter texel refined
    /// ([`crate::gpu_types::NODE_EMITTER`]), every emitter leaf skipped; each pixel gathers
    /// them itself.
    pub emitters_apart: bool,
}

impl FarSplit {
    /// No split: the gather of a bounce.
    pub const WHOLE: Self = Self {
        near_radius: 0.0,
        emitters_apart: false,
    };

    /// Where the walk of receiver `(p, n)` (largest albedo channel `rho`) goes from node `s`
    /// of `scene`'s hierarchy, whose radiance the oracle reads as `l`, when it does not gather
    /// from it: the next node (its first child: refined by the oracle, §4.3, or reaching into
    /// the near field; past it: a skipped emitter leaf), or `None` to gather from it. The
    /// gather's, the far field's and the links' ([`gather_texel_split`],
    /// [`super::cpu_links::receiver_links`]).
    pub(super) fn step(
        self,
        scene: &TwinScene,
        s: usize,
        (p, n, rho): (Vec3, Vec3, f32),
        l: Vec3,
        traversal: &Traversal,
    ) -> Option<usize> {
        let node = &scene.hierarchy.nodes[s];
        let far_only = self.near_radius > 0.0;
        // The emitters' light, left to the pixels: refine down to it and skip it.
        if far_only && self.emitters_apart && scene.spreads[s].flags & NODE_EMITTER != 0 {
            return Some(if node.count > 1 {
                s + 1
            } else {
                node.skip as usize
            });
        }
        let bound = irradiance_bound(p, n, node, l) * (rho / PI);
        let near = (Vec3::from(node.center) - p).length() - node.radius < self.near_radius;
        (node.count > 1
            && (tone_mapped(bound, traversal.exposure) > traversal.threshold || (far_only && near)))
            .then_some(s + 1)
    }

    /// The share of a leaf at `y` of its light the far field takes at `p` (1 without a
    /// split): `1 - near_split_weight`.
    pub(super) fn leaf_share(self, y: Vec3, p: Vec3) -> f32 {
        if self.near_radius > 0.0 {
            1.0 - near_split_weight(y.distance(p), self.near_radius)
        } else {
            1.0
        }
    }
}

/// `gather.wgsl::gather_texel` with `params.gather` 2 (`split.near_radius` above 0): the far
/// field of texel `receiver`, every node reaching within `near_radius` refined and every leaf
/// sending `1 - near_split_weight` of its light, the emitters left out when `split` says so
/// (`lightcuts`' texture-space final gather); with [`FarSplit::WHOLE`],
/// [`gather_texel_counted`].
#[allow(clippy::too_many_arguments)]
pub fn gather_texel_split(
    scene: &TwinScene,
    nodes: &[GpuNode],
    radiance: &[Vec3],
    traversal: &Traversal,
    split: FarSplit,
    receiver: u32,
    p: Vec3,
    n: Vec3,
    rho: f32,
    tally: &mut impl crate::work::GatherTally,
) -> (Vec3, u32) {
    let texels = &scene.texels;
    let mut e = Vec3::ZERO;
    let mut cut = 0;
    let mut s = 0usize;
    let mut iteration = 0;
    while s < nodes.len() {
        tally.node(iteration, s as u32);
        iteration += 1;
        let node = &nodes[s];
        let l = radiance[s];
        if let Some(next) = split.step(scene, s, (p, n, rho), l, traversal) {
            s = next;
            continue;
        }
        cut += 1;
        let sender = node.representative;
        if sender != receiver && l.cmpgt(Vec3::ZERO).any() {
            let y = &texels[sender as usize];
            let spread = &scene.spreads[s];
            // A single texel's footprint is integrated in its near field.
            let (unoccluded, _) = if node.count == 1 {
                let (e, w) = irradiance_from_texel(p, n, y.pos(), y.nrm(), node.area, l);
                (e * split.leaf_share(y.pos(), p), w)
            } else {
                irradiance_from_cluster(p, n, y.pos(), node, spread, l)
            };
            if unoccluded.cmpgt(Vec3::ZERO).any() {
                // A cluster seen from the other side than its representative's: the
                // visibility of its texel facing the receiver (transfer.rs).
                let sender = visibility_sender(node, spread, texels, p);
                tally.query();
                let visibility = texel_visibility(scene, (receiver, p, n), sender, tally);
                e += unoccluded * visibility;
            }
        }
        s = node.skip as usize;
    }
    (e, cut)
}

/// The clear fraction between texel `receiver` (at `p`, normal `n`) and texel `sender`
/// where they stand: both ends' cube maps when the options ask (`QueryOptions::both_ends`),
/// each object's own and the other moving objects' CSMs (§3.3); 1 where neither answers. The
/// gather's and the links' (`gather.wgsl`, `links.wgsl`: `moving_visibility_between`).
pub(super) fn texel_visibility(
    scene: &TwinScene,
    (receiver, p, n): (u32, Vec3, Vec3),
    sender: u32,
    tally: &mut impl cssm_formats::visibility::QueryTally,
) -> f32 {
    let texels = &scene.texels;
    let y = &texels[sender as usize];
    scene
        .visibility
        .between_counted(
            &ObjectPoint {
                senders: &[(receiver, 1.0)],
                position: p,
                normal: n,
                object: texels[receiver as usize].object,
            },
            &ObjectPoint {
                senders: &[(sender, 1.0)],
                position: y.pos(),
                normal: y.nrm(),
                object: y.object,
            },
            tally,
        )
        .unwrap_or(1.0)
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
/// the tree, then the bounces of gather and pull `iterations` asks for (a count, or until
/// converged, tested on the root as the GPU does); every object where it was baked.
pub fn radiosity(
    query: &VisibilityQuery,
    direct: &[Vec3],
    albedo: &[Vec3],
    traversal: &Traversal,
    iterations: impl Into<BouncePlan>,
) -> CpuRadiosity {
    radiosity_over(
        &TwinScene::baked(query, &[]),
        direct,
        albedo,
        traversal,
        iterations,
    )
}

/// [`radiosity`] over `scene`, whose objects may have moved (§3.3).
pub fn radiosity_over(
    scene: &TwinScene,
    direct: &[Vec3],
    albedo: &[Vec3],
    traversal: &Traversal,
    iterations: impl Into<BouncePlan>,
) -> CpuRadiosity {
    let nodes = &scene.hierarchy.nodes;
    iterate(
        scene,
        direct,
        albedo,
        iterations.into(),
        |leaf_nodes, radiance| {
            leaf_nodes
                .par_iter()
                .map(|&(t, _)| {
                    let texel = &scene.texels[t as usize];
                    gather_texel(
                        scene,
                        nodes,
                        radiance,
                        traversal,
                        t,
                        texel.pos(),
                        texel.nrm(),
                        albedo[t as usize].max_element(),
                    )
                })
                .collect()
        },
    )
}

/// Every leaf node of `nodes` in leaf order: (its texel, its node index).
pub(super) fn leaf_nodes(scene: &TwinScene) -> Vec<(u32, usize)> {
    let leaf_texels = &scene.hierarchy.leaf_texels;
    scene
        .hierarchy
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| n.count == 1)
        .map(|(i, n)| (leaf_texels[n.first as usize], i))
        .collect()
}

/// The iteration of [`radiosity_over`] and [`radiosity_with_links`]: the direct light pulled,
/// then as many bounces as `plan` asks, each `bounce` giving every leaf's (leaf order)
/// irradiance and cut size from the node radiance before it.
pub(super) fn iterate(
    scene: &TwinScene,
    direct: &[Vec3],
    albedo: &[Vec3],
    plan: BouncePlan,
    bounce: impl Fn(&[(u32, usize)], &[Vec3]) -> Vec<(Vec3, u32)>,
) -> CpuRadiosity {
    let nodes = &scene.hierarchy.nodes;
    let leaf_nodes = leaf_nodes(scene);
    let mut radiance = vec![Vec3::ZERO; nodes.len()];
    for &(t, i) in &leaf_nodes {
        radiance[i] = direct[t as usize];
    }
    pull(nodes, &mut radiance);
    let mut irradiance = vec![Vec3::ZERO; scene.texels.len()];
    let mut gathered_total = 0;
    // The test reads the root, node 0 (none in a hierarchy without texels).
    let root = |radiance: &[Vec3]| radiance.first().copied().unwrap_or_default();
    let convergence = run_plan(plan, root(&radiance), |_| {
        let gathered = bounce(&leaf_nodes, &radiance);
        gathered_total = gathered.iter().map(|g| u64::from(g.1)).sum();
        let mut next = radiance.clone();
        for (&(t, i), (e, _)) in leaf_nodes.iter().zip(gathered) {
            irradiance[t as usize] = e;
            next[i] = direct[t as usize] + albedo[t as usize] / PI * e;
        }
        pull(nodes, &mut next);
        radiance = next;
        root(&radiance)
    });
    CpuRadiosity {
        node_radiance: radiance,
        texel_irradiance: irradiance,
        gathered: gathered_total,
        convergence,
    }
}

/// The far field of every texel (texel order) from the node radiance `radiance`: what
/// `lightcuts`' far-field pass (`gather.wgsl` with `params.gather` 2) writes, each texel's
/// [`gather_texel_split`] at `split`, reflecting `albedo` in the oracle.
pub fn far_field(
    scene: &TwinScene,
    radiance: &[Vec3],
    albedo: &[Vec3],
    traversal: &Traversal,
    split: FarSplit,
) -> Vec<Vec3> {
    let nodes = &scene.hierarchy.nodes;
    let mut far = vec![Vec3::ZERO; scene.texels.len()];
    let leaves: Vec<u32> = nodes
        .iter()
        .filter(|n| n.count == 1)
        .map(|n| scene.hierarchy.leaf_texels[n.first as usize])
        .collect();
    let gathered: Vec<(u32, Vec3)> = leaves
        .par_iter()
        .map(|&t| {
            let texel = &scene.texels[t as usize];
            let mut none = cssm_formats::visibility::QueryWork::default();
            let (e, _) = gather_texel_split(
                scene,
                nodes,
                radiance,
                traversal,
                split,
                t,
                texel.pos(),
                texel.nrm(),
                albedo[t as usize].max_element(),
                &mut none,
            );
            (t, e)
        })
        .collect();
    for (t, e) in gathered {
        far[t as usize] = e;
    }
    far
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
