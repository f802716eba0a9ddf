//! The CPU twin of `sample.wgsl`: the same sampling pattern, visibility and arithmetic for one
//! receiver, given the reflective shadow map as read back. `tests/gpu.rs`
//! (`rsm_sampling_matches_cpu_twin`) holds the GPU to it; the path tracer measures how far
//! both are from the light (`reports/runtime.md`).

use glam::{Vec2, Vec3, Vec4};

use crate::{
    common::random::hash_unit,
    gpu_types::{GpuMaterial, GpuSpotLight},
};

use super::{RsmOptions, Visibility};

/// One light's reflective shadow map, read back (row-major, row 0 at the top).
#[derive(Clone, Debug)]
pub struct CpuRsm {
    /// Texels per side.
    pub resolution: u32,
    /// xyz world position, w 1 where covered.
    pub position: Vec<Vec4>,
    /// xyz normal turned towards the light.
    pub normal: Vec<Vec4>,
    /// rgb reflected flux.
    pub flux: Vec<Vec4>,
}

/// A receiver: a G-buffer pixel.
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// The full-resolution pixel it stands for (its per-pixel rotation and scale).
    pub pixel: (u32, u32),
    /// World position.
    pub position: Vec3,
    /// Unit normal (towards the eye).
    pub normal: Vec3,
    /// Its material (the glossy lobe's exponent).
    pub material: GpuMaterial,
    /// The eye.
    pub eye: Vec3,
}

/// `sample.wgsl::hash`: Chris Wellons' lowbias32 integer hash.
pub fn hash(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// The receiver's per-pixel rotation (a fraction of a sector) and radius scale (§3.2: one
/// base pattern, slightly rotated and scaled per pixel).
pub fn pixel_variation(pixel: (u32, u32)) -> (f32, f32) {
    let key = pixel.0.wrapping_add(pixel.1.wrapping_mul(65_536));
    (
        hash_unit(hash(key ^ 0x1b87_3593)),
        0.9 + 0.2 * hash_unit(hash(key ^ 0x5bd1_e995)),
    )
}

/// Where the base pattern puts sample `k` of path `j`: the angle's jitter in [-0.5, 0.5) of
/// a quarter sector and the radius' stratum offset in [0, 1) (Algorithm 1, lines 4-5).
pub fn base_jitter(j: u32, k: u32) -> (f32, f32) {
    let key = j * 1024 + k;
    (
        hash_unit(hash(key)) - 0.5,
        hash_unit(hash(key ^ 0x68e3_1da4)),
    )
}

/// Gathers the indirect light at `r` from `rsms` (one per light in `lights`): rgb diffuse
/// irradiance and rgb glossy lobe-weighted irradiance (the `sample.wgsl` output, two planes).
pub fn gather(
    rsms: &[CpuRsm],
    lights: &[GpuSpotLight],
    r: &Receiver,
    params: &RsmOptions,
) -> [Vec3; 2] {
    let mut diffuse = Vec3::ZERO;
    let mut glossy = Vec3::ZERO;
    let view = (r.eye - r.position).normalize();
    let (rotation, scale) = pixel_variation(r.pixel);
    let paths = params.paths;
    let samples = params.path_samples;
    let sector = std::f32::consts::TAU / paths as f32;
    let radius = params.radius * scale;
    for (rsm, light) in rsms.iter().zip(lights) {
        let view_proj = glam::Mat4::from_cols_array_2d(&light.view_proj);
        // The paths' origin: the receiver's projection, the map's nearest point for a
        // receiver beside the light's view, the map's centre for one behind the light.
        let clip = view_proj * r.position.extend(1.0);
        let projection = if clip.w > 0.0 {
            let ndc = Vec2::new(clip.x, clip.y) / clip.w;
            Vec2::new(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5).clamp(Vec2::ZERO, Vec2::ONE)
        } else {
            Vec2::splat(0.5)
        };
        let n_side = rsm.resolution as f32;
        let light_position = Vec3::from(light.position);
        let axis = Vec3::from(light.direction);
        for j in 0..paths {
            // §3.3, Algorithm 6: the micro linear buffer, reset for every path.
            let mut slots = [1.0f32; super::MAX_SLOTS as usize];
            let mut previous: Option<(u32, f32)> = None;
            for k in 0..samples {
                let (jitter_angle, jitter_radius) = base_jitter(j, k);
                let theta = sector * (rotation + j as f32 + 0.5 + 0.5 * jitter_angle);
                let u = (k as f32 + jitter_radius) / samples as f32;
                let rho = radius * u * u;
                let at = projection + rho * Vec2::new(theta.cos(), theta.sin());
                if at.x < 0.0 || at.y < 0.0 || at.x >= 1.0 || at.y >= 1.0 {
                    continue;
                }
                let texel = (at * n_side).floor();
                let index = (texel.y as u32 * rsm.resolution + texel.x as u32) as usize;
                let p = rsm.position[index];
                if p.w <= 0.0 {
                    continue;
                }
                let sender = p.truncate();
                let d = sender - r.position;
                let d2 = d.dot(d);
                if d2 <= 0.0 {
                    continue;
                }
                let visible = match params.visibility {
                    Visibility::None => 1.0,
                    Visibility::MicroBuffer => {
                        let dz = d.dot(axis);
                        let lateral = (d - dz * axis).length();
                        let elevation = (-dz).atan2(lateral);
                        let slot = super::slot_of(elevation, params.slots);
                        let v = match previous {
                            Some((last, v)) if last == slot => v,
                            _ => {
                                let v = slots[slot as usize];
                                slots[slot as usize] -= 1.0;
                                v
                            }
                        };
                        previous = Some((slot, v));
                        v.clamp(0.0, 1.0)
                    }
                };
                let n_p = rsm.normal[index].truncate();
                let cos_product = n_p.dot(-d).max(0.0) * r.normal.dot(d).max(0.0) / d2;
                let to_sender = sender - light_position;
                let light_d2 = to_sender.dot(to_sender);
                let cos_axis = to_sender.dot(axis) / light_d2.sqrt();
                let cos_light = (n_p.dot(-to_sender) / light_d2.sqrt()).abs().max(0.05);
                let area = light.texel_solid_angle * cos_axis.powi(3) * light_d2 / cos_light;
                let phi = rsm.flux[index].truncate();
                let irradiance =
                    phi / std::f32::consts::PI * cos_product / (d2 + area / std::f32::consts::PI);
                let weight =
                    2.0 * sector * radius * radius * u * u * u / samples as f32 * n_side * n_side;
                let e = (visible * weight) * irradiance;
                diffuse += e;
                let l = d / d2.sqrt();
                let mirrored = -l - 2.0 * (-l).dot(r.normal) * r.normal;
                let ns = r.material.ns;
                let lobe =
                    (ns + 2.0) / std::f32::consts::TAU * mirrored.dot(view).max(0.0).powf(ns);
                glossy += e * lobe;
            }
        }
    }
    [diffuse, glossy]
}
