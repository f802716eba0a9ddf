//! CPU reference of the direct light: the shading of `light.wgsl` with exact shadows, ray cast
//! with obvhs (`cssm_bake::raycast::SceneBvh`) through the same pixel centres the rasteriser
//! samples.

use cssm_bake::raycast::SceneBvh;
use cssm_formats::{CssmFile, Scene};
use glam::Vec3;
use rayon::prelude::*;

use crate::{common::camera::View, gpu_types::GpuMaterial, load::AlbedoTexture};

/// What the CPU reference saw at one pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CpuPixel {
    /// Linear radiance towards the eye.
    pub radiance: Vec3,
    /// Triangle seen, `u32::MAX` for background.
    pub triangle: u32,
    /// Bit `i` set when light `i` reaches the point (inside its cone, on the front side,
    /// unshadowed).
    pub lit: u32,
}

/// Irradiance at `p` (normal `n`) from `light`, and whether the light reaches `p`.
fn spot_irradiance(
    light: &cssm_formats::scene::SpotLight,
    bvh: &SceneBvh,
    eps: f32,
    p: Vec3,
    n: Vec3,
) -> Option<(Vec3, Vec3)> {
    let to_light = light.position - p;
    let dist2 = to_light.dot(to_light);
    let l = to_light / dist2.sqrt();
    let cos_i = n.dot(l);
    let dir = light.direction.normalize();
    if cos_i <= 0.0 || (-l).dot(dir) < light.cutoff_deg.to_radians().cos() {
        return None;
    }
    if !bvh.segment_clear(p + n * eps, light.position) {
        return None;
    }
    Some((Vec3::from(light.intensity) * (cos_i / dist2), l))
}

/// Direct radiance per pixel of `view`, row-major, row 0 at the top.
pub fn render_screen(
    scene: &Scene,
    view: &View,
    materials: &[GpuMaterial],
    textures: &[AlbedoTexture],
    bvh: &SceneBvh,
) -> Vec<CpuPixel> {
    let eps = 1e-4 * scene.diameter();
    let (w, h) = (view.width, view.height);
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let dir = view.primary_ray(x, y);
            let Some((t, triangle)) = bvh.closest_hit(view.eye, dir, 0.0, f32::INFINITY) else {
                return CpuPixel {
                    triangle: u32::MAX,
                    ..Default::default()
                };
            };
            let p = view.eye + dir * t;
            let [a, b, c] = scene.triangle(triangle as usize);
            let mut n = (b - a).cross(c - a).normalize_or_zero();
            if n.dot(view.eye - p) < 0.0 {
                n = -n;
            }
            let m = &materials[scene.triangle_materials[triangle as usize] as usize];
            let mut albedo = Vec3::from(m.kd);
            if m.texture >= 0 && !scene.texcoords.is_empty() {
                let bary = barycentric(p, a, b, c);
                let idx = scene.triangles[triangle as usize];
                let uv = idx.iter().zip(bary).fold([0.0f32; 2], |acc, (&v, w)| {
                    let t = scene.texcoords[v as usize];
                    [acc[0] + t[0] * w, acc[1] + t[1] * w]
                });
                albedo *= textures[m.texture as usize].sample(uv);
            }
            let v = -dir;
            let mut radiance = Vec3::ZERO;
            let mut lit = 0;
            for (k, light) in scene.lights.iter().enumerate() {
                let Some((e, l)) = spot_irradiance(light, bvh, eps, p, n) else {
                    continue;
                };
                lit |= 1 << k.min(31);
                let r = (-l).reflect(n);
                let lobe = Vec3::from(m.ks)
                    * ((m.ns + 2.0) / (2.0 * std::f32::consts::PI) * r.dot(v).max(0.0).powf(m.ns));
                radiance += (albedo / std::f32::consts::PI + lobe) * e;
            }
            CpuPixel {
                radiance,
                triangle,
                lit,
            }
        })
        .collect()
}

/// Barycentric coordinates of `p` in triangle (`a`, `b`, `c`).
pub fn barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> [f32; 3] {
    let (v0, v1, v2) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
    let (d20, d21) = (v2.dot(v0), v2.dot(v1));
    let denom = d00 * d11 - d01 * d01;
    if denom == 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    [1.0 - v - w, v, w]
}

/// Diffuse radiance leaving every texel of `file` (front side), in texel order: Kd/pi times the
/// exact irradiance.
pub fn render_atlas(scene: &Scene, file: &CssmFile, bvh: &SceneBvh) -> Vec<Vec3> {
    let eps = 1e-4 * scene.diameter();
    file.texels
        .par_iter()
        .map(|t| {
            let (p, n) = (t.pos(), t.nrm());
            let e: Vec3 = scene
                .lights
                .iter()
                .filter_map(|l| spot_irradiance(l, bvh, eps, p, n).map(|(e, _)| e))
                .sum();
            Vec3::from(scene.materials[t.material as usize].kd) / std::f32::consts::PI * e
        })
        .collect()
}
