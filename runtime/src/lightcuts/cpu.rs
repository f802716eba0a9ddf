//! CPU twin of `final_gather.wgsl`: the same traversal, oracle and transfer per receiver
//! point, with the CPU visibility query, over a [`TwinScene`] (whose rigid objects may have
//! moved, §3.3: senders where their objects stand now).

use cssm_formats::moving::ObjectPoint;
use glam::{Vec2, Vec3};

use crate::{
    gpu_types::GpuMaterial,
    radiosity::cpu::TwinScene,
    radiosity::transfer::{
        brdf, brdf_bound, in_near_field, irradiance_bound, irradiance_from,
        irradiance_from_footprint, jitter_in_disk, jitter_leaf, tone_mapped,
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

/// `final_gather.wgsl::gather_pixel`: indirect radiance leaving the receiver towards the eye
/// and the cut size, gathering from the node radiance `radiance` (`jitter`: the seed when
/// senders are random texels of their node, and the receiver's id), over `scene`'s texels and
/// hierarchy.
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
    let mut out = Vec3::ZERO;
    let mut cut = 0;
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
        cut += 1;
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
            } else {
                irradiance_from(p, n, position, Vec3::from(node.normal), node.area, l)
            };
            if e.cmpgt(Vec3::ZERO).any() {
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
                out += brdf(n, v, w, r.albedo, ks, ns) * e * visibility;
            }
        }
        s = node.skip as usize;
    }
    (out, cut)
}
