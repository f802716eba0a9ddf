//! Coherent shadow maps of the rigid objects (§3.1, after Ritschel et al. 2007, the paper's
//! \[17\]): orthographic depth maps of one object from `k x k` directions over the sphere, in a
//! coherent order, each pixel storing any depth between the ray's first and second hit (dual
//! depth), compressed into the CSSM's piecewise-constant runs and random-access layout
//! ([`RunData`]). A CSM answers whether the segment between two points outside the object's
//! convex hull is blocked by the object, without casting a ray: §3.3 tests every *other*
//! moving object between two surface points with its CSM (each object's CSSM tests
//! self-occlusion). The bake is `cssm_bake::csm`; this module holds the data and the CPU
//! query.
//!
//! - Directions: the cells of a `k x k` octahedral map of the sphere, the direction at each
//!   cell's centre ([`cell_direction`]); the bake visits them along the generalised Hilbert
//!   curve over the map, so consecutive maps look along neighbouring directions.
//! - The map of direction `d` looks at the object's bounding sphere (centre `c`, radius `R`):
//!   pixel `(x, y)` casts from `c - R d + u t + v b` along `d` (`(t, b)` = [`image_frame`]`(d)`,
//!   `u, v` in `[-R, R]`) and its depths are quantised over `[0, 2R]`.

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::cssm::RunData;
use crate::cube::{DEPTH_MAX, DepthQuantizer};

/// Valid range of [`CsmData::directions`] (the octahedral map's side).
pub const CSM_DIRECTIONS_RANGE: std::ops::RangeInclusive<u32> = 2..=256;
/// Valid range of [`CsmData::resolution`].
pub const CSM_RESOLUTION_RANGE: std::ops::RangeInclusive<u32> = 4..=256;

/// One rigid object's coherent shadow map, in the object's own space (its vertices before the
/// `[[objects]]` transform), so it holds wherever the object moves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CsmData {
    /// Index of the object in `Scene::objects`.
    pub object: u32,
    /// Centre of the object's bounding sphere (object space).
    pub center: [f32; 3],
    /// Its radius.
    pub radius: f32,
    /// Side `k` of the octahedral map of directions: `k²` depth maps.
    pub directions: u32,
    /// Width and height of each depth map in pixels.
    pub resolution: u32,
    /// `map_of_cell[y * k + x]`: the position in the sequence of the map of octahedral cell
    /// `(x, y)`.
    pub map_of_cell: Vec<u32>,
    /// The depth maps in sequence order, `resolution²` pixels each.
    pub runs: RunData,
}

/// Unit direction of the octahedral map at `uv` in `[-1, 1]²`.
///
/// ```
/// use cssm_formats::csm::{octahedral_direction, octahedral_uv};
/// let d = glam::Vec3::new(0.3, -0.5, -0.81).normalize();
/// assert!(octahedral_direction(octahedral_uv(d)).distance(d) < 1e-5);
/// ```
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

/// Direction at the centre of cell `cell` (`y * k + x`) of the `k x k` octahedral map.
pub fn cell_direction(k: u32, cell: u32) -> Vec3 {
    let (x, y) = (cell % k, cell / k);
    octahedral_direction(Vec2::new(
        (x as f32 + 0.5) / k as f32 * 2.0 - 1.0,
        (y as f32 + 0.5) / k as f32 * 2.0 - 1.0,
    ))
}

/// Two unit vectors completing `d` to an orthonormal frame (Duff et al. 2017): the image plane
/// of the map looking along `d`.
pub fn image_frame(d: Vec3) -> (Vec3, Vec3) {
    let sign = if d.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + d.z);
    let b = d.x * d.y * a;
    (
        Vec3::new(1.0 + sign * d.x * d.x * a, sign * b, -sign * d.x),
        Vec3::new(b, sign + d.y * d.y * a, -d.y),
    )
}

impl CsmData {
    /// Quantiser of the maps' depths, over `[0, 2R]`.
    pub fn quantizer(&self) -> DepthQuantizer {
        DepthQuantizer::new(0.0, 2.0 * self.radius)
    }

    /// Fraction in `[0, 1]` of the segment from `light` to `receiver` (object space) that the
    /// object leaves clear; 1 for a degenerate segment. The maps of the four direction cells
    /// around `receiver - light`, each with 2x2 percentage-closer filtering, weighted
    /// bilinearly over the octahedral map (the CSM's filtering across neighbouring maps: it
    /// halves the error of the nearest map alone, `reports/csm.md`). Both points must lie
    /// outside the object's convex hull (§3.1: the CSM's limit; the surface points of *another*
    /// object do in the paper's use, §3.3).
    pub fn visibility(&self, light: Vec3, receiver: Vec3) -> f32 {
        let k = self.directions;
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
    /// its `-d`; the receiver is occluded where the stored depth at its projection lies between
    /// the light's depth and its own. 2x2 percentage-closer filtering.
    fn map_visibility(&self, cell: u32, light: Vec3, receiver: Vec3) -> f32 {
        let res = self.resolution;
        let d = cell_direction(self.directions, cell);
        let (t, b) = image_frame(d);
        let origin = Vec3::from(self.center) - d * self.radius;
        let depth_of = |p: Vec3| (p - origin).dot(d);
        let (light_depth, receiver_depth) = (depth_of(light), depth_of(receiver));
        let map = self.map_of_cell[cell as usize];
        let quantizer = self.quantizer();
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

    /// Checks the ranges, the permutation of cells and the run layout, so that
    /// [`CsmData::visibility`] never indexes out of range.
    pub(crate) fn validate(&self) -> Result<(), String> {
        if !CSM_DIRECTIONS_RANGE.contains(&self.directions) {
            return Err(format!(
                "{} directions per side outside {}..={}",
                self.directions,
                CSM_DIRECTIONS_RANGE.start(),
                CSM_DIRECTIONS_RANGE.end()
            ));
        }
        if !CSM_RESOLUTION_RANGE.contains(&self.resolution) {
            return Err(format!(
                "resolution {} outside {}..={}",
                self.resolution,
                CSM_RESOLUTION_RANGE.start(),
                CSM_RESOLUTION_RANGE.end()
            ));
        }
        if !(self.center.iter().all(|c| c.is_finite())
            && self.radius.is_finite()
            && self.radius > 0.0)
        {
            return Err("bounding sphere not finite or of no radius".into());
        }
        let maps = self.directions * self.directions;
        if self.map_of_cell.len() != maps as usize {
            return Err(format!(
                "{} cells for {maps} directions",
                self.map_of_cell.len()
            ));
        }
        let mut seen = vec![false; maps as usize];
        for &m in &self.map_of_cell {
            match seen.get_mut(m as usize) {
                Some(s) if !*s => *s = true,
                _ => return Err(format!("map_of_cell is not a permutation (map {m})")),
            }
        }
        if self.runs.map_count != maps {
            return Err(format!(
                "{} maps of runs for {maps} directions",
                self.runs.map_count
            ));
        }
        crate::cssm::validate_run_layout(&self.runs, self.resolution * self.resolution)
            .map_err(|e| e.to_string())
    }
}
