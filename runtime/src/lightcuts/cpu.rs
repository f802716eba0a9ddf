//! CPU twin of `final_gather.wgsl`: the same traversal, oracle and transfer per receiver
//! point, with the CPU visibility query, over a [`TwinScene`] (whose rigid objects may have
//! moved, §3.3: senders where their objects stand now).

use cssm_formats::moving::ObjectPoint;
use glam::{Vec2, Vec3};

use crate::{
    gpu_types::{GpuMaterial, NODE_ALL_EMITTERS, NODE_EMITTER},
    lightmap::{Filter, lookup},
    radiosity::cpu::TwinScene,
    radiosity::transfer::{
        brdf_bound, in_near_field, irradiance_bound, irradiance_from, irradiance_from_cluster,
        irradiance_from_footprint, irradiance_from_texel, jitter_in_disk, jitter_leaf,
        near_split_weight, phong_lobe, tone_mapped, visibility_sender,
    },
};

/// How the twin gathers a pixel: the kernel's `grid.mode` ([`super::GatherForm`]).
#[derive(Clone, Copy, Debug)]
pub enum TwinGather<'a> {
    /// The walk over the whole hierarchy.
    Walk,
    /// The far field's bicubic lookup plus the near field within `near_radius`; glossy pixels
    /// walk for their lobe.
    Atlas {
        /// Per texel (texel order), the far field ([`crate::radiosity::cpu::far_field`]).
        far: &'a [Vec3],
        /// The near field's reach, world units ([`super::near_radius`]).
        near_radius: f32,
        /// The texels' near lists, or none (every near field walks the hierarchy).
        lists: Option<&'a super::near::NearLists>,
        /// The emitters' light gathered by the pixel, left out of `far` and the near field
        /// ([`crate::radiosity::cpu::FarSplit::emitters_apart`]).
        emitters_apart: bool,
    },
}

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
    form: TwinGather,
    threshold: f32,
    exposure: f32,
    jitter: Option<(u32, u32)>,
    r: &Receiver,
    material: &GpuMaterial,
) -> (Vec3, u32) {
    let g = gather_planes(
        scene, radiance, form, threshold, exposure, jitter, r, material,
    );
    let out =
        r.albedo / std::f32::consts::PI * g.irradiance + Vec3::from(material.ks) * g.lobe_weighted;
    (out, g.cut)
}

/// `final_gather.wgsl`'s `main` for one pixel: the indirect light arriving at the receiver as
/// the two planes the kernel writes, and the cut size, gathering as `form` says from the node
/// radiance `radiance` (`jitter`: the seed when senders are random texels of their node, and
/// the receiver's id), over `scene`'s texels and hierarchy.
#[allow(clippy::too_many_arguments)]
pub fn gather_planes(
    scene: &TwinScene,
    radiance: &[Vec3],
    form: TwinGather,
    threshold: f32,
    exposure: f32,
    jitter: Option<(u32, u32)>,
    r: &Receiver,
    material: &GpuMaterial,
) -> Gathered {
    let mut none = cssm_formats::visibility::QueryWork::default();
    gather_planes_counted(
        scene, radiance, form, threshold, exposure, jitter, r, material, &mut none,
    )
}

/// [`gather_planes`], telling `tally` of every node the walk visits, every one it queries, and
/// every load of the CSSM query (issue 48's counters; `crate::work::passes`).
#[allow(clippy::too_many_arguments)]
pub fn gather_planes_counted(
    scene: &TwinScene,
    radiance: &[Vec3],
    form: TwinGather,
    threshold: f32,
    exposure: f32,
    jitter: Option<(u32, u32)>,
    r: &Receiver,
    material: &GpuMaterial,
    tally: &mut impl crate::work::GatherTally,
) -> Gathered {
    let texels = &scene.texels;
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
    let end = PixelEnd {
        senders: &senders,
        object,
    };
    let walk = |oracle_albedo: Vec3, emitters_only: bool, tally: &mut _| {
        let oracle = Oracle {
            threshold,
            exposure,
            albedo: oracle_albedo,
            emitters_only,
        };
        gather_walk(scene, radiance, &oracle, jitter, r, material, &end, tally)
    };
    match form {
        TwinGather::Walk => walk(r.albedo, false, tally),
        TwinGather::Atlas {
            far,
            near_radius,
            lists,
            emitters_apart,
        } => {
            let mut gathered = if Vec3::from(material.ks).cmpgt(Vec3::ZERO).any() {
                walk(Vec3::ZERO, false, tally)
            } else {
                Gathered::default()
            };
            let atlas = lookup(scene.visibility.cssm(), far, r.atlas, Filter::Bicubic);
            let near = near_field(
                scene,
                radiance,
                (near_radius, lists, emitters_apart),
                r,
                &end,
                tally,
            );
            gathered.irradiance = atlas + near;
            if emitters_apart {
                let emitted = walk(r.albedo, true, tally);
                gathered.irradiance += emitted.irradiance;
                gathered.cut += emitted.cut;
            }
            gathered
        }
    }
}

/// The pixel's end of every query: its sender-filter slots and the object they lie on.
struct PixelEnd<'s> {
    senders: &'s [(u32, f32)],
    object: u32,
}

impl PixelEnd<'_> {
    /// The clear fraction between the pixel at `r` and `sender` (at `position`; its object's
    /// and both ends' maps, §3.3), 1 where no texel answers.
    fn visibility(
        &self,
        scene: &TwinScene,
        r: &Receiver,
        sender: u32,
        position: Vec3,
        tally: &mut impl crate::work::GatherTally,
    ) -> f32 {
        let y = &scene.texels[sender as usize];
        tally.query();
        scene
            .visibility
            .between_counted(
                &ObjectPoint {
                    senders: self.senders,
                    position: r.position,
                    normal: r.normal,
                    object: self.object,
                },
                &ObjectPoint {
                    senders: &[(sender, 1.0)],
                    position,
                    normal: y.nrm(),
                    object: y.object,
                },
                tally,
            )
            .unwrap_or(1.0)
    }
}

/// The near field's loop iterations, as [`crate::work::GatherTally::node`] hears them: after
/// any the walk could reach, so that the warp replay issues them together.
const NEAR_LOOP: u32 = 1 << 24;

/// The emitters' walk's iterations, after the near field's.
const EMITTER_LOOP: u32 = 2 << 24;

/// `final_gather.wgsl::near_field`: the leaves within `radius` of the receiver, each weighted
/// by [`near_split_weight`], from its texel's list when `lists` has one for it, else walked;
/// the emitters left out when the pixel gathers them apart.
fn near_field(
    scene: &TwinScene,
    radiance: &[Vec3],
    (radius, lists, emitters_apart): (f32, Option<&super::near::NearLists>, bool),
    r: &Receiver,
    end: &PixelEnd,
    tally: &mut impl crate::work::GatherTally,
) -> Vec3 {
    let nodes = &scene.hierarchy.nodes;
    let (p, n) = (r.position, r.normal);
    let mut e = Vec3::ZERO;
    let leaf = |s: usize, tally: &mut _| {
        let node = &nodes[s];
        if emitters_apart && scene.spreads[s].flags & NODE_EMITTER != 0 {
            return Vec3::ZERO;
        }
        let l = radiance[s];
        let y = &scene.texels[node.representative as usize];
        let w = near_split_weight(y.pos().distance(p), radius);
        if w <= 0.0 || !l.cmpgt(Vec3::ZERO).any() {
            return Vec3::ZERO;
        }
        let (unoccluded, _) = irradiance_from_texel(p, n, y.pos(), y.nrm(), node.area, l);
        let unoccluded = w * unoccluded;
        if !unoccluded.cmpgt(Vec3::ZERO).any() {
            return Vec3::ZERO;
        }
        unoccluded * end.visibility(scene, r, node.representative, y.pos(), tally)
    };
    let list = lists
        .zip(end.senders.first())
        .and_then(|(lists, &(t, weight))| {
            let texel = scene.texels.get(t as usize).filter(|_| weight > 0.0)?;
            lists.list(t, p, texel.pos(), texel.nrm())
        });
    if let Some(list) = list {
        for (iteration, &s) in (0..).zip(list) {
            tally.node(NEAR_LOOP + iteration, s);
            e += leaf(s as usize, tally);
        }
        return e;
    }
    let mut iteration = 0;
    super::near::walk_within(nodes, p, radius, |s, is_leaf| {
        // The kernel's second loop, after a glossy pixel's walk: its own iterations.
        tally.node(NEAR_LOOP + iteration, s as u32);
        iteration += 1;
        if is_leaf {
            e += leaf(s, tally);
        }
    });
    e
}

/// The walk's oracle: its threshold and exposure, the diffuse albedo it bounds the BRDF
/// with beside the material's lobe (zero: the lobe's alone), and whether the walk takes the
/// emitters' light alone (nodes holding no emitter skipped, nodes mixing them refined).
struct Oracle {
    threshold: f32,
    exposure: f32,
    albedo: Vec3,
    emitters_only: bool,
}

/// `final_gather.wgsl::gather_pixel`: the walk over the whole hierarchy.
#[allow(clippy::too_many_arguments)]
fn gather_walk(
    scene: &TwinScene,
    radiance: &[Vec3],
    oracle: &Oracle,
    jitter: Option<(u32, u32)>,
    r: &Receiver,
    material: &GpuMaterial,
    end: &PixelEnd,
    tally: &mut impl crate::work::GatherTally,
) -> Gathered {
    let (texels, nodes) = (&scene.texels, &scene.hierarchy.nodes);
    let leaf_texels = &scene.hierarchy.leaf_texels;
    let (ks, ns) = (Vec3::from(material.ks), material.ns);
    let (p, n, v) = (r.position, r.normal, r.view);
    let mut gathered = Gathered::default();
    let mut s = 0usize;
    // The kernel's third loop, after the near field's: its own iterations.
    let mut iteration = if oracle.emitters_only {
        EMITTER_LOOP
    } else {
        0
    };
    while s < nodes.len() {
        tally.node(iteration, s as u32);
        iteration += 1;
        let node = &nodes[s];
        let flags = scene.spreads[s].flags;
        if oracle.emitters_only && flags & NODE_EMITTER == 0 {
            s = node.skip as usize;
            continue;
        }
        let l = radiance[s];
        if oracle.emitters_only && node.count > 1 && flags & NODE_ALL_EMITTERS == 0 {
            s += 1;
            continue;
        }
        if node.count > 1 {
            let to_center = Vec3::from(node.center) - p;
            let bound = irradiance_bound(p, n, node, l)
                * brdf_bound(n, v, oracle.albedo, ks, ns, to_center, node.radius);
            if tone_mapped(bound, oracle.exposure) > oracle.threshold {
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
                let (sender, position) = if jitter.is_none() {
                    let sender = visibility_sender(node, &scene.spreads[s], texels, p);
                    (sender, texels[sender as usize].pos())
                } else {
                    (sender, position)
                };
                // The pixel's texels and the sender's (both ends, when the options ask), each
                // object's own and the other moving objects' CSMs (§3.3).
                let visibility = end.visibility(scene, r, sender, position, tally);
                gathered.irradiance += e * visibility;
                gathered.lobe_weighted += phong_lobe(n, v, w, ns) * e * visibility;
            }
        }
        s = node.skip as usize;
    }
    gathered
}
