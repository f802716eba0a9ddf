//! CPU reference of the direct light: the shading of `light.wgsl` with exact shadows, ray cast
//! with obvhs (`cssm_raycast::SceneBvh`) through the same pixel centres the rasteriser
//! samples, plus the radiance a surface seen from its front emits (the G-buffer's emission,
//! [`emitted_radiance`]).
//!
//! Its shading pieces (light, BRDF, albedo, facing and normal-mapped shading normal) are shared
//! with the path tracer, [`crate::reference`], so the two see the same scene. The atlas
//! ([`render_atlas`]) keeps the geometric normals, as the bake's texels do.

use cssm_formats::{Scene, texel::Texel};
use cssm_raycast::SceneBvh;
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
    /// Unit shading normal turned towards the eye (normal-mapped): the G-buffer's normal.
    pub normal: Vec3,
}

/// Irradiance at `p` (normal `n`) from `light`, and the unit direction to the light, when the
/// light reaches `p` (inside its cone, on the front side, and an exact shadow ray from `p` lifted
/// by `eps` along `n` is clear).
pub(crate) fn spot_irradiance(
    light: &cssm_formats::scene::SpotLight,
    bvh: &SceneBvh,
    eps: f32,
    p: Vec3,
    n: Vec3,
) -> Option<(Vec3, Vec3)> {
    shaded_spot_irradiance(light, bvh, eps, p, n, n)
}

/// [`spot_irradiance`] at a point whose shading normal `shading` (normal-mapped,
/// [`shading_normal`]) differs from its geometric normal `geometric` (both on the side the
/// light is reflected to): the cosine is the shading normal's, the side and the shadow ray's
/// lift the geometric normal's (a light below the surface does not reach it, whatever the
/// shading normal says).
pub(crate) fn shaded_spot_irradiance(
    light: &cssm_formats::scene::SpotLight,
    bvh: &SceneBvh,
    eps: f32,
    p: Vec3,
    geometric: Vec3,
    shading: Vec3,
) -> Option<(Vec3, Vec3)> {
    let to_light = light.position - p;
    let dist2 = to_light.dot(to_light);
    let l = to_light / dist2.sqrt();
    let cos_i = shading.dot(l);
    let dir = light.direction.normalize();
    if cos_i <= 0.0
        || geometric.dot(l) <= 0.0
        || (-l).dot(dir) < light.cutoff_deg.to_radians().cos()
    {
        return None;
    }
    if !bvh.segment_clear(p + geometric * eps, light.position) {
        return None;
    }
    Some((Vec3::from(light.intensity) * (cos_i / dist2), l))
}

/// The offset that lifts ray origins off a surface of `scene` (shadow rays, path continuations).
pub fn ray_epsilon(scene: &Scene) -> f32 {
    1e-4 * scene.diameter()
}

/// Unit geometric (flat) normal of `triangle`, flipped to the side of `towards` (the direction
/// from the surface point to the viewer or the previous path vertex): surfaces are two-sided.
pub fn facing_normal(scene: &Scene, triangle: u32, towards: Vec3) -> Vec3 {
    let [a, b, c] = scene.triangle(triangle as usize);
    let n = (b - a).cross(c - a).normalize_or_zero();
    if n.dot(towards) < 0.0 { -n } else { n }
}

/// Texture coordinates at `p` on `triangle` (zero when the mesh has none), interpolated as the
/// rasteriser does.
fn texcoords_at(scene: &Scene, triangle: u32, p: Vec3) -> [f32; 2] {
    if scene.texcoords.is_empty() {
        return [0.0; 2];
    }
    let [a, b, c] = scene.triangle(triangle as usize);
    let bary = barycentric(p, a, b, c);
    let idx = scene.triangles[triangle as usize];
    idx.iter().zip(bary).fold([0.0f32; 2], |acc, (&v, w)| {
        let t = scene.texcoords[v as usize];
        [acc[0] + t[0] * w, acc[1] + t[1] * w]
    })
}

/// The shading normal at `p` on `triangle`: its geometric normal `n` (turned to the side it is
/// seen from, [`facing_normal`]) tilted by the material's normal map in the triangle's flat
/// tangent frame, as the G-buffer pass does (`gbuffer.wgsl`, [`crate::normal_map::perturb`]);
/// `n` itself without a normal map, texture coordinates or a frame.
pub fn shading_normal(
    scene: &Scene,
    m: &GpuMaterial,
    textures: &[AlbedoTexture],
    triangle: u32,
    p: Vec3,
    n: Vec3,
) -> Vec3 {
    if m.normal_texture < 0 || scene.texcoords.is_empty() {
        return n;
    }
    let [tx, ty, tz, handedness] = crate::load::triangle_tangent(scene, triangle as usize);
    if handedness == 0.0 {
        return n;
    }
    // The frame turns with the normal (the back's normal is the front's negated).
    let winding = front_normal(scene, triangle);
    let side = if winding.dot(n) < 0.0 { -1.0 } else { 1.0 };
    let tangent = Vec3::new(tx, ty, tz);
    let t = tangent * side;
    let b = winding.cross(tangent) * (handedness * side);
    let Some(map) = textures.get(m.normal_texture as usize) else {
        return n;
    };
    let sample = map.sample(texcoords_at(scene, triangle, p));
    crate::normal_map::perturb(sample, n, t, b)
}

/// Albedo at `p` on `triangle`: the material's Kd times its albedo texture, sampled as the
/// G-buffer pass does.
pub fn albedo_at(
    scene: &Scene,
    m: &GpuMaterial,
    textures: &[AlbedoTexture],
    triangle: u32,
    p: Vec3,
) -> Vec3 {
    let mut albedo = Vec3::from(m.kd);
    if m.texture >= 0 && !scene.texcoords.is_empty() {
        albedo *= textures[m.texture as usize].sample(texcoords_at(scene, triangle, p));
    }
    albedo
}

/// The radiance `triangle` emits at `p` from its front side (the material's emission times its
/// emission texture, sampled as the G-buffer pass does), whichever side it is seen from.
pub(crate) fn emission_at(
    scene: &Scene,
    m: &GpuMaterial,
    textures: &[AlbedoTexture],
    triangle: u32,
    p: Vec3,
) -> Vec3 {
    let mut emission = Vec3::from(m.emission);
    if m.emission_texture >= 0 && emission.cmpgt(Vec3::ZERO).any() {
        let uv = texcoords_at(scene, triangle, p);
        emission *= textures[m.emission_texture as usize].sample(uv);
    }
    emission
}

/// Unit geometric normal of `triangle` from its winding: the front side, the one that emits.
pub(crate) fn front_normal(scene: &Scene, triangle: u32) -> Vec3 {
    let [a, b, c] = scene.triangle(triangle as usize);
    (b - a).cross(c - a).normalize_or_zero()
}

/// The radiance `triangle` emits at `p` towards `towards` (the direction to the viewer, any
/// length): its emission where `towards` is on its front side (as `gbuffer.wgsl` decides the
/// side, `n . towards >= 0`), zero on its back. Emission is one-sided, as pbrt's and Mitsuba's
/// area lights are by default.
pub fn emitted_radiance(
    scene: &Scene,
    m: &GpuMaterial,
    textures: &[AlbedoTexture],
    triangle: u32,
    p: Vec3,
    towards: Vec3,
) -> Vec3 {
    if front_normal(scene, triangle).dot(towards) < 0.0 {
        return Vec3::ZERO;
    }
    emission_at(scene, m, textures, triangle, p)
}

/// The BRDF of `light.wgsl` for the unit light direction `l` and view direction `v` at normal
/// `n`: `albedo / pi + Ks (Ns + 2) / (2 pi) max(0, reflect(-l, n) . v)^Ns` (Lambert plus
/// normalised Phong).
pub(crate) fn brdf(albedo: Vec3, m: &GpuMaterial, l: Vec3, n: Vec3, v: Vec3) -> Vec3 {
    let r = (-l).reflect(n);
    let lobe = Vec3::from(m.ks)
        * ((m.ns + 2.0) / (2.0 * std::f32::consts::PI) * r.dot(v).max(0.0).powf(m.ns));
    albedo / std::f32::consts::PI + lobe
}

/// Radiance leaving `p` (geometric normal `ng`, shading normal `n`, both on the side of the
/// unit direction `v`) under every light of `scene`, exactly shadowed, and the lights that
/// reach `p` as a bit set (bit `min(i, 31)`). The cosine and the BRDF take the shading normal,
/// the side and the shadow ray the geometric one ([`shaded_spot_irradiance`]).
#[allow(clippy::too_many_arguments)]
pub fn direct_radiance(
    scene: &Scene,
    bvh: &SceneBvh,
    eps: f32,
    p: Vec3,
    ng: Vec3,
    n: Vec3,
    v: Vec3,
    albedo: Vec3,
    m: &GpuMaterial,
) -> (Vec3, u32) {
    let mut radiance = Vec3::ZERO;
    let mut lit = 0;
    for (k, light) in scene.lights.iter().enumerate() {
        let Some((e, l)) = shaded_spot_irradiance(light, bvh, eps, p, ng, n) else {
            continue;
        };
        lit |= 1 << k.min(31);
        radiance += brdf(albedo, m, l, n, v) * e;
    }
    (radiance, lit)
}

/// Direct radiance per pixel of `view`, row-major, row 0 at the top: the spot lights' light
/// reflected once, plus what the surface emits towards the eye ([`emitted_radiance`]).
pub fn render_screen(
    scene: &Scene,
    view: &View,
    materials: &[GpuMaterial],
    textures: &[AlbedoTexture],
    bvh: &SceneBvh,
) -> Vec<CpuPixel> {
    let eps = ray_epsilon(scene);
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
            let ng = facing_normal(scene, triangle, view.eye - p);
            let m = &materials[scene.triangle_materials[triangle as usize] as usize];
            let n = shading_normal(scene, m, textures, triangle, p, ng);
            let albedo = albedo_at(scene, m, textures, triangle, p);
            let (reflected, lit) = direct_radiance(scene, bvh, eps, p, ng, n, -dir, albedo, m);
            let emitted = emitted_radiance(scene, m, textures, triangle, p, view.eye - p);
            CpuPixel {
                radiance: reflected + emitted,
                triangle,
                lit,
                normal: n,
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

/// What a texel reflects in the view-independent bounces of the atlas (§4.1): Kd (times its
/// texture's mean: pass [`crate::gpu_types::GpuMaterial::kd_mean`]) plus Ks, clamped to 1, the glossy lobe's energy (Ks of light along the normal, for the normalised
/// Phong) sent out diffusely instead of lost. `light.wgsl`: `bounce_albedo`.
///
/// ```
/// let rho = cssm_runtime::direct::cpu::bounce_albedo([0.25; 3], [0.5; 3]);
/// assert_eq!(rho, glam::Vec3::splat(0.75));
/// assert_eq!(cssm_runtime::direct::cpu::bounce_albedo([0.8; 3], [0.5; 3]).x, 1.0);
/// ```
pub fn bounce_albedo(kd: [f32; 3], ks: [f32; 3]) -> Vec3 {
    (Vec3::from(kd) + Vec3::from(ks)).min(Vec3::ONE)
}

/// Diffuse radiance leaving every texel of `texels` (front side), in texel order: [`bounce_albedo`] over pi
/// times the exact irradiance, plus the radiance its material emits (`emission_mean` of `materials`,
/// the scene's as [`crate::load::cpu_materials`] makes them): the source of the radiosity
/// (§4.7). `texels` are a file's, each where its object stands in `scene` and `bvh` (the file's
/// own as baked, or `cssm_formats::moving::posed_texels` of them in the posed scene, §3.3).
pub fn render_atlas(
    scene: &Scene,
    materials: &[GpuMaterial],
    texels: &[Texel],
    bvh: &SceneBvh,
) -> Vec<Vec3> {
    let eps = ray_epsilon(scene);
    texels
        .par_iter()
        .map(|t| {
            let (p, n) = (t.pos(), t.nrm());
            let e: Vec3 = scene
                .lights
                .iter()
                .filter_map(|l| spot_irradiance(l, bvh, eps, p, n).map(|(e, _)| e))
                .sum();
            let m = &materials[t.material as usize];
            bounce_albedo(m.kd_mean, m.ks) / std::f32::consts::PI * e + Vec3::from(m.emission_mean)
        })
        .collect()
}
