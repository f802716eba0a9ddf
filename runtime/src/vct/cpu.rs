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

use super::{radiance::SvoParams, trace::TraceParams};
use crate::{common::voxelize::VoxelFragment, gpu_types::GpuSpotLight};

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
    // No light sends any flux: nothing is injected; a finite scale (see `radiance.wgsl`).
    if total > 0.0 { total } else { 1.0 }
}

/// `[flux units per W, radiance per flux unit]` (`plan`; the GPU's division may differ in the
/// last bits, so a twin that must match bit for bit reads the GPU's).
pub fn flux_constants(lights: &[GpuSpotLight], voxel: f32) -> [f32; 2] {
    let scale = FLUX_UNITS / flux_bound(lights);
    [scale, 1.0 / (scale * std::f32::consts::PI * voxel * voxel)]
}

/// `radiance.wgsl`'s `AREA_UNITS`: fixed-point units of area per leaf voxel face.
pub const AREA_UNITS: f32 = 16_777_216.0;

/// `radiance.wgsl`'s `MIN_COS`: the slant at which a texel's area stops growing.
pub const MIN_COS: f32 = 0.05;

/// One texel of an RSM, as the raster wrote it, and the surface area it covers.
#[derive(Clone, Copy, Debug)]
pub struct RsmTexel {
    /// xyz world position, w 1 where a surface covers the texel.
    pub position: Vec4,
    /// Unit normal turned towards the light.
    pub normal: Vec3,
    /// Reflected flux, W.
    pub flux: Vec3,
    /// Surface area, world units squared ([`texel_area`]).
    pub area: f32,
}

/// The surface area an RSM texel of `light` at `p` with the unit `normal` covers: its solid
/// angle from the light (`texel_solid_angle` on the axis, cos³ off it) times the squared
/// distance over the cosine of incidence, at least [`MIN_COS`] (`radiance.wgsl::texel_area`).
pub fn texel_area(light: &GpuSpotLight, p: Vec3, normal: Vec3) -> f32 {
    let to_surface = p - Vec3::from(light.position);
    let d2 = to_surface.dot(to_surface);
    let dir = to_surface / d2.sqrt();
    let cos_axis = dir.dot(Vec3::from(light.direction));
    let cos_in = (-normal.dot(dir)).max(MIN_COS);
    light.texel_solid_angle * cos_axis * cos_axis * cos_axis * d2 / cos_in
}

/// A leaf's radiance from its sums: flux units times `radiance_per_unit` (the second of
/// [`flux_constants`]) per unit of area, zero without area (`radiance.wgsl::leaves`).
pub fn leaf_radiance(sums: [u32; 4], radiance_per_unit: f32) -> Vec3 {
    if sums[3] == 0 {
        return Vec3::ZERO;
    }
    let units = Vec3::new(sums[0] as f32, sums[1] as f32, sums[2] as f32);
    units * (radiance_per_unit * (AREA_UNITS / sums[3] as f32))
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
/// towards the light first), in units of `1 / scale` W, and its area in [`AREA_UNITS`] per
/// leaf voxel face (`radiance.wgsl::inject`).
pub fn inject(
    params: &SvoParams,
    texels: impl IntoIterator<Item = RsmTexel>,
    occupied: &BTreeSet<[u32; 3]>,
    scale: f32,
) -> BTreeMap<[u32; 3], [u32; 4]> {
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
        let [r, g, b] = (t.flux * scale).to_array().map(|f| f as u32);
        let area = (t.area * params.inv_voxel * params.inv_voxel * AREA_UNITS + 0.5) as u32;
        let sum: &mut [u32; 4] = sums.entry(leaf).or_default();
        for (s, u) in sum.iter_mut().zip([r, g, b, area]) {
            *s = s.wrapping_add(u);
        }
    }
    sums
}

/// A dense pyramid of the octree's values: level `l` holds `(2^l)³` voxels of
/// `(radiance times opacity, opacity)`, x fastest, `faces` values each (1 isotropic, 6
/// anisotropic: +x, -x, +y, -y, +z, -z).
#[derive(Clone, Debug)]
pub struct Pyramid {
    /// Levels below the root.
    pub max_level: u32,
    /// Values per voxel.
    pub faces: u32,
    /// Level 0 (the root) to `max_level` (the leaves), `voxel * faces + face`.
    pub levels: Vec<Vec<Vec4>>,
}

impl Pyramid {
    /// The pyramid of `leaves` (occupied cells and their radiance; every one opaque, the same
    /// from every side). Each coarser voxel is the box filter of its eight children, summed in
    /// octant order: isotropic their mean; anisotropic, per face, each of the four columns
    /// along the face's axis composited front to back, then the columns' mean (`mip`).
    pub fn from_leaves(max_level: u32, faces: u32, leaves: &BTreeMap<[u32; 3], Vec3>) -> Self {
        let side = 1usize << max_level;
        let f = faces as usize;
        let mut finest = vec![Vec4::ZERO; side * side * side * f];
        for (c, radiance) in leaves {
            let voxel = c[0] as usize + side * (c[1] as usize + side * c[2] as usize);
            finest[voxel * f..(voxel + 1) * f].fill(radiance.extend(1.0));
        }
        let mut levels = vec![finest];
        for level in (0..max_level).rev() {
            let side = 1usize << level;
            let fine = levels.last().expect("a finer level");
            let fine_side = 2 * side;
            let child = |x: usize, y: usize, z: usize, o: usize, face: usize| {
                let (cx, cy, cz) = (2 * x + (o & 1), 2 * y + ((o >> 1) & 1), 2 * z + (o >> 2));
                fine[(cx + fine_side * (cy + fine_side * cz)) * f + face]
            };
            let mut coarse = vec![Vec4::ZERO; side * side * side * f];
            for (i, out) in coarse.iter_mut().enumerate() {
                let (voxel, face) = (i / f, i % f);
                let (x, y, z) = (voxel % side, (voxel / side) % side, voxel / (side * side));
                let mut sum = Vec4::ZERO;
                if faces == 1 {
                    for o in 0..8 {
                        sum += child(x, y, z, o, 0);
                    }
                    *out = sum * 0.125;
                    continue;
                }
                let bit = 1usize << (face / 2);
                let front_set = if face & 1 == 1 { bit } else { 0 };
                for o in (0..8).filter(|o| o & bit == 0) {
                    let front = child(x, y, z, o | front_set, face);
                    let back = child(x, y, z, o | (bit ^ front_set), face);
                    sum += front + (1.0 - front.w) * back;
                }
                *out = sum * 0.25;
            }
            levels.push(coarse);
        }
        levels.reverse();
        Self {
            max_level,
            faces,
            levels,
        }
    }

    /// Face `face` of voxel `c` of `level`, zero outside the grid.
    pub fn cell(&self, level: u32, c: [i64; 3], face: u32) -> Vec4 {
        let side = 1i64 << level;
        if c.iter().any(|&k| k < 0 || k >= side) {
            return Vec4::ZERO;
        }
        let s = side as usize;
        let voxel = c[0] as usize + s * (c[1] as usize + s * c[2] as usize);
        self.levels[level as usize][voxel * self.faces as usize + face as usize]
    }

    /// The brick texel of face `face` at vertex `h` of `level`, in half voxels: the mean of the
    /// voxels touching it (one at a centre, two at a face, four at an edge, eight at a corner),
    /// summed z, y, x as `fill_bricks` does.
    pub fn vertex(&self, level: u32, h: [i64; 3], face: u32) -> Vec4 {
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
                    sum += self.cell(level, [i, j, k], face);
                    n += 1.0;
                }
            }
        }
        sum / n
    }

    /// Level `level` (1 to `max_level`) at `p` (leaf voxels from the grid's corner), seen along
    /// the unit `dir`: zero where the parent voxel is empty (no brick there), else the
    /// trilinear interpolation of the level's voxel-centred values, anisotropic ones weighed by
    /// the squared components of `dir` over the three faces it looks at (`svo_sample`).
    pub fn sample(&self, p: Vec3, level: u32, dir: Vec3) -> Vec4 {
        let res = (1u32 << self.max_level) as f32;
        if p.cmplt(Vec3::ZERO).any() || p.cmpge(Vec3::splat(res)).any() {
            return Vec4::ZERO;
        }
        let parent_size = (1u32 << (self.max_level + 1 - level)) as f32;
        let parent = (p / parent_size).floor().as_i64vec3().to_array();
        if (0..self.faces).all(|face| self.cell(level - 1, parent, face).w <= 0.0) {
            return Vec4::ZERO;
        }
        let size = parent_size * 0.5;
        let q = p / size - 0.5;
        let base = q.floor();
        let f = q - base;
        let base = base.as_i64vec3().to_array();
        let trilinear = |face| {
            let mut out = Vec4::ZERO;
            for o in 0..8i64 {
                let bit = [o & 1, (o >> 1) & 1, o >> 2];
                let w = (0..3)
                    .map(|k| if bit[k] == 1 { f[k] } else { 1.0 - f[k] })
                    .product::<f32>();
                out += w * self.cell(level, [0, 1, 2].map(|k| base[k] + bit[k]), face);
            }
            out
        };
        if self.faces == 1 {
            return trilinear(0);
        }
        let w = dir * dir;
        let face = |axis: u32, c: f32| 2 * axis + u32::from(c < 0.0);
        w.x * trilinear(face(0, dir.x))
            + w.y * trilinear(face(1, dir.y))
            + w.z * trilinear(face(2, dir.z))
    }

    /// The quadrilinear sample: `floor(level)` and the next finer level, interpolated
    /// (`svo_sample_lod`).
    pub fn sample_lod(&self, p: Vec3, level: f32, dir: Vec3) -> Vec4 {
        let coarse = level.floor() as u32;
        let f = level - level.floor();
        let a = self.sample(p, coarse, dir);
        if f <= 0.0 || coarse >= self.max_level {
            return a;
        }
        a.lerp(self.sample(p, coarse + 1, dir), f)
    }
}

/// A cone from `origin` (leaf voxels) along the unit `dir`, its radius `tan_half` times the
/// distance, from distance `start` to the grid's diagonal or until opaque: front-to-back
/// accumulation (`svo_cone`), each sample's opacity corrected for a step shorter than its
/// voxel when `correct_opacity` (§5). Returns `(radiance, opacity)`.
pub fn trace_cone(
    pyramid: &Pyramid,
    origin: Vec3,
    dir: Vec3,
    tan_half: f32,
    start: f32,
    correct_opacity: bool,
) -> Vec4 {
    let end = (1u32 << pyramid.max_level) as f32 * 1.732_050_8;
    trace_cone_to(
        pyramid,
        origin,
        dir,
        (tan_half, start, end),
        correct_opacity,
    )
}

/// [`trace_cone`] with its `(tan_half, start, end)`: up to distance `end` (`svo_cone_to`).
pub fn trace_cone_to(
    pyramid: &Pyramid,
    origin: Vec3,
    dir: Vec3,
    (tan_half, start, end): (f32, f32, f32),
    correct_opacity: bool,
) -> Vec4 {
    let max_level = pyramid.max_level as f32;
    let mut radiance = Vec3::ZERO;
    let mut alpha = 0.0f32;
    let mut t = start;
    for _ in 0..MAX_SAMPLES {
        if t >= end || alpha >= 0.99 {
            break;
        }
        let diameter = (2.0 * t * tan_half).max(1.0);
        let level = (max_level - diameter.log2()).clamp(1.0, max_level);
        let s = pyramid.sample_lod(origin + t * dir, level, dir);
        let step = STEP * diameter;
        if s.w > 0.0 {
            let mut a = s.w;
            if correct_opacity && s.w < 1.0 {
                let size = (max_level - level).exp2();
                a = 1.0 - (1.0 - s.w).powf(step / size);
            }
            radiance += (1.0 - alpha) * a * (s.truncate() / s.w);
            alpha += (1.0 - alpha) * a;
        }
        t += step;
    }
    radiance.extend(alpha)
}

/// `trace.wgsl`'s `GOLDEN_ANGLE`, pi (3 - sqrt 5).
pub const GOLDEN_ANGLE: f32 = 2.399_963_2;

/// An orthonormal basis `[t, u, n]` around the unit `n` (Duff et al. 2017; `trace.wgsl::basis`).
pub fn basis(n: Vec3) -> [Vec3; 3] {
    let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    [
        Vec3::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x),
        Vec3::new(b, s + n.y * n.y * a, -n.y),
        n,
    ]
}

/// Cone `k` of `cones` in the normal's frame (z the normal): equal areas of the unit disc
/// projected up onto the hemisphere, cosine-distributed, along a Fibonacci spiral turned `turn`
/// of a full turn about the normal (`svo.wgsl::svo_cone_direction`).
pub fn cone_direction(k: u32, cones: u32, turn: f32) -> Vec3 {
    let u = (k as f32 + 0.5) / cones as f32;
    let r = u.sqrt();
    let phi = GOLDEN_ANGLE * k as f32 + std::f32::consts::TAU * turn;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u).sqrt())
}

/// tan of the glossy cone's half angle: where the Phong lobe `cos^ns` falls to half, from half
/// a degree to `half_angle` (`trace.wgsl::glossy_tan_half`).
pub fn glossy_tan_half(ns: f32, half_angle: f32) -> f32 {
    let angle = 0.5f32.powf(1.0 / ns.max(1.0)).acos();
    angle.clamp(0.00873, half_angle).tan()
}

/// The mean radiance of `trace.cones` cosine-distributed diffuse cones around the unit `n`
/// from `origin` (leaf voxels), their spiral turned `turn` of a full turn: the irradiance over
/// pi (`svo.wgsl::svo_diffuse`).
pub fn diffuse(
    pyramid: &Pyramid,
    origin: Vec3,
    n: Vec3,
    (trace, turn): (&TraceParams, f32),
    correct_opacity: bool,
) -> Vec3 {
    let [t, u, _] = basis(n);
    let mut sum = Vec3::ZERO;
    for k in 0..trace.cones {
        let d = cone_direction(k, trace.cones, turn);
        let dir = t * d.x + u * d.y + n * d.z;
        let cone = trace_cone(
            pyramid,
            origin,
            dir,
            trace.tan_half,
            trace.start,
            correct_opacity,
        );
        sum += cone.truncate();
    }
    sum / trace.cones as f32
}

/// Ambient occlusion (§6): the mean opacity of the diffuse cones around `n` from `origin`
/// within `radius` leaf voxels (`svo.wgsl::svo_occlusion`).
pub fn occlusion(
    pyramid: &Pyramid,
    origin: Vec3,
    n: Vec3,
    trace: &TraceParams,
    radius: f32,
    correct_opacity: bool,
) -> f32 {
    let [t, u, _] = basis(n);
    let reach = (trace.tan_half, trace.start, trace.start + radius);
    let mut sum = 0.0;
    for k in 0..trace.cones {
        let d = cone_direction(k, trace.cones, 0.0);
        let dir = t * d.x + u * d.y + n * d.z;
        sum += trace_cone_to(pyramid, origin, dir, reach, correct_opacity).w;
    }
    sum / trace.cones as f32
}

/// Every leaf's surface from the fragments, as `radiance.wgsl::surface_of_leaves` sums it:
/// `[albedo r, g, b (0 to 255 a fragment), fragments, normal x, y, z (-127 to 127 a fragment,
/// two's complement), 0]`.
pub fn surface_sums(fragments: &[VoxelFragment]) -> BTreeMap<[u32; 3], [u32; 8]> {
    let mut sums = BTreeMap::new();
    for f in fragments {
        let s: &mut [u32; 8] = sums.entry(f.cell()).or_default();
        let albedo = f.albedo.to_le_bytes();
        let normal = f
            .normal
            .to_le_bytes()
            .map(|b| (b as i8).max(-127) as i32 as u32);
        for k in 0..3 {
            s[k] = s[k].wrapping_add(albedo[k] as u32);
            s[4 + k] = s[4 + k].wrapping_add(normal[k]);
        }
        s[3] += 1;
    }
    sums
}

/// One more bounce of the leaves (`radiance.wgsl::bounce`, §8.1): each leaf's `direct`
/// radiance plus its albedo times what its diffuse cones gather through `pyramid` (the bounces
/// so far), the apex `trace.offset` leaves off the voxel's centre along the fragments' mean
/// normal; a leaf whose normals cancel gathers nothing.
pub fn bounce(
    pyramid: &Pyramid,
    direct: &BTreeMap<[u32; 3], Vec3>,
    surface: &BTreeMap<[u32; 3], [u32; 8]>,
    trace: &TraceParams,
    correct_opacity: bool,
) -> BTreeMap<[u32; 3], Vec3> {
    direct
        .iter()
        .map(|(cell, &light)| {
            let Some(s) = surface.get(cell).filter(|s| s[3] > 0) else {
                return (*cell, light);
            };
            let count = s[3] as f32;
            let normal = Vec3::new(s[4] as i32 as f32, s[5] as i32 as f32, s[6] as i32 as f32);
            if normal.dot(normal) <= count * count {
                return (*cell, light);
            }
            let albedo = Vec3::new(s[0] as f32, s[1] as f32, s[2] as f32) / (255.0 * count);
            let n = normal.normalize();
            let origin = Vec3::from(cell.map(|c| c as f32)) + 0.5 + n * trace.offset;
            let gathered = diffuse(pyramid, origin, n, (trace, 0.0), correct_opacity);
            (*cell, light + albedo * gathered)
        })
        .collect()
}

/// A pixel of the G-buffer.
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// World position.
    pub position: Vec3,
    /// Unit normal.
    pub normal: Vec3,
    /// Diffuse albedo (Kd times the texture).
    pub albedo: Vec3,
    /// Specular albedo of the normalised Phong lobe.
    pub ks: Vec3,
    /// Phong exponent.
    pub ns: f32,
    /// The camera's position.
    pub eye: Vec3,
}

/// The diffuse cones' turn at full-resolution pixel `pixel` (`trace.wgsl::pixel_turn`): a hash
/// of the pixel in [0, 1) when `trace.turn` is set, else 0.
pub fn pixel_turn(trace: &TraceParams, pixel: (u32, u32)) -> f32 {
    if trace.turn == 0 {
        return 0.0;
    }
    use crate::common::random::{hash_unit, pcg_hash};
    hash_unit(pcg_hash(pixel.0.wrapping_add(pixel.1.wrapping_mul(65536))))
}

/// The two planes `trace.wgsl::main` writes for receiver `r` at full-resolution pixel `pixel`:
/// the diffuse irradiance (pi times the mean of the diffuse cones, turned by [`pixel_turn`])
/// and, for a glossy material, the mirror cone times the normalised lobe's integral, without
/// Ks. `common/resolve.wgsl` reflects them: albedo / pi times the first plus Ks times the
/// second.
pub fn trace_planes(
    pyramid: &Pyramid,
    svo: &SvoParams,
    trace: &TraceParams,
    r: &Receiver,
    pixel: (u32, u32),
) -> [Vec3; 2] {
    let n = r.normal;
    let corrected = svo.correct_opacity != 0;
    let origin = (r.position - Vec3::from(svo.origin)) * svo.inv_voxel + n * trace.offset;
    let turn = pixel_turn(trace, pixel);
    let irradiance = std::f32::consts::PI * diffuse(pyramid, origin, n, (trace, turn), corrected);
    let mut glossy = Vec3::ZERO;
    if r.ks.cmpgt(Vec3::ZERO).any() {
        let v = (r.eye - r.position).normalize();
        let mirror = -v - 2.0 * (-v).dot(n) * n;
        let cos_r = n.dot(mirror);
        if cos_r > 0.0 {
            let tan_half = glossy_tan_half(r.ns, trace.half_angle);
            let lobe = trace_cone(pyramid, origin, mirror, tan_half, trace.start, corrected);
            glossy = lobe.truncate() * ((r.ns + 2.0) / (r.ns + 1.0) * cos_r);
        }
    }
    [irradiance, glossy]
}

/// The ambient occlusion view's grey at `r` (`trace.wgsl::main` with `occlusion_radius` above
/// 0): one minus the [`occlusion`] of the diffuse cones within that reach.
pub fn occlusion_view(
    pyramid: &Pyramid,
    svo: &SvoParams,
    trace: &TraceParams,
    r: &Receiver,
) -> f32 {
    let n = r.normal;
    let corrected = svo.correct_opacity != 0;
    let origin = (r.position - Vec3::from(svo.origin)) * svo.inv_voxel + n * trace.offset;
    1.0 - occlusion(pyramid, origin, n, trace, trace.occlusion_radius, corrected)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn one_leaf() -> Pyramid {
        Pyramid::from_leaves(
            2,
            1,
            &BTreeMap::from([([1, 2, 3], Vec3::new(4.0, 2.0, 1.0))]),
        )
    }

    #[test]
    fn each_level_is_the_mean_of_its_children() {
        let p = one_leaf();
        assert_eq!(p.cell(2, [1, 2, 3], 0), Vec4::new(4.0, 2.0, 1.0, 1.0));
        assert_eq!(p.cell(1, [0, 1, 1], 0), Vec4::new(0.5, 0.25, 0.125, 0.125));
        assert_eq!(p.cell(0, [0, 0, 0], 0).w, 1.0 / 64.0);
        assert_eq!(p.cell(2, [4, 0, 0], 0), Vec4::ZERO);
    }

    #[test]
    fn anisotropic_voxels_keep_a_wall_opaque_face_on() {
        // A wall of leaves x = 1 of a 4³ grid: seen along x every coarser voxel is opaque,
        // along y half of it is.
        let leaves = (0..4)
            .flat_map(|y| (0..4).map(move |z| ([1u32, y, z], Vec3::ONE)))
            .collect();
        let p = Pyramid::from_leaves(2, 6, &leaves);
        for face in [0, 1] {
            assert_eq!(p.cell(1, [0, 1, 0], face), Vec4::ONE, "face {face}");
            assert_eq!(p.cell(0, [0, 0, 0], face), Vec4::ONE, "face {face}");
        }
        assert_eq!(p.cell(1, [0, 1, 0], 2), Vec4::splat(0.5));
        // Edge on at the root: two half-opaque voxels in a column, in half the columns.
        assert_eq!(p.cell(0, [0, 0, 0], 3), Vec4::splat(0.375));
        assert_eq!(p.cell(1, [1, 1, 0], 0), Vec4::ZERO);
        let iso = Pyramid::from_leaves(2, 1, &leaves);
        assert_eq!(iso.cell(1, [0, 1, 0], 0), Vec4::splat(0.5));
    }

    #[test]
    fn vertices_are_the_mean_of_the_cells_they_touch() {
        let p = one_leaf();
        // The centre of the leaf is the leaf; a face between it and an empty one, half of it.
        let leaf = p.cell(2, [1, 2, 3], 0);
        assert_eq!(p.vertex(2, [3, 5, 7], 0), leaf);
        assert_eq!(p.vertex(2, [4, 5, 7], 0), leaf * 0.5);
        assert_eq!(p.vertex(2, [4, 4, 8], 0), leaf * 0.125);
    }

    #[test]
    fn samples_interpolate_inside_occupied_parents_only() {
        let p = one_leaf();
        // At the leaf's centre: the leaf; a quarter voxel towards an empty neighbour: 3/4.
        let centre = Vec3::new(1.5, 2.5, 3.5);
        assert_eq!(p.sample(centre, 2, Vec3::X), p.cell(2, [1, 2, 3], 0));
        let off = p.sample(centre + Vec3::new(0.25, 0.0, 0.0), 2, Vec3::X);
        assert!((off.w - 0.75).abs() < 1e-6, "{off}");
        // The parent of cell (3, 2, 3) at level 1 is (1, 1, 1): empty, though the trilinear
        // interpolation would reach the leaf.
        assert_eq!(p.sample(Vec3::new(2.1, 2.5, 3.5), 2, Vec3::X), Vec4::ZERO);
        assert_eq!(p.sample(Vec3::new(-0.1, 2.5, 3.5), 2, Vec3::X), Vec4::ZERO);
    }

    #[test]
    fn a_cone_into_an_opaque_wall_sees_its_radiance() {
        // A wall of leaves at x = 6 of an 8³ grid, radiance 2.
        let leaves = (0..8)
            .flat_map(|y| (0..8).map(move |z| ([6u32, y, z], Vec3::splat(2.0))))
            .collect();
        let p = Pyramid::from_leaves(3, 1, &leaves);
        let thin = trace_cone(&p, Vec3::new(1.0, 4.0, 4.0), Vec3::X, 0.01, 0.5, true);
        assert!(
            thin.w > 0.99 && (thin.x - 2.0 * thin.w).abs() < 1e-3,
            "{thin}"
        );
        // Away from the wall nothing.
        let away = trace_cone(&p, Vec3::new(4.0, 4.0, 4.0), Vec3::NEG_X, 0.01, 0.5, true);
        assert_eq!(away, Vec4::ZERO);
        // A wide cone sees the wall through coarse isotropic voxels, far from opaque (the
        // averaged opacity of §4.2.3); anisotropic voxels keep it opaque face on (§9).
        let wide = trace_cone(&p, Vec3::new(1.0, 4.0, 4.0), Vec3::X, 0.6, 0.5, true);
        assert!(wide.w > 0.2 && wide.w < 0.9 && wide.x > 0.0, "{wide}");
        assert!((wide.x / wide.w - 2.0).abs() < 1e-3, "{wide}");
        let anisotropic = Pyramid::from_leaves(3, 6, &leaves);
        let wide6 = trace_cone(
            &anisotropic,
            Vec3::new(1.0, 4.0, 4.0),
            Vec3::X,
            0.6,
            0.5,
            true,
        );
        assert!(wide6.w > 0.8 && wide6.w > wide.w + 0.2, "{wide6} {wide}");
        assert!((wide6.x / wide6.w - 2.0).abs() < 1e-3, "{wide6}");
    }

    #[test]
    fn a_texel_covers_more_surface_far_and_aslant() {
        let light = GpuSpotLight {
            position: [0.0; 3],
            direction: [0.0, -1.0, 0.0],
            texel_solid_angle: 1e-4,
            ..bytemuck::Zeroable::zeroed()
        };
        let near = texel_area(&light, Vec3::new(0.0, -1.0, 0.0), Vec3::Y);
        assert!((near - 1e-4).abs() < 1e-10);
        let far = texel_area(&light, Vec3::new(0.0, -2.0, 0.0), Vec3::Y);
        assert!((far / near - 4.0).abs() < 1e-4);
        let slanted = Vec3::new(1.0, 1.0, 0.0).normalize();
        let aslant = texel_area(&light, Vec3::new(0.0, -1.0, 0.0), slanted);
        assert!((aslant / near - 2f32.sqrt()).abs() < 1e-4);
        // Off the axis: cos³ of the solid angle, the distance squared, the incidence.
        let off = texel_area(&light, Vec3::new(1.0, -1.0, 0.0), Vec3::Y);
        let c = 0.5f32.sqrt();
        assert!((off / near - c * c * c * 2.0 / c).abs() < 1e-4, "{off}");
    }

    #[test]
    fn cones_are_cosine_distributed_over_the_hemisphere() {
        let cones = 64;
        let dirs: Vec<Vec3> = (0..cones).map(|k| cone_direction(k, cones, 0.0)).collect();
        assert!(
            dirs.iter()
                .all(|d| (d.length() - 1.0).abs() < 1e-5 && d.z > 0.0)
        );
        // The mean cosine of a cosine-distributed direction is 2/3.
        let mean = dirs.iter().map(|d| d.z).sum::<f32>() / cones as f32;
        assert!((mean - 2.0 / 3.0).abs() < 0.01, "{mean}");
        for n in [Vec3::X, Vec3::NEG_Z, Vec3::new(0.3, -0.8, 0.52).normalize()] {
            let [t, u, n2] = basis(n);
            assert!(t.dot(u).abs() < 1e-5 && t.dot(n).abs() < 1e-5 && n2 == n);
            assert!((t.cross(u) - n).length() < 1e-5);
        }
    }

    #[test]
    fn a_sharper_lobe_gets_a_narrower_cone() {
        let half = 7.5f32.to_radians();
        assert!(glossy_tan_half(1000.0, half) < glossy_tan_half(100.0, half));
        assert_eq!(glossy_tan_half(1.0, half), half.tan());
        assert_eq!(glossy_tan_half(1e9, half), 0.00873f32.tan());
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
            faces: 1,
            correct_opacity: 0,
            inner_bricks: 0,
            brick_capacity: 1,
        };
        // A floor on the boundary y = 1 between two occupied layers, lit from above.
        let occupied = BTreeSet::from([[1, 0, 1], [1, 1, 1]]);
        let texel = RsmTexel {
            position: Vec4::new(1.5, 1.0, 1.5, 1.0),
            normal: Vec3::Y,
            flux: Vec3::new(1.0, 0.5, 0.0),
            area: 0.25,
        };
        let sums = inject(&params, [texel, texel], &occupied, 1000.0);
        assert_eq!(
            sums,
            BTreeMap::from([([1, 1, 1], [2000, 1000, 0, 1 << 23])])
        );
        // Flux 2 W on half a voxel's face, 1000 units per W: 2 / (pi 0.5).
        let radiance = leaf_radiance(sums[&[1, 1, 1]], 1.0 / (1000.0 * std::f32::consts::PI));
        assert!(
            (radiance.x - 4.0 / std::f32::consts::PI).abs() < 1e-5,
            "{radiance}"
        );
        // Nudged into an empty voxel: the point's own.
        let near_top = RsmTexel {
            position: Vec4::new(1.5, 1.9, 1.5, 1.0),
            ..texel
        };
        let sums = inject(&params, [near_top], &occupied, 1000.0);
        assert_eq!(sums.keys().collect::<Vec<_>>(), [&[1, 1, 1]]);
    }
}
