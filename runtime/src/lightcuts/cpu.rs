//! CPU twin of `final_gather.wgsl`: the same traversal, oracle and transfer per receiver
//! point, with the CPU visibility query, over a [`TwinScene`] (whose rigid objects may have
//! moved, §3.3: senders where their objects stand now).

use cssm_formats::moving::ObjectPoint;
use glam::{Vec2, Vec3};

use crate::{
    gpu_types::GpuMaterial,
    radiosity::cpu::TwinScene,
    radiosity::transfer::{
        brdf_bound, in_near_field, irradiance_bound, irradiance_from, irradiance_from_cluster,
        irradiance_from_footprint, jitter_in_disk, jitter_leaf, phong_lobe, tone_mapped,
        visibility_sender,
    },
};

/// A receiver point of the final gather, as the G-buffer holds it.
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// World position.
    pub position: Vec3,
    /// Unit normal turned towards the eye.
    pub normal: Vec3,
    /// Unit direction towards the eye.
    pub view: Vec3,
    /// Diffuse albedo (Kd times the texture).
    pub albedo: Vec3,
    /// Atlas coordinates, texels.
    pub atlas: Vec2,
}

/// What [`gather_planes`] gathers at a receiver: the planes `final_gather.wgsl` writes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Gathered {
    /// The indirect irradiance.
    pub irradiance: Vec3,
    /// The indirect irradiance weighted by the receiver's normalised Phong lobe towards the eye
    /// ([`phong_lobe`]).
    pub lobe_weighted: Vec3,
    /// Nodes gathered from.
    pub cut: u32,
}

/// `final_gather.wgsl` then `common/resolve.wgsl`: indirect radiance leaving the receiver
/// towards the eye (`albedo / pi * irradiance + ks * lobe_weighted` of [`gather_planes`]) and
/// the cut size.
#[allow(clippy::too_many_arguments)]
pub fn gather_pixel(
    scene: &TwinScene,
    radiance: &[Vec3],
    threshold: f32,
    exposure: f32,
    jitter: Option<(u32, u32)>,
    r: &Receiver,
    material: &GpuMaterial,
) -> (Vec3, u32) {
    let g = gather_planes(scene, radiance, threshold, exposure, jitter, r, material);
    let out = r.albedo / std::f32::consts::PI * g.irradiance + Vec3::from(material.ks) * g.lobe_weighted;
    (out, g.cut)
}

/// `final_gather.wgsl::gather_pixel`: the indirect light arriving at the receiver as the two
/// planes the kernel writes, and the cut size, gathering from the node radiance `radiance`
/// (`jitter`: the seed when senders are random texels of their node, and the receiver's id),
/// over `scene`'s texels and hierarchy.
#[allow(clippy::too_many_arguments)]
pub fn gather_planes(
    scene: &TwinScene,
    radiance: &[Vec3],
    threshold: f32,
    exposure: f32,
    jitter: Option<(u32, u32)>,
    r: &Receiver,
    material: &GpuMaterial,
) -> Gathered {
    let (texels, nodes) = (&scene.texels, &scene.hierarchy.nodes);
    let leaf_texels = &scene.hierarchy.leaf_texels;
    let (ks, ns) = (Vec3::from(material.ks), material.ns);
    let (p, n, v) = (r.position, r.normal, r.view);
    // The receiver's own texels, found once for all its senders (as the kernel does), and the
    // object they lie on (a point without texels: the static part, answered unshadowed).
    let senders = scene.visibility.cssm().sender_texels_at(r.atlas);
    let object = senders
        .first()
        .filter(|s| s.1 > 0.0)
        .map_or(0, |s| texels[s.0 as usize].object);
    let mut gathered = Gathered::default();
    let mut s = 0usize;
    while s < nodes.len() {
        let node = &nodes[s];
        let l = radiance[s];
        if node.count > 1 {
            let to_center = Vec3::from(node.center) - p;
            let bound = irradiance_bound(p, n, node, l)
                * brdf_bound(n, v, r.albedo, ks, ns, to_center, node.radius);
            if tone_mapped(bound, exposure) > threshold {
                s += 1;
                continue;
            }
        }
        gathered.cut += 1;
        let sender = match jitter {
            Some((seed, receiver)) if node.count > 1 => {
                leaf_texels[jitter_leaf(seed, receiver, s as u32, node) as usize]
            }
            _ => node.representative,
        };
        if l.cmpgt(Vec3::ZERO).any() {
            let y = &texels[sender as usize];
            let near = node.count == 1 && in_near_field(p, y.pos(), node.area);
            let position = match jitter {
                Some((seed, receiver)) if !near => {
                    jitter_in_disk(seed, receiver, s as u32, y.pos(), y.nrm(), y.area)
                }
                _ => y.pos(),
            };
            // The texel's footprint integrated exactly: what jittering would average to.
            let (e, w) = if near {
                irradiance_from_footprint(p, n, position, y.nrm(), node.area, l)
            } else if node.count > 1 {
                irradiance_from_cluster(p, n, position, node, &scene.spreads[s], l)
            } else {
                irradiance_from(p, n, position, Vec3::from(node.normal), node.area, l)
            };
            if e.cmpgt(Vec3::ZERO).any() {
                // Unjittered, a cluster seen from the other side than its representative's:
                // the visibility of its texel facing the receiver (transfer.rs).
                let (sender, y, position) = if jitter.is_none() {
                    let sender = visibility_sender(node, &scene.spreads[s], texels, p);
                    let y = &texels[sender as usize];
                    (sender, y, y.pos())
                } else {
                    (sender, y, position)
                };
                // The pixel's texels and the sender's (both ends, when the options ask), each
                // object's own and the other moving objects' CSMs (§3.3).
                let visibility = scene
                    .visibility
                    .between(
                        &ObjectPoint {
                            senders: &senders,
                            position: p,
                            normal: n,
                            object,
                        },
                        &ObjectPoint {
                            senders: &[(sender, 1.0)],
                            position,
                            normal: y.nrm(),
                            object: y.object,
                        },
                    )
                    .unwrap_or(1.0);
                gathered.irradiance += e * visibility;
                gathered.lobe_weighted += phong_lobe(n, v, w, ns) * e * visibility;
            }
        }
        s = node.skip as usize;
    }
    gathered
}
