//! CPU twin of the sparse voxel octree's values and reads (`radiance.wgsl`, `svo.wgsl`): the
//! same values in a dense pyramid, one full grid per level, so that every read the GPU makes
//! through nodes and bricks has a plain-array counterpart to be held to (`tests/gpu/vct.rs`).
//!
//! - [`inject`]: the RSM texels' flux into the leaves, in the GPU's fixed point (the sums are
//!   integers, so the GPU's atomics in any order give the same words);
//! - [`Pyramid::from_leaves`]: the leaves' values and every coarser level the mean of its eight
//!   children (`leaves`, `mip`);
//! - [`Pyramid::vertex`]: a brick texel, the mean of the cells touching its vertex
//!   (`fill_bricks`);
//! - [`Pyramid::sample`], [`Pyramid::sample_lod`], [`trace_cone`]: the trilinear sample of a
//!   level (what the hardware filter computes inside a brick), the quadrilinear one, and a
//!   cone's front-to-back accumulation (`svo_sample`, `svo_sample_lod`, `svo_cone`).

use std::collections::{BTreeMap, BTreeSet};

use glam::{Vec3, Vec4};

use super::radiance::SvoParams;
use crate::gpu_types::GpuSpotLight;

/// `radiance.wgsl`'s `FLUX_UNITS`: the fixed point's units for the flux bound.
pub const FLUX_UNITS: f32 = 1_073_741_824.0;

/// `svo.wgsl`'s `SVO_STEP`: a cone's step in diameters.
pub const STEP: f32 = 0.5;

/// `svo.wgsl`'s `SVO_MAX_SAMPLES`.
pub const MAX_SAMPLES: u32 = 4096;

/// The flux the lights' cones send at most: the intensity's largest component times the cone's
/// solid angle (`radiance.wgsl::flux_bound`).
pub fn flux_bound(lights: &[GpuSpotLight]) -> f32 {
    let total: f32 = lights
        .iter()
        .map(|l| {
            let peak = l.intensity[0].max(l.intensity[1]).max(l.intensity[2]);
            peak * (2.0 * std::f32::consts::PI * (1.0 - l.cos_cutoff))
        })
        .sum();
    total.max(1e-30)
}

/// `[flux units per W, radiance per flux unit]` (`plan`; the GPU's division may differ in the
/// last bits, so a twin that must match bit for bit reads the GPU's).
pub fn flux_constants(lights: &[GpuSpotLight], voxel: f32) -> [f32; 2] {
    let scale = FLUX_UNITS / flux_bound(lights);
    [scale, 1.0 / (scale * std::f32::consts::PI * voxel * voxel)]
}

/// One texel of an RSM, as the raster wrote it.
#[derive(Clone, Copy, Debug)]
pub struct RsmTexel {
    /// xyz world position, w 1 where a surface covers the texel.
    pub position: Vec4,
    /// Unit normal turned towards the light.
    pub normal: Vec3,
    /// Reflected flux, W.
    pub flux: Vec3,
}

/// The leaf cell of world point `p`, `None` outside the grid.
pub fn leaf_of(params: &SvoParams, p: Vec3) -> Option<[u32; 3]> {
    let q = ((p - Vec3::from(params.origin)) * params.inv_voxel).floor();
    let res = params.resolution as f32;
    if q.cmplt(Vec3::ZERO).any() || q.cmpge(Vec3::splat(res)).any() {
        return None;
    }
    Some([q.x as u32, q.y as u32, q.z as u32])
}

/// Every texel's flux into the occupied leaf holding its surface point (nudged a quarter voxel
/// towards the light first), in units of `1 / scale` W (`radiance.wgsl::inject`).
pub fn inject(
    params: &SvoParams,
    texels: impl IntoIterator<Item = RsmTexel>,
    occupied: &BTreeSet<[u32; 3]>,
    scale: f32,
) -> BTreeMap<[u32; 3], [u32; 3]> {
    let mut sums = BTreeMap::new();
    let occupied_leaf = |p| leaf_of(params, p).filter(|c| occupied.contains(c));
    for t in texels {
        if t.position.w <= 0.0 || t.flux.cmple(Vec3::ZERO).all() {
            continue;
        }
        let p = t.position.truncate();
        let Some(leaf) = occupied_leaf(p + t.normal * (0.25 * params.voxel)).or(occupied_leaf(p))
        else {
            continue;
        };
        let units = (t.flux * scale).to_array().map(|f| f as u32);
        let sum: &mut [u32; 3] = sums.entry(leaf).or_default();
        for (s, u) in sum.iter_mut().zip(units) {
            *s = s.wrapping_add(u);
        }
    }
    sums
}

/// A dense pyramid of the octree's values: level `l` holds `(2^l)³` voxels of
/// `(radiance times opacity, opacity)`, x fastest.
#[derive(Clone, Debug)]
pub struct Pyramid {
    /// Levels below the root.
    pub max_level: u32,
    /// Level 0 (the root) to `max_level` (the leaves).
    pub levels: Vec<Vec<Vec4>>,
}

impl Pyramid {
    /// The pyramid of `leaves` (occupied cells and their radiance; every one opaque): each
    /// coarser voxel the mean of its eight children, summed in octant order.
    pub fn from_leaves(max_level: u32, leaves: &BTreeMap<[u32; 3], Vec3>) -> Self {
        let side = 1usize << max_level;
        let mut finest = vec![Vec4::ZERO; side * side * side];
        for (c, radiance) in leaves {
            finest[c[0] as usize + side * (c[1] as usize + side * c[2] as usize)] =
                radiance.extend(1.0);
        }
        let mut levels = vec![finest];
        for level in (0..max_level).rev() {
            let side = 1usize << level;
            let fine = levels.last().expect("a finer level");
            let fine_side = 2 * side;
            let mut coarse = vec![Vec4::ZERO; side * side * side];
            for (i, out) in coarse.iter_mut().enumerate() {
                let (x, y, z) = (i % side, (i / side) % side, i / (side * side));
                let mut sum = Vec4::ZERO;
                for o in 0..8 {
                    let (cx, cy, cz) = (2 * x + (o & 1), 2 * y + ((o >> 1) & 1), 2 * z + (o >> 2));
                    sum += fine[cx + fine_side * (cy + fine_side * cz)];
                }
                *out = sum * 0.125;
            }
            levels.push(coarse);
        }
        levels.reverse();
        Self { max_level, levels }
    }

    /// The voxel `c` of `level`, zero outside the grid.
    pub fn cell(&self, level: u32, c: [i64; 3]) -> Vec4 {
        let side = 1i64 << level;
        if c.iter().any(|&k| k < 0 || k >= side) {
            return Vec4::ZERO;
        }
        let s = side as usize;
        self.levels[level as usize][c[0] as usize + s * (c[1] as usize + s * c[2] as usize)]
    }

    /// The brick texel at vertex `h` of `level`, in half voxels: the mean of the voxels touching
    /// it (one at a centre, two at a face, four at an edge, eight at a corner), summed z, y, x
    /// as `fill_bricks` does.
    pub fn vertex(&self, level: u32, h: [i64; 3]) -> Vec4 {
        let axis = |h: i64| {
            if h.rem_euclid(2) == 1 {
                ((h - 1) / 2, (h - 1) / 2)
            } else {
                (h / 2 - 1, h / 2)
            }
        };
        let (x, y, z) = (axis(h[0]), axis(h[1]), axis(h[2]));
        let mut sum = Vec4::ZERO;
        let mut n = 0.0;
        for k in z.0..=z.1 {
            for j in y.0..=y.1 {
                for i in x.0..=x.1 {
                    sum += self.cell(level, [i, j, k]);
                    n += 1.0;
                }
            }
        }
        sum / n
    }

    /// Level `level` (1 to `max_level`) at `p` (leaf voxels from the grid's corner): zero where
    /// the parent voxel is empty (no brick there), else the trilinear interpolation of the
    /// level's voxel-centred values (`svo_sample`).
    pub fn sample(&self, p: Vec3, level: u32) -> Vec4 {
        let res = (1u32 << self.max_level) as f32;
        if p.cmplt(Vec3::ZERO).any() || p.cmpge(Vec3::splat(res)).any() {
            return Vec4::ZERO;
        }
        let parent_size = (1u32 << (self.max_level + 1 - level)) as f32;
        let parent = (p / parent_size).floor().as_i64vec3().to_array();
        if self.cell(level - 1, parent).w <= 0.0 {
            return Vec4::ZERO;
        }
        let size = parent_size * 0.5;
        let q = p / size - 0.5;
        let base = q.floor();
        let f = q - base;
        let base = base.as_i64vec3().to_array();
        let mut out = Vec4::ZERO;
        for o in 0..8i64 {
            let bit = [o & 1, (o >> 1) & 1, o >> 2];
            let w = (0..3)
                .map(|k| if bit[k] == 1 { f[k] } else { 1.0 - f[k] })
                .product::<f32>();
            out += w * self.cell(level, [0, 1, 2].map(|k| base[k] + bit[k]));
        }
        out
    }

    /// The quadrilinear sample: `floor(level)` and the next finer level, interpolated
    /// (`svo_sample_lod`).
    pub fn sample_lod(&self, p: Vec3, level: f32) -> Vec4 {
        let coarse = level.floor() as u32;
        let f = level - level.floor();
        let a = self.sample(p, coarse);
        if f <= 0.0 || coarse >= self.max_level {
            return a;
        }
        a.lerp(self.sample(p, coarse + 1), f)
    }
}

/// A cone from `origin` (leaf voxels) along the unit `dir`, its radius `tan_half` times the
/// distance, from distance `start` to the grid's diagonal or until opaque: front-to-back
/// accumulation (`svo_cone`). Returns `(radiance, opacity)`.
pub fn trace_cone(pyramid: &Pyramid, origin: Vec3, dir: Vec3, tan_half: f32, start: f32) -> Vec4 {
    let max_level = pyramid.max_level as f32;
    let end = (1u32 << pyramid.max_level) as f32 * 1.732_050_8;
    let mut radiance = Vec3::ZERO;
    let mut alpha = 0.0f32;
    let mut t = start;
    for _ in 0..MAX_SAMPLES {
        if t >= end || alpha >= 0.99 {
            break;
        }
        let diameter = (2.0 * t * tan_half).max(1.0);
        let level = (max_level - diameter.log2()).clamp(1.0, max_level);
        let s = pyramid.sample_lod(origin + t * dir, level);
        let step = STEP * diameter;
        if s.w > 0.0 {
            let size = (max_level - level).exp2();
            let a = if s.w < 1.0 {
                1.0 - (1.0 - s.w).powf(step / size)
            } else {
                1.0
            };
            radiance += (1.0 - alpha) * a * (s.truncate() / s.w);
            alpha += (1.0 - alpha) * a;
        }
        t += step;
    }
    radiance.extend(alpha)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_leaf() -> Pyramid {
        Pyramid::from_leaves(2, &BTreeMap::from([([1, 2, 3], Vec3::new(4.0, 2.0, 1.0))]))
    }

    #[test]
    fn each_level_is_the_mean_of_its_children() {
        let p = one_leaf();
        assert_eq!(p.cell(2, [1, 2, 3]), Vec4::new(4.0, 2.0, 1.0, 1.0));
        assert_eq!(p.cell(1, [0, 1, 1]), Vec4::new(0.5, 0.25, 0.125, 0.125));
        assert_eq!(p.cell(0, [0, 0, 0]).w, 1.0 / 64.0);
        assert_eq!(p.cell(2, [4, 0, 0]), Vec4::ZERO);
    }

    #[test]
    fn vertices_are_the_mean_of_the_cells_they_touch() {
        let p = one_leaf();
        // The centre of the leaf is the leaf; a face between it and an empty one, half of it.
        assert_eq!(p.vertex(2, [3, 5, 7]), p.cell(2, [1, 2, 3]));
        assert_eq!(p.vertex(2, [4, 5, 7]), p.cell(2, [1, 2, 3]) * 0.5);
        assert_eq!(p.vertex(2, [4, 4, 8]), p.cell(2, [1, 2, 3]) * 0.125);
    }

    #[test]
    fn samples_interpolate_inside_occupied_parents_only() {
        let p = one_leaf();
        // At the leaf's centre: the leaf; a quarter voxel towards an empty neighbour: 3/4.
        let centre = Vec3::new(1.5, 2.5, 3.5);
        assert_eq!(p.sample(centre, 2), p.cell(2, [1, 2, 3]));
        let off = p.sample(centre + Vec3::new(0.25, 0.0, 0.0), 2);
        assert!((off.w - 0.75).abs() < 1e-6, "{off}");
        // The parent of cell (3, 2, 3) at level 1 is (1, 1, 1): empty, though the trilinear
        // interpolation would reach the leaf.
        assert_eq!(p.sample(Vec3::new(2.1, 2.5, 3.5), 2), Vec4::ZERO);
        assert_eq!(p.sample(Vec3::new(-0.1, 2.5, 3.5), 2), Vec4::ZERO);
    }

    #[test]
    fn a_cone_into_an_opaque_wall_sees_its_radiance() {
        // A wall of leaves at x = 6 of an 8³ grid, radiance 2.
        let leaves = (0..8)
            .flat_map(|y| (0..8).map(move |z| ([6u32, y, z], Vec3::splat(2.0))))
            .collect();
        let p = Pyramid::from_leaves(3, &leaves);
        let thin = trace_cone(&p, Vec3::new(1.0, 4.0, 4.0), Vec3::X, 0.01, 0.5);
        assert!(
            thin.w > 0.99 && (thin.x - 2.0 * thin.w).abs() < 1e-3,
            "{thin}"
        );
        // Away from the wall nothing.
        let away = trace_cone(&p, Vec3::new(4.0, 4.0, 4.0), Vec3::NEG_X, 0.01, 0.5);
        assert_eq!(away, Vec4::ZERO);
        // A wide cone sees the wall through coarse voxels, not fully opaque.
        let wide = trace_cone(&p, Vec3::new(1.0, 4.0, 4.0), Vec3::X, 0.6, 0.5);
        assert!(wide.w > 0.2 && wide.x > 0.0, "{wide}");
        assert!((wide.x / wide.w - 2.0).abs() < 1e-3, "{wide}");
    }

    #[test]
    fn injection_nudges_towards_the_light_and_keeps_integers() {
        let params = SvoParams {
            origin: [0.0; 3],
            inv_voxel: 1.0,
            max_level: 2,
            resolution: 4,
            bricks_per_side: 1,
            voxel: 1.0,
        };
        // A floor on the boundary y = 1 between two occupied layers, lit from above.
        let occupied = BTreeSet::from([[1, 0, 1], [1, 1, 1]]);
        let texel = RsmTexel {
            position: Vec4::new(1.5, 1.0, 1.5, 1.0),
            normal: Vec3::Y,
            flux: Vec3::new(1.0, 0.5, 0.0),
        };
        let sums = inject(&params, [texel, texel], &occupied, 1000.0);
        assert_eq!(sums, BTreeMap::from([([1, 1, 1], [2000, 1000, 0])]));
        // Nudged into an empty voxel: the point's own.
        let near_top = RsmTexel {
            position: Vec4::new(1.5, 1.9, 1.5, 1.0),
            ..texel
        };
        let sums = inject(&params, [near_top], &occupied, 1000.0);
        assert_eq!(sums.keys().collect::<Vec<_>>(), [&[1, 1, 1]]);
    }
}
