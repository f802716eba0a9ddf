//! Coherent shadow maps of one rigid object (§3.1, after Ritschel et al. 2007, the paper's
//! [17]): orthographic depth maps of the object from `k x k` directions over the sphere, in a
//! coherent order, each pixel storing any depth between the ray's first and second hit (dual
//! depth), compressed into the same piecewise-constant runs and random-access layout as a
//! CSSM. A CSM answers whether the segment from a point outside the object's convex hull to
//! another is blocked by the object, without casting a ray: §3.3 tests every *other* moving
//! object between two surface points with its CSM (each object's own CSSM tests
//! self-occlusion).
//!
//! This is the bake and the CPU query of issue 21's first item, in memory; storing CSMs in the
//! `.cssm` container and the GPU query come next.
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
    cssm::RunData,
    cube::{DEPTH_MAX, DepthQuantizer},
};
use glam::{Vec2, Vec3};
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

/// One object's coherent shadow map.
#[derive(Clone, Debug, PartialEq)]
pub struct Csm {
    /// Centre of the object's bounding sphere (object space).
    pub center: Vec3,
    /// Its radius.
    pub radius: f32,
    /// What was baked.
    pub options: CsmOptions,
    /// `map_of_cell[cell]`: the position in the sequence of the map of octahedral cell
    /// `y * k + x`.
    pub map_of_cell: Vec<u32>,
    /// The depth maps, in sequence order, `resolution²` pixels each.
    pub runs: RunData,
}

/// Unit direction of the octahedral map at `uv` in `[-1, 1]²`.
pub fn octahedral_direction(uv: Vec2) -> Vec3 {
    let mut d = Vec3::new(uv.x, uv.y, 1.0 - uv.x.abs() - uv.y.abs());
    if d.z < 0.0 {
        let (x, y) = (d.x, d.y);
        d.x = (1.0 - y.abs()) * x.signum();
        d.y = (1.0 - x.abs()) * y.signum();
    }
    d.normalize()
}

/// Position in `[-1, 1]²` of the unit direction `d` on the octahedral map.
pub fn octahedral_uv(d: Vec3) -> Vec2 {
    let p = d / (d.x.abs() + d.y.abs() + d.z.abs());
    if p.z >= 0.0 {
        Vec2::new(p.x, p.y)
    } else {
        Vec2::new(
            (1.0 - p.y.abs()) * if p.x >= 0.0 { 1.0 } else { -1.0 },
            (1.0 - p.x.abs()) * if p.y >= 0.0 { 1.0 } else { -1.0 },
        )
    }
}

/// Two unit vectors completing `d` to an orthonormal frame (Duff et al. 2017), the image plane
/// of the map looking along `d`.
fn frame(d: Vec3) -> (Vec3, Vec3) {
    let sign = if d.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + d.z);
    let b = d.x * d.y * a;
    (
        Vec3::new(1.0 + sign * d.x * d.x * a, sign * b, -sign * d.x),
        Vec3::new(b, sign + d.y * d.y * a, -d.y),
    )
}

impl Csm {
    /// Bakes the CSM of `object` (its triangles in object space).
    ///
    /// # Panics
    /// When `options` asks for no maps or no pixels, or the object has no triangles.
    pub fn bake(object: &Scene, options: CsmOptions) -> Self {
        let (k, res) = (options.directions, options.resolution);
        assert!(k > 0 && res > 0, "a CSM needs directions and pixels");
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
        for group in cells.chunks(batch_maps) {
            let slots = &mut batch[..group.len() * pixels];
            slots
                .par_chunks_mut(pixels)
                .zip(group.par_iter())
                .for_each(|(out, &cell)| {
                    let d = cell_direction(k, cell);
                    let (t, b) = frame(d);
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
        }
        let mut map_of_cell = vec![0u32; (k * k) as usize];
        for (map, &cell) in cells.iter().enumerate() {
            map_of_cell[cell as usize] = map as u32;
        }
        Self {
            center,
            radius,
            options,
            map_of_cell,
            runs: compressor.finish(),
        }
    }

    /// Fraction in `[0, 1]` of the segment from `light` to `receiver` (object space) that the
    /// object leaves clear; 1 for a degenerate segment. The maps of the four direction cells
    /// around `receiver - light`, each with 2x2 percentage-closer filtering, weighted
    /// bilinearly over the octahedral map (the CSM's filtering across neighbouring maps:
    /// halves the error of the nearest map alone, `csm_agrees_with_ray_casts_outside_the_hull`).
    /// Both points must lie outside the object's convex hull (§3.1: the CSM's limit; the surface
    /// points of *another* object do in the paper's use, §3.3).
    pub fn visibility(&self, light: Vec3, receiver: Vec3) -> f32 {
        let k = self.options.directions;
        let w = receiver - light;
        if w.length_squared() <= 0.0 {
            return 1.0;
        }
        let uv = octahedral_uv(w.normalize());
        let max = (k - 1) as f32;
        let fx = ((uv.x + 1.0) * 0.5 * k as f32 - 0.5).clamp(0.0, max);
        let fy = ((uv.y + 1.0) * 0.5 * k as f32 - 0.5).clamp(0.0, max);
        let (x0, y0) = (fx.floor() as u32, fy.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(k - 1), (y0 + 1).min(k - 1));
        let (wx, wy) = (fx - x0 as f32, fy - y0 as f32);
        let at = |x: u32, y: u32| self.map_visibility(y * k + x, light, receiver);
        (1.0 - wy) * ((1.0 - wx) * at(x0, y0) + wx * at(x1, y0))
            + wy * ((1.0 - wx) * at(x0, y1) + wx * at(x1, y1))
    }

    /// The answer of the map of direction cell `cell` alone: a shadow map of a light far along
    /// its `-d`, the receiver occluded where the stored depth at its projection lies between
    /// the light's depth and its own; 2x2 percentage-closer filtering.
    fn map_visibility(&self, cell: u32, light: Vec3, receiver: Vec3) -> f32 {
        let res = self.options.resolution;
        let d = cell_direction(self.options.directions, cell);
        let (t, b) = frame(d);
        let origin = self.center - d * self.radius;
        let depth_of = |p: Vec3| (p - origin).dot(d);
        let (light_depth, receiver_depth) = (depth_of(light), depth_of(receiver));
        let map = self.map_of_cell[cell as usize];
        let quantizer = DepthQuantizer::new(0.0, 2.0 * self.radius);
        let r = receiver - origin;
        let fx = (r.dot(t) / self.radius + 1.0) * 0.5 * res as f32 - 0.5;
        let fy = (r.dot(b) / self.radius + 1.0) * 0.5 * res as f32 - 0.5;
        // A receiver whose projection misses the map is beside the object: nothing blocks it.
        if !(fx > -1.0 && fy > -1.0 && fx < res as f32 && fy < res as f32) {
            return 1.0;
        }
        // Half a code of bias: the quantisation of the stored depth.
        let bias = self.radius / DEPTH_MAX as f32;
        let clear = |x: i64, y: i64| -> f32 {
            if x < 0 || y < 0 || x >= i64::from(res) || y >= i64::from(res) {
                return 1.0;
            }
            let z = quantizer.depth(self.runs.lookup(map, (y as u32) * res + x as u32));
            if z > light_depth + bias && z < receiver_depth - bias {
                0.0
            } else {
                1.0
            }
        };
        let (x0, y0) = (fx.floor(), fy.floor());
        let (wx, wy) = (fx - x0, fy - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        (1.0 - wy) * ((1.0 - wx) * clear(x0, y0) + wx * clear(x0 + 1, y0))
            + wy * ((1.0 - wx) * clear(x0, y0 + 1) + wx * clear(x0 + 1, y0 + 1))
    }

    /// Bytes of the run data in memory (offsets and runs), the CSSM's `gpu_bytes`.
    pub fn gpu_bytes(&self) -> u64 {
        self.runs.gpu_bytes()
    }

    /// Uncompressed size: 2 bytes per pixel of every map.
    pub fn uncompressed_bytes(&self) -> u64 {
        self.runs.uncompressed_bytes()
    }
}

/// Direction at the centre of cell `cell` (`y * k + x`) of the `k x k` octahedral map.
fn cell_direction(k: u32, cell: u32) -> Vec3 {
    let (x, y) = (cell % k, cell / k);
    octahedral_direction(Vec2::new(
        (x as f32 + 0.5) / k as f32 * 2.0 - 1.0,
        (y as f32 + 0.5) / k as f32 * 2.0 - 1.0,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
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
        let csm = Csm::bake(
            &object,
            CsmOptions {
                directions: k,
                resolution: res,
            },
        );
        let ratio = csm.uncompressed_bytes() as f64 / csm.gpu_bytes() as f64;
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
                return csm.center + d.normalize() * r;
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
