//! CPU twin of the cached links (`radiosity/links.rs`, `links.wgsl`, `product.wgsl`; issue 49,
//! item 1): every receiver leaf's cut as the gather walks it, stored with its transfer, so
//! that a bounce, or `lightcuts`' far field, is a sparse matrix-vector product.

use glam::Vec3;
use rayon::prelude::*;

use super::cpu::{
    CpuRadiosity, FarSplit, Traversal, TwinScene, iterate, leaf_nodes, texel_visibility,
};
use super::transfer::{
    irradiance_bound, irradiance_from_cluster, irradiance_from_texel, visibility_sender,
};
use crate::common::converge::BouncePlan;

const PI: f32 = std::f32::consts::PI;

/// One cached link: a node of a receiver's cut and its transfer (`links.wgsl`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Link {
    /// The node.
    pub node: u32,
    /// Its transfer: the node's radiance times it is the receiver's irradiance from it.
    pub transfer: f32,
    /// Its bound of unit radiance ([`super::transfer::irradiance_bound`]; 0 for a leaf),
    /// which the staleness test multiplies by its radiance.
    pub bound: f32,
}

/// The radiosity's cached links (`links.wgsl`, issue 49 item 1): every receiver leaf's cut as
/// the gather walks it, each node of it with its transfer of unit radiance times the
/// visibility, so that a bounce is a sparse matrix-vector product ([`link_product`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Links {
    /// Per leaf in leaf order, its cut.
    pub cuts: Vec<Vec<Link>>,
    /// Per leaf, its slot's capacity (`links::slot_capacity` of its count at the build).
    pub capacity: Vec<u32>,
}

impl Links {
    /// How many links.
    pub fn count(&self) -> u64 {
        self.cuts.iter().map(|c| c.len() as u64).sum()
    }

    /// Bytes on the GPU: 12 a link's slot (node, transfer, bound), 8 a leaf's table entry.
    pub fn bytes(&self) -> u64 {
        let slots: u64 = self.capacity.iter().map(|&c| u64::from(c)).sum();
        12 * slots + 8 * self.cuts.len() as u64 + 12
    }
}

/// `links.wgsl::walk_links` for texel `receiver` (position `p`, normal `n`, largest albedo
/// channel `rho`): its cut under the oracle reading `cut_radiance`, every node whose
/// unoccluded transfer is above zero with that transfer for unit radiance times the visibility
/// (the gather's, [`super::cpu::gather_texel`]); with a `split` other than
/// [`FarSplit::WHOLE`], the far field's cut ([`super::cpu::gather_texel_split`]: the nodes
/// reaching into the near field and those holding an emitter refined, the emitter leaves left
/// out, each leaf's transfer weighted out of the near field).
#[allow(clippy::too_many_arguments)]
pub fn receiver_links(
    scene: &TwinScene,
    cut_radiance: &[Vec3],
    traversal: &Traversal,
    split: FarSplit,
    receiver: u32,
    p: Vec3,
    n: Vec3,
    rho: f32,
) -> Vec<Link> {
    let (nodes, texels) = (&scene.hierarchy.nodes, &scene.texels);
    let mut links = Vec::new();
    let mut s = 0usize;
    while s < nodes.len() {
        let node = &nodes[s];
        if let Some(next) = split.step(scene, s, (p, n, rho), cut_radiance[s], traversal) {
            s = next;
            continue;
        }
        let sender = node.representative;
        if sender != receiver {
            let y = &texels[sender as usize];
            let unoccluded = if node.count == 1 {
                let share = split.leaf_share(y.pos(), p);
                irradiance_from_texel(p, n, y.pos(), y.nrm(), node.area, Vec3::ONE).0 * share
            } else {
                irradiance_from_cluster(p, n, y.pos(), node, &scene.spreads[s], Vec3::ONE).0
            }
            .x;
            if unoccluded > 0.0 {
                let sender = visibility_sender(node, &scene.spreads[s], texels, p);
                let mut none = cssm_formats::visibility::QueryWork::default();
                let visibility = texel_visibility(scene, (receiver, p, n), sender, &mut none);
                let bound = if node.count > 1 {
                    irradiance_bound(p, n, node, Vec3::ONE).x
                } else {
                    0.0
                };
                links.push(Link {
                    node: s as u32,
                    transfer: unoccluded * visibility,
                    bound,
                });
            }
        }
        s = node.skip as usize;
    }
    links
}

/// Every leaf's cut for the node radiance `cut_radiance` (texels reflecting `albedo` in the
/// oracle) where `which` says (leaf order), in parallel: `receiver_links` of each.
fn cuts_of(
    scene: &TwinScene,
    cut_radiance: &[Vec3],
    albedo: &[Vec3],
    (traversal, split): (&Traversal, FarSplit),
    which: impl Fn(usize) -> bool + Sync,
) -> Vec<Option<Vec<Link>>> {
    leaf_nodes(scene)
        .par_iter()
        .enumerate()
        .map(|(leaf, &(t, _))| {
            which(leaf).then(|| {
                let texel = &scene.texels[t as usize];
                let rho = albedo[t as usize].max_element();
                receiver_links(
                    scene,
                    cut_radiance,
                    traversal,
                    split,
                    t,
                    texel.pos(),
                    texel.nrm(),
                    rho,
                )
            })
        })
        .collect()
}

/// Every leaf's links (leaf order) for the node radiance `cut_radiance`, texels reflecting
/// `albedo` in the oracle, the cuts of `split` ([`FarSplit::WHOLE`]: the radiosity's; else
/// `lightcuts`' far field): what `radiosity/links.rs` builds on the GPU.
pub fn build_links(
    scene: &TwinScene,
    cut_radiance: &[Vec3],
    albedo: &[Vec3],
    (traversal, split): (&Traversal, FarSplit),
) -> Links {
    let cuts: Vec<Vec<Link>> = cuts_of(scene, cut_radiance, albedo, (traversal, split), |_| true)
        .into_iter()
        .flatten()
        .collect();
    let capacity = cuts
        .iter()
        .map(|c| super::links::slot_capacity(c.len() as u32))
        .collect();
    Links { cuts, capacity }
}

/// `product.wgsl` for leaf `leaf` (leaf order): its irradiance from the node radiance
/// `radiance` over its links.
pub fn link_product(links: &Links, leaf: usize, radiance: &[Vec3]) -> Vec3 {
    links.cuts[leaf]
        .iter()
        .map(|link| radiance[link.node as usize] * link.transfer)
        .sum()
}

/// `product.wgsl`'s staleness test for leaf `leaf` (largest albedo channel `rho`): whether
/// the oracle would refine a node of its cut under the node radiance `radiance`, by more than
/// [`super::links::STALE_MARGIN`].
pub fn cut_is_stale(
    links: &Links,
    leaf: usize,
    radiance: &[Vec3],
    rho: f32,
    traversal: &Traversal,
) -> bool {
    let limit = super::links::STALE_MARGIN * traversal.threshold.powf(2.2)
        / (traversal.exposure * rho / PI).max(1e-30);
    rho > 0.0
        && links.cuts[leaf]
            .iter()
            .any(|link| radiance[link.node as usize].max_element() * link.bound > limit)
}

/// The iteration of [`super::cpu::radiosity_over`] with every bounce the product of `links` (what the GPU
/// runs once its links are built; the cut sizes are the link counts), and per leaf whether a
/// bounce found its cut stale ([`cut_is_stale`] on each bounce's incoming radiance).
pub fn radiosity_with_links(
    scene: &TwinScene,
    links: &Links,
    (direct, albedo): (&[Vec3], &[Vec3]),
    traversal: &Traversal,
    iterations: impl Into<BouncePlan>,
) -> (CpuRadiosity, Vec<bool>) {
    let stale = std::sync::Mutex::new(vec![false; links.cuts.len()]);
    let solved = iterate(
        scene,
        direct,
        albedo,
        iterations.into(),
        |leaf_nodes, radiance| {
            let mut stale = stale.lock().unwrap_or_else(|e| e.into_inner());
            leaf_nodes
                .iter()
                .enumerate()
                .map(|(leaf, &(t, _))| {
                    let rho = albedo[t as usize].max_element();
                    stale[leaf] |= cut_is_stale(links, leaf, radiance, rho, traversal);
                    (
                        link_product(links, leaf, radiance),
                        links.cuts[leaf].len() as u32,
                    )
                })
                .collect()
        },
    );
    (
        solved,
        stale.into_inner().unwrap_or_else(|e| e.into_inner()),
    )
}

/// `links.wgsl` re-cutting: every leaf `stale` flags re-cut for the node radiance
/// `cut_radiance` (the cuts of `split`, as [`build_links`]), in place where the new cut fits
/// its slot; the rest keep their old cut. Returns how many overflowed (the GPU then builds
/// everything again).
pub fn recut_links(
    scene: &TwinScene,
    links: &mut Links,
    stale: &[bool],
    cut_radiance: &[Vec3],
    (albedo, traversal, split): (&[Vec3], &Traversal, FarSplit),
) -> u32 {
    let cuts = cuts_of(scene, cut_radiance, albedo, (traversal, split), |leaf| {
        stale[leaf]
    });
    let mut overflow = 0;
    for (leaf, cut) in cuts.into_iter().enumerate() {
        match cut {
            Some(cut) if cut.len() as u32 <= links.capacity[leaf] => links.cuts[leaf] = cut,
            Some(_) => overflow += 1,
            None => {}
        }
    }
    overflow
}

/// `product.wgsl` over the far field's links (`lightcuts`' far-field product): every texel's
/// far-field irradiance (texel order) from the node radiance `radiance`, and per leaf whether
/// its cut is stale under it ([`cut_is_stale`]).
pub fn far_field_with_links(
    scene: &TwinScene,
    links: &Links,
    radiance: &[Vec3],
    albedo: &[Vec3],
    traversal: &Traversal,
) -> (Vec<Vec3>, Vec<bool>) {
    let mut far = vec![Vec3::ZERO; scene.texels.len()];
    let stale = leaf_nodes(scene)
        .iter()
        .enumerate()
        .map(|(leaf, &(t, _))| {
            far[t as usize] = link_product(links, leaf, radiance);
            let rho = albedo[t as usize].max_element();
            cut_is_stale(links, leaf, radiance, rho, traversal)
        })
        .collect();
    (far, stale)
}
