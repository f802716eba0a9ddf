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

/// The G-buffer of `view` over `scene` as the CPU twins see it, row-major: at each pixel the
/// receiver its primary ray through the pixel centre meets (position, the geometric normal
/// tilted by the material's normal map and turned towards the eye, Kd as albedo, atlas
/// coordinates from `file`) and its triangle; `None` where it meets nothing.
///
/// # Errors
/// A texture of the scene that does not load.
pub fn receivers(
    scene: &cssm_formats::Scene,
    file: &cssm_formats::CssmFile,
    view: &crate::common::camera::View,
) -> Result<Vec<Option<(Receiver, u32)>>, crate::RuntimeError> {
    use crate::direct::cpu;
    let bvh = cssm_raycast::SceneBvh::new(scene);
    let (materials, textures) = crate::load::cpu_materials(scene)?;
    let (w, h) = (view.width, view.height);
    Ok((0..w * h)
        .map(|i| {
            let dir = view.primary_ray(i % w, i / w);
            let (t, triangle) = bvh.closest_hit(view.eye, dir, 0.0, f32::INFINITY)?;
            let p = view.eye + dir * t;
            let [a, b, c] = scene.triangle(triangle as usize);
            let n = cpu::facing_normal(scene, triangle, view.eye - p);
            let material = &materials[scene.triangle_materials[triangle as usize] as usize];
            let n = cpu::shading_normal(scene, material, &textures, triangle, p, n);
            let bary = cpu::barycentric(p, a, b, c);
            let uv = file.triangle_uvs[triangle as usize];
            let atlas = Vec2::from(uv[0]) * bary[0]
                + Vec2::from(uv[1]) * bary[1]
                + Vec2::from(uv[2]) * bary[2];
            let m = &scene.materials[scene.triangle_materials[triangle as usize] as usize];
            Some((
                Receiver {
                    position: p,
                    normal: n,
                    view: -dir,
                    albedo: Vec3::from(m.kd),
                    atlas,
                },
                triangle,
            ))
        })
        .collect())
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
    let out =
        r.albedo / std::f32::consts::PI * g.irradiance + Vec3::from(material.ks) * g.lobe_weighted;
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
    let mut none = cssm_formats::visibility::QueryWork::default();
    gather_planes_counted(
        scene, radiance, threshold, exposure, jitter, r, material, &mut none,
    )
}

/// [`gather_planes`], telling `tally` of every node the walk visits, every one it queries, and
/// every load of the CSSM query (issue 48's counters; `crate::work::passes`).
#[allow(clippy::too_many_arguments)]
pub fn gather_planes_counted(
    scene: &TwinScene,
    radiance: &[Vec3],
    threshold: f32,
    exposure: f32,
    jitter: Option<(u32, u32)>,
    r: &Receiver,
    material: &GpuMaterial,
    tally: &mut impl crate::work::GatherTally,
) -> Gathered {
    let (texels, nodes) = (&scene.texels, &scene.hierarchy.nodes);
    let leaf_texels = &scene.hierarchy.leaf_texels;
    let (ks, ns) = (Vec3::from(material.ks), material.ns);
    let (p, n, v) = (r.position, r.normal, r.view);
    // The receiver's own texels, found once for all its senders (as the kernel does: its four
    // sender-filter slots, `CssmSenders`), and the object they lie on (the first slot's; a
    // point without texels: the static part, answered unshadowed).
    let senders: Vec<(u32, f32)> = scene
        .visibility
        .cssm()
        .sender_slots_at(r.atlas, Default::default(), tally)
        .map(Vec::from)
        .unwrap_or_default();
    let object = senders
        .first()
        .filter(|s| s.1 > 0.0)
        .map_or(0, |s| texels[s.0 as usize].object);
    let mut gathered = Gathered::default();
    let mut s = 0usize;
    let mut iteration = 0;
    while s < nodes.len() {
        tally.node(iteration, s as u32);
        iteration += 1;
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
                tally.query();
                let visibility = scene
                    .visibility
                    .between_counted(
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
                        tally,
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
