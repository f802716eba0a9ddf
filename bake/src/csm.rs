//! Coherent shadow maps of one rigid object (§3.1, after Ritschel et al. 2007, the paper's
//! \[17\]): orthographic depth maps of the object from `k x k` directions over the sphere, in a
//! coherent order, each pixel storing any depth between the ray's first and second hit (dual
//! depth), compressed into the same piecewise-constant runs and random-access layout as a
//! CSSM. A CSM answers whether the segment from a point outside the object's convex hull to
//! another is blocked by the object, without casting a ray: §3.3 tests every *other* moving
//! object between two surface points with its CSM (each object's own CSSM tests
//! self-occlusion).
//!
//! The bake of issue 21's first item: [`bake_objects`] bakes one CSM per rigid object of a scene
//! into [`cssm_formats::CssmFile::csms`]; the data and the CPU query are
//! [`cssm_formats::csm`]'s. The GPU query comes next.
//!
//! - Directions: the cells of a `k x k` octahedral map of the sphere (Engelhardt and
//!   Dachsbacher's octahedral parameterisation), the direction at each cell's centre; visited
//!   along the generalised Hilbert curve over the map, so consecutive directions are neighbours
//!   (the map's edges fold onto each other, so the curve's few jumps stay short too).
//! - Each map looks along its direction `d` at the object's bounding sphere (centre `c`,
//!   radius `R`): pixel `(x, y)` casts from `c - R d + u t + v b` along `d`, `u, v` in
//!   `[-R, R]` (`(t, b)` the frame of [`crate::cubemap`]'s cube faces' Duff construction), and
//!   quantises depths over `[0, 2R]`.
//! - Query: for a segment from `light` to `receiver` (object space), the map whose direction is
//!   nearest to `receiver - light` is a shadow map of a light far along `-d`: the receiver is
//!   occluded where the stored depth at its projection lies between the light's depth and its
//!   own (2x2 percentage-closer filtering, as §3.2.2 uses for CSSMs).

use cssm_formats::{
    Scene,
    csm::{CSM_DIRECTIONS_RANGE, CSM_RESOLUTION_RANGE, CsmData, cell_direction, image_frame},
    cube::{DEPTH_MAX, DepthQuantizer},
};
use glam::Vec3;
use rayon::prelude::*;

use crate::{
    compress::{CompressOptions, Compressor, RunValue},
    cubemap::Interval,
    raycast::SceneBvh,
    traverse::gilbert_ranks,
};

/// What to bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CsmOptions {
    /// Side `k` of the octahedral map of directions: `k²` depth maps.
    pub directions: u32,
    /// Width and height of each depth map in pixels.
    pub resolution: u32,
}

impl Default for CsmOptions {
    fn default() -> Self {
        // reports/csm.md: the directions set the error, the resolution hardly.
        Self {
            directions: 64,
            resolution: 64,
        }
    }
}

/// Bakes the CSM of `object` (a scene of its triangles in object space) for object index
/// `index`; `progress(maps done)` after every batch of maps.
///
/// # Panics
/// When `options` is outside [`cssm_formats::csm::CSM_DIRECTIONS_RANGE`] or
/// [`cssm_formats::csm::CSM_RESOLUTION_RANGE`], or the object has no vertices.
pub fn bake_csm(
    object: &Scene,
    index: u32,
    options: CsmOptions,
    progress: &mut dyn FnMut(u64),
) -> CsmData {
    let (k, res) = (options.directions, options.resolution);
    assert!(
        CSM_DIRECTIONS_RANGE.contains(&k) && CSM_RESOLUTION_RANGE.contains(&res),
        "CSM options out of range: {options:?}"
    );
    let (lo, hi) = object
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    let center = 0.5 * (lo + hi);
    let radius = object
        .positions
        .iter()
        .map(|p| p.distance(center))
        .fold(0.0f32, f32::max)
        .max(1e-6);
    let bvh = SceneBvh::new(object);
    let quantizer = DepthQuantizer::new(0.0, 2.0 * radius);
    // Hits closer together than a tenth of a code are one surface.
    let separation = 0.1 * 2.0 * radius / DEPTH_MAX as f32;
    let ranks = gilbert_ranks(k, k);
    let mut cells = vec![0u32; (k * k) as usize];
    for (cell, &rank) in ranks.iter().enumerate() {
        cells[rank as usize] = cell as u32;
    }
    let pixels = (res * res) as usize;
    let mut compressor = Compressor::with_options(
        res * res,
        k * k,
        CompressOptions {
            run_value: RunValue::Middle,
            merge_short_runs: 0,
            near_codes: 0.0,
        },
    );
    let batch_maps = 4 * rayon::current_num_threads().max(2);
    let mut batch: Vec<Interval> = vec![(0, 0); batch_maps * pixels];
    let mut done = 0u64;
    for group in cells.chunks(batch_maps) {
        let slots = &mut batch[..group.len() * pixels];
        slots
            .par_chunks_mut(pixels)
            .zip(group.par_iter())
            .for_each(|(out, &cell)| {
                let d = cell_direction(k, cell);
                let (t, b) = image_frame(d);
                let origin = center - d * radius;
                for (pixel, slot) in out.iter_mut().enumerate() {
                    let (x, y) = (pixel as u32 % res, pixel as u32 / res);
                    let u = ((x as f32 + 0.5) / res as f32 * 2.0 - 1.0) * radius;
                    let v = ((y as f32 + 0.5) / res as f32 * 2.0 - 1.0) * radius;
                    let hit = bvh.dual_hit(origin + t * u + b * v, d, separation);
                    *slot = quantizer.interval(hit.first, hit.second);
                }
            });
        compressor.push(slots);
        done += group.len() as u64;
        progress(done);
    }
    let mut map_of_cell = vec![0u32; (k * k) as usize];
    for (map, &cell) in cells.iter().enumerate() {
        map_of_cell[cell as usize] = map as u32;
    }
    CsmData {
        object: index,
        center: center.to_array(),
        radius,
        directions: k,
        resolution: res,
        map_of_cell,
        runs: compressor.finish(),
    }
}

/// The CSMs of every rigid object of `scene` (`[[objects]]`), in object order, each baked in
/// the object's own space (its vertices taken back through its transform) so that it holds
/// wherever the object moves; `progress(maps done, maps in all)`.
pub fn bake_objects(
    scene: &Scene,
    options: CsmOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Vec<CsmData> {
    let rigid: Vec<(usize, &cssm_formats::SceneObject)> = scene
        .objects
        .iter()
        .enumerate()
        .filter(|(_, o)| o.kind == cssm_formats::ObjectKind::Rigid)
        .collect();
    let per_object = u64::from(options.directions * options.directions);
    let total = per_object * rigid.len() as u64;
    let mut csms = Vec::with_capacity(rigid.len());
    for (n, (index, object)) in rigid.into_iter().enumerate() {
        let local = scene.object_mesh(index, object.transform.inverse());
        let before = per_object * n as u64;
        csms.push(bake_csm(&local, index as u32, options, &mut |done| {
            progress(before + done, total)
        }));
    }
    csms
}

#[cfg(test)]
mod tests {
    use super::*;
    use cssm_formats::csm::{octahedral_direction, octahedral_uv};
    use cssm_raycast::SplitMix64;

    /// A torus of `rings x sides` quads around +z (major radius 1, minor 0.35): concave, with a
    /// hole a segment can pass through.
    fn torus(rings: u32, sides: u32) -> Scene {
        let mut positions = Vec::new();
        for i in 0..rings {
            let a = i as f32 / rings as f32 * std::f32::consts::TAU;
            for j in 0..sides {
                let b = j as f32 / sides as f32 * std::f32::consts::TAU;
                let r = 1.0 + 0.35 * b.cos();
                positions.push(Vec3::new(r * a.cos(), r * a.sin(), 0.35 * b.sin()));
            }
        }
        let mut triangles = Vec::new();
        let at = |i: u32, j: u32| (i % rings) * sides + (j % sides);
        for i in 0..rings {
            for j in 0..sides {
                let (p, q, r, s) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                triangles.push([p, q, r]);
                triangles.push([p, r, s]);
            }
        }
        Scene::from_triangles(positions, triangles)
    }

    #[test]
    fn octahedral_map_round_trips() {
        let mut rng = SplitMix64(3);
        for _ in 0..10_000 {
            let d = Vec3::new(
                rng.next_f64() as f32 - 0.5,
                rng.next_f64() as f32 - 0.5,
                rng.next_f64() as f32 - 0.5,
            )
            .normalize();
            let back = octahedral_direction(octahedral_uv(d));
            assert!(back.distance(d) < 1e-5, "{d} -> {back}");
        }
    }

    #[test]
    fn csm_agrees_with_ray_casts_outside_the_hull() {
        // CSM_OBJECT=mesh.obj measures another object (reports/csm.md: the bunny).
        let object = match std::env::var_os("CSM_OBJECT") {
            Some(path) => Scene::load(std::path::Path::new(&path)).expect("CSM_OBJECT loads"),
            None => torus(48, 24),
        };
        // CSM_DIRECTIONS and CSM_RESOLUTION override the sizes for the sweep of reports/csm.md.
        let size = |name: &str, default: u32| {
            std::env::var(name)
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(default)
        };
        let (k, res) = (size("CSM_DIRECTIONS", 32), size("CSM_RESOLUTION", 64));
        let options = CsmOptions {
            directions: k,
            resolution: res,
        };
        let csm = bake_csm(&object, 0, options, &mut |_| {});
        let ratio = csm.runs.uncompressed_bytes() as f64 / csm.runs.gpu_bytes() as f64;
        let center = Vec3::from(csm.center);
        let bvh = SceneBvh::new(&object);
        let mut rng = SplitMix64(7);
        let point_outside = |rng: &mut SplitMix64| loop {
            // In a shell around the bounding sphere (outside the convex hull, which lies in it).
            let d = Vec3::new(
                rng.next_f64() as f32 - 0.5,
                rng.next_f64() as f32 - 0.5,
                rng.next_f64() as f32 - 0.5,
            );
            if d.length() > 0.1 && d.length() <= 0.5 {
                let r = csm.radius * (1.05 + 1.5 * rng.next_f64() as f32);
                return center + d.normalize() * r;
            }
        };
        let (mut agree, mut blocked, pairs) = (0, 0, 20_000);
        let (mut false_visible, mut false_occluded) = (0, 0);
        for _ in 0..pairs {
            let light = point_outside(&mut rng);
            let receiver = point_outside(&mut rng);
            let truth = bvh.segment_clear(light, receiver);
            let answer = csm.visibility(light, receiver) >= 0.5;
            blocked += usize::from(!truth);
            agree += usize::from(answer == truth);
            false_visible += usize::from(answer && !truth);
            false_occluded += usize::from(!answer && truth);
        }
        let agreement = agree as f64 / pairs as f64;
        eprintln!(
            "{} ({} triangles) CSM {k}x{k} directions, {res}x{res} pixels: ratio {ratio:.1} : 1, agreement \
             {:.2}% over {pairs} segments ({blocked} blocked; {false_visible} false visible, \
             {false_occluded} false occluded)",
            object.name,
            object.triangles.len(),
            100.0 * agreement
        );
        assert!(
            blocked > pairs / 20,
            "too few blocked segments to judge: {blocked}"
        );
        assert!(agreement > 0.97, "agreement {agreement}");
        assert!(ratio > 2.0, "ratio {ratio}");
    }
}
