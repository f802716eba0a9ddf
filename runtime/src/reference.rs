//! The CPU path tracer: ground truth for the global-illumination methods.
//!
//! [`render_reference`] renders the scene's light transport by Monte Carlo path tracing on the
//! CPU, with exact ray casts (`cssm_raycast::SceneBvh`) for every visibility, so the
//! images of the GPU methods (direct light, and the CSSM-based indirect bounces of the paper,
//! Ritschel et al. 2008, §4) can be compared with it pixel by pixel.
//!
//! # What it simulates
//!
//! The scene model of the direct light (`direct/light.wgsl`, [`crate::direct::cpu`]), extended
//! to interreflections:
//!
//! - **Lights**: the scene's spot lights, points of constant radiant intensity inside their cone
//!   and none outside, falling off with `1 / d^2`. No path can hit a point light, so their
//!   light reaches a path by next-event estimation (NEE) alone: at every vertex, one exact
//!   shadow ray per light, from the point lifted by `1e-4` of the scene diameter along its
//!   normal, as in `direct::cpu`.
//! - **Emitters** (area lights): every triangle whose material emits (MTL `Ke`, glTF emissive)
//!   sends its emitted radiance (times its emission texture) from its *front* side only, the
//!   side its winding normal faces, as pbrt's and Mitsuba's area lights do by default. A camera
//!   ray that meets an emitter's front sees its radiance; at every vertex a path samples one
//!   point on the emitters (a triangle chosen in proportion to its power, area times the
//!   luminance of its mean emission, then a uniform point on it) with an exact shadow ray, and
//!   a continuation that meets an emitter's front collects its radiance too; the two
//!   strategies are combined by multiple importance sampling with the power heuristic (Veach
//!   and Guibas 1995), so neither the small bright panel (light sampling wins) nor a large dim
//!   emitter seen up close (BSDF sampling wins) is noisy. [`EmitterSampling`] can keep one
//!   strategy alone, for tests.
//! - **Surfaces**: two-sided, with the geometric (flat) normal flipped towards the incoming ray;
//!   BRDF `albedo / pi + Ks (Ns + 2) / (2 pi) max(0, reflect(-l, n) . v)^Ns` (Lambert plus
//!   normalised Phong) at *every* vertex, `albedo` being Kd times the material's albedo texture
//!   sampled as the G-buffer pass does.
//! - **Camera**: one primary ray per pixel through the pixel centre, as the rasteriser samples
//!   (no anti-aliasing: the comparison is pixel by pixel), traced once per pixel; the direct
//!   light at the first vertex is therefore exact (no noise) and equals
//!   [`crate::direct::cpu::render_screen`].
//! - **Paths**: from the first vertex, [`ReferenceOptions::samples_per_pixel`] paths of at most
//!   [`ReferenceOptions::bounces`] indirect bounces each. A bounce picks the diffuse lobe or the
//!   glossy lobe with probabilities proportional to the mean albedo and the mean Ks, samples a
//!   cosine-weighted direction (diffuse) or a direction of the Phong lobe `cos^Ns` around the
//!   mirror direction (glossy), and weights the path by `BRDF cos / pdf` with the pdf of the
//!   mixture of both lobes; a direction below the surface or a ray that leaves the scene ends
//!   the path. There is no Russian roulette: the estimate of the light transport truncated after
//!   `bounces` bounces (the Neumann series up to that term) is unbiased, unless
//!   [`ReferenceOptions::clamp`] is set.
//!
//! # Direct and indirect ([`Component`])
//!
//! The split follows the GPU's: *direct* is what the direct-light pass computes, the spot
//! lights' light reflected once at the first vertex plus the radiance the first vertex emits
//! towards the eye. An emitter's light reflected by another surface is *indirect*, as on the
//! GPU, where the emitters are the radiosity's source (§4.7: any direct light may be) and
//! reach other surfaces through the methods' first bounce. So `bounces` counts bounces after
//! the direct light of each source: with `B` bounces the image holds a spot light's light
//! reflected 1 to `B + 1` times and an emitter's light reflected 0 to `B` times (an emitter's
//! light is sampled at the path's vertices 0 to `B - 1`, the light of the spot lights at
//! vertices 0 to `B`), which is what the GPU methods compute with `B` bounces.
//!
//! Not simulated: transmission, participating media, normal maps, depth of field and motion.
//!
//! # Determinism and cost
//!
//! Pixel `i` draws its random numbers from its own SplitMix64 stream, started from `seed` and
//! `i`, so an image depends on the options only, never on the number of rayon threads. Rows are
//! rendered in parallel into one preallocated image; a path allocates nothing. A pixel costs one
//! primary ray and one shadow ray per light, plus, per path and bounce, one continuation ray,
//! one shadow ray per light and, when the scene has emitters, one shadow ray to a point on
//! them. A scene without emitters draws the same random numbers as before emitters existed.

use std::sync::atomic::{AtomicU64, Ordering};

use cssm_formats::Scene;
use cssm_raycast::{SceneBvh, SplitMix64};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::{
    RuntimeError,
    common::{
        camera::View,
        converge::{BouncePlan, Convergence, run_plan},
        tonemap::luminance,
    },
    direct::cpu::{
        albedo_at, brdf, direct_radiance, emission_at, emitted_radiance, facing_normal,
        front_normal, ray_epsilon, shading_normal,
    },
    gpu_types::GpuMaterial,
    load::AlbedoTexture,
    method::{self, Backend, Checks, Energy, CpuSetup, MethodEntry, OptionKind, OptionSpec},
};

/// `--method reference`: this path tracer, on the CPU, the ground truth of every other method.
pub const METHOD: MethodEntry = MethodEntry {
    name: "reference",
    summary: "CPU path tracer with exact ray casts (obvhs, rayon): ground truth",
    needs_cssm: false,
    options: &[
        method::BOUNCES,
        OptionSpec {
            name: "samples",
            help: "paths per pixel",
            kind: OptionKind::Count {
                default: 256,
                min: 1,
                max: 1 << 20,
            },
        },
    ],
    passes: &[],
    backend: Backend::Cpu(render_method),
    checks: Checks {
        energy: Energy::Within(0.02),
        emissive: Energy::Within(0.02),
        ..Checks::DEFAULT
    },
};

/// The path tracer runs on the CPU: no WGSL.
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet::NONE;

/// [`METHOD`]'s entry point: the scene's materials and textures as the GPU sees them, a BVH,
/// then [`render_reference`].
fn render_method(setup: &CpuSetup) -> Result<Vec<[f32; 4]>, RuntimeError> {
    crate::frame::check_size(setup.view.width, setup.view.height)?;
    let (materials, textures) = crate::load::cpu_materials(setup.scene)?;
    let bvh = SceneBvh::new(setup.scene);
    let plan = BouncePlan::from_option(setup.options.count("bounces"));
    let options = ReferenceOptions {
        samples_per_pixel: setup.options.count("samples"),
        bounces: plan.max,
        converge: plan.fraction,
        component: setup.component,
        ..Default::default()
    };
    let (image, convergence) = render_reference_converging(
        setup.scene,
        setup.view,
        &materials,
        &textures,
        &bvh,
        &options,
        setup.progress,
    );
    if let Some(convergence) = convergence {
        (setup.on_bounces)(convergence);
    }
    Ok(image.iter().map(|c| [c.x, c.y, c.z, 1.0]).collect())
}

pub use crate::common::compose::Component;

/// The version of the light model the path tracer simulates, for caches of its images: 2 since
/// emissive surfaces are one-sided area lights (1: spot lights only).
pub const LIGHT_MODEL: u32 = 2;

/// Options of [`render_reference`].
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceOptions {
    /// Paths per pixel (0 counts as 1). The noise of the indirect light falls as one over its
    /// square root; the direct light at the first vertex is exact whatever the count.
    pub samples_per_pixel: u32,
    /// Indirect bounces of a path at most: 0 = direct light only, 1 = one bounce of indirect
    /// light, and so on.
    pub bounces: u32,
    /// Above 0: the image ends at the first bounce that adds at most this share of its light
    /// (Rec. 709 luminance of the image's mean), the bounces after it left out, as the GPU
    /// methods' converged runs end (`crate::common::converge`); every path is still traced
    /// `bounces` deep, each bounce's light kept apart (12 bytes a pixel a bounce). 0 (the
    /// default): every bounce of `bounces`.
    pub converge: f32,
    /// Which light paths the image holds.
    pub component: Component,
    /// Seed of the random numbers; the same options give the same image.
    pub seed: u64,
    /// `Some(c)` (with `c > 0`): each path's indirect radiance is scaled down so that its
    /// largest channel is at most `c`, which removes fireflies at the price of a bias (darker).
    /// `None` (the default): unbiased.
    pub clamp: Option<f32>,
    /// How paths find the emitters' light (the default: both strategies, weighted by MIS).
    pub emitters: EmitterSampling,
}

impl Default for ReferenceOptions {
    /// 256 paths per pixel, 3 bounces, the full light, seed 0, no clamping, MIS.
    fn default() -> Self {
        Self {
            samples_per_pixel: 256,
            bounces: 3,
            converge: 0.0,
            component: Component::Full,
            seed: 0,
            clamp: None,
            emitters: EmitterSampling::Mis,
        }
    }
}

/// How a path gathers the light of emissive surfaces (area lights). Each strategy alone is
/// unbiased too; they differ in noise. The spot lights are always sampled (NEE).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EmitterSampling {
    /// Light sampling and BSDF sampling, combined by multiple importance sampling with the
    /// power heuristic (Veach and Guibas 1995): the default.
    #[default]
    Mis,
    /// Light sampling only: a point on the emitters per vertex; a continuation that meets an
    /// emitter collects nothing from it.
    Light,
    /// BSDF sampling only: the light of an emitter the continuation meets.
    Bsdf,
}

/// The emitting triangles of a scene, for sampling points on them in proportion to their
/// power (area times the luminance of their mean emission).
struct Emitters {
    /// Emitting triangles.
    triangles: Vec<u32>,
    /// Cumulative probability of choosing `triangles[..=i]`; the last is 1.
    cdf: Vec<f64>,
    /// Per scene triangle, the density of the sampled point per unit area (its choice
    /// probability over its area), zero for triangles that do not emit.
    area_pdf: Vec<f32>,
}

impl Emitters {
    fn new(scene: &Scene, materials: &[GpuMaterial]) -> Self {
        let mut triangles = Vec::new();
        let mut power = Vec::new();
        for t in 0..scene.triangles.len() {
            let m = &materials[scene.triangle_materials[t] as usize];
            let [a, b, c] = scene.triangle(t);
            let area = 0.5 * (b - a).cross(c - a).length();
            let weight = area * luminance(Vec3::from(m.emission_mean));
            if weight > 0.0 && weight.is_finite() {
                triangles.push(t as u32);
                power.push(weight as f64);
            }
        }
        let total: f64 = power.iter().sum();
        let mut cdf = Vec::with_capacity(power.len());
        let mut area_pdf = vec![0.0f32; scene.triangles.len()];
        let mut sum = 0.0;
        for (&t, &w) in triangles.iter().zip(&power) {
            sum += w;
            cdf.push(sum / total);
            let [a, b, c] = scene.triangle(t as usize);
            let area = 0.5 * (b - a).cross(c - a).length() as f64;
            area_pdf[t as usize] = (w / total / area) as f32;
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Self {
            triangles,
            cdf,
            area_pdf,
        }
    }

    fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// A triangle in proportion to its power and a uniform point on it.
    fn sample(&self, scene: &Scene, rng: &mut SplitMix64) -> (u32, Vec3) {
        let u = uniform(rng) as f64;
        let i = self.cdf.partition_point(|&c| c <= u).min(self.cdf.len() - 1);
        let t = self.triangles[i];
        let [a, b, c] = scene.triangle(t as usize);
        let su = uniform(rng).sqrt();
        let (b0, b1) = (1.0 - su, uniform(rng) * su);
        (t, a * b0 + b * b1 + c * (1.0 - b0 - b1))
    }

    /// The solid-angle density with which [`Self::sample`] picks the point `y` of triangle `t`
    /// seen from `p`, `None` when `p` is not in front of the triangle (it sends nothing there).
    fn solid_angle_pdf(&self, scene: &Scene, t: u32, p: Vec3, y: Vec3) -> Option<f32> {
        let d = y - p;
        let dist2 = d.length_squared();
        let cos_l = front_normal(scene, t).dot(-d) / dist2.sqrt();
        (cos_l > 0.0 && dist2 > 0.0).then(|| self.area_pdf[t as usize] * dist2 / cos_l)
    }
}

/// The power heuristic (exponent 2) weight of a strategy of density `pdf` against another of
/// density `other`.
fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let (a, b) = (pdf * pdf, other * other);
    if a + b > 0.0 && (a + b).is_finite() {
        a / (a + b)
    } else if pdf.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// Linear radiance per pixel of `view` (row-major, row 0 at the top, the pixel centres and
/// conventions of [`crate::direct::cpu::render_screen`]; background black), by path tracing
/// (see the module docs). `materials` and `textures` are the scene's as the GPU sees them
/// ([`crate::load::SceneGpu::cpu_materials`] and `cpu_textures`, or built from
/// [`crate::load::cpu_materials`]); `bvh` is `SceneBvh::new(scene)`.
///
/// `progress(done, total)` is called from the worker threads after each row with the number of
/// pixels finished so far and the number in all.
pub fn render_reference(
    scene: &Scene,
    view: &View,
    materials: &[GpuMaterial],
    textures: &[AlbedoTexture],
    bvh: &SceneBvh,
    options: &ReferenceOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Vec<Vec3> {
    render_reference_converging(scene, view, materials, textures, bvh, options, progress).0
}

/// [`render_reference`], and with [`ReferenceOptions::converge`] above 0 how many bounces the
/// image kept.
pub fn render_reference_converging(
    scene: &Scene,
    view: &View,
    materials: &[GpuMaterial],
    textures: &[AlbedoTexture],
    bvh: &SceneBvh,
    options: &ReferenceOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> (Vec<Vec3>, Option<Convergence>) {
    let (w, h) = (view.width as usize, view.height as usize);
    let total = (w * h) as u64;
    let mut image = vec![Vec3::ZERO; w * h];
    if image.is_empty() {
        return (image, None);
    }
    let tracer = Tracer {
        scene,
        materials,
        textures,
        bvh,
        eps: ray_epsilon(scene),
        emitters: Emitters::new(scene, materials),
        sampling: options.emitters,
    };
    let done = AtomicU64::new(0);
    let layered = options.converge > 0.0 && options.component.has_indirect() && options.bounces > 0;
    if !layered {
        image.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                *out = tracer.pixel(view, x as u32, y as u32, options, &mut Layers::default());
            }
            let finished = done.fetch_add(w as u64, Ordering::Relaxed) + w as u64;
            progress(finished, total);
        });
        return (image, None);
    }
    // Every pixel's light per bounce (layer 0 the direct light), then the bounces the image's
    // mean says converged.
    let n = options.bounces as usize + 1;
    let mut layers = vec![Vec3::ZERO; w * h * n];
    layers.par_chunks_mut(w * n).enumerate().for_each(|(y, row)| {
        let mut scratch = Layers::new(options.bounces);
        for (x, out) in row.chunks_mut(n).enumerate() {
            tracer.pixel(view, x as u32, y as u32, options, &mut scratch);
            out.copy_from_slice(&scratch.mean);
        }
        let finished = done.fetch_add(w as u64, Ordering::Relaxed) + w as u64;
        progress(finished, total);
    });
    let mean = |b: usize| -> DVec3 {
        layers.chunks(n).map(|p| p[b].as_dvec3()).sum::<DVec3>() / (w * h) as f64
    };
    let plan = BouncePlan {
        max: options.bounces,
        fraction: options.converge,
    };
    let mut cumulative = mean(0);
    let convergence = run_plan(plan, cumulative.as_vec3(), |k| {
        cumulative += mean(k as usize);
        cumulative.as_vec3()
    });
    let kept = convergence.bounces as usize + 1;
    for (out, p) in image.iter_mut().zip(layers.chunks(n)) {
        *out = p[..kept].iter().sum();
    }
    (image, Some(convergence))
}

/// A pixel's light kept apart per bounce ([`ReferenceOptions::converge`]); empty when not.
#[derive(Default)]
struct Layers {
    /// Per layer (0: the direct light, `b`: bounce `b`), the mean over the pixel's paths.
    mean: Vec<Vec3>,
    /// One path's light per bounce.
    path: Vec<Vec3>,
    /// Per bounce, the sum over the pixel's paths.
    sum: Vec<DVec3>,
}

impl Layers {
    fn new(bounces: u32) -> Self {
        let b = bounces as usize;
        Self {
            mean: vec![Vec3::ZERO; b + 1],
            path: vec![Vec3::ZERO; b],
            sum: vec![DVec3::ZERO; b],
        }
    }
}

/// A surface point of a path.
#[derive(Clone, Copy)]
struct Vertex<'a> {
    /// Position.
    p: Vec3,
    /// Unit shading normal on the side the path arrives from (the geometric one tilted by the
    /// material's normal map): the cosines, the BRDF and the sampled lobes take it.
    n: Vec3,
    /// Unit geometric normal on that side: ray origins are lifted along it, and a direction
    /// below it leaves no light (the surface itself is in the way).
    ng: Vec3,
    /// Unit direction back along the path (towards the eye or the previous vertex).
    v: Vec3,
    /// Kd times the albedo texture at `p`.
    albedo: Vec3,
    material: &'a GpuMaterial,
}

/// The scene as the paths see it.
struct Tracer<'a> {
    scene: &'a Scene,
    materials: &'a [GpuMaterial],
    textures: &'a [AlbedoTexture],
    bvh: &'a SceneBvh,
    /// Offset of ray origins off the surface.
    eps: f32,
    /// The emitting triangles.
    emitters: Emitters,
    /// How paths gather the emitters' light.
    sampling: EmitterSampling,
}

impl<'a> Tracer<'a> {
    /// The vertex at `p` on `triangle`, reached along a ray whose origin lies towards `towards`
    /// (decides the side of the normal), seen from the unit direction `v`.
    fn vertex(&self, triangle: u32, p: Vec3, towards: Vec3, v: Vec3) -> Vertex<'a> {
        let material = &self.materials[self.scene.triangle_materials[triangle as usize] as usize];
        let ng = facing_normal(self.scene, triangle, towards);
        Vertex {
            p,
            n: shading_normal(self.scene, material, self.textures, triangle, p, ng),
            ng,
            v,
            albedo: albedo_at(self.scene, material, self.textures, triangle, p),
            material,
        }
    }

    /// Radiance leaving `x` towards `x.v` straight from the lights (next-event estimation).
    fn direct(&self, x: &Vertex) -> Vec3 {
        direct_radiance(
            self.scene, self.bvh, self.eps, x.p, x.ng, x.n, x.v, x.albedo, x.material,
        )
        .0
    }

    /// The emitters' light reflected at `x` towards `x.v`, estimated from one point sampled on
    /// them (light sampling) with an exact shadow ray, weighted against BSDF sampling by the
    /// power heuristic under [`EmitterSampling::Mis`].
    fn emitter_light(&self, x: &Vertex, rng: &mut SplitMix64) -> Vec3 {
        let (t, y) = self.emitters.sample(self.scene, rng);
        let Some(pdf) = self.emitters.solid_angle_pdf(self.scene, t, x.p, y) else {
            return Vec3::ZERO;
        };
        let wi = (y - x.p).normalize();
        let cos_i = x.n.dot(wi);
        if cos_i <= 0.0 || x.ng.dot(wi) <= 0.0 || !pdf.is_finite() {
            return Vec3::ZERO;
        }
        let m = &self.materials[self.scene.triangle_materials[t as usize] as usize];
        let le = emission_at(self.scene, m, self.textures, t, y);
        if le == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let lifted = y + front_normal(self.scene, t) * self.eps;
        if !self.bvh.segment_clear(x.p + x.ng * self.eps, lifted) {
            return Vec3::ZERO;
        }
        let weight = match self.sampling {
            EmitterSampling::Mis => power_heuristic(pdf, bounce_pdf(x, wi)),
            _ => 1.0,
        };
        brdf(x.albedo, x.material, wi, x.n, x.v) * le * (cos_i * weight / pdf)
    }

    /// The radiance the emitter `t` sends back along a continuation from `x` in the direction
    /// `wi` (drawn with the density `pdf`) that met it at `y`: its emission when `x` lies in
    /// front of it, weighted against light sampling under [`EmitterSampling::Mis`].
    fn emitter_hit(&self, x: &Vertex, wi: Vec3, pdf: f32, t: u32, y: Vec3) -> Vec3 {
        let m = &self.materials[self.scene.triangle_materials[t as usize] as usize];
        let le = emitted_radiance(self.scene, m, self.textures, t, y, -wi);
        if le == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let weight = match self.sampling {
            EmitterSampling::Mis => {
                let light = self.emitters.solid_angle_pdf(self.scene, t, x.p, y);
                power_heuristic(pdf, light.unwrap_or(0.0))
            }
            _ => 1.0,
        };
        le * weight
    }

    /// Radiance of pixel (`x`, `y`), and with `layers` not empty its light per bounce there.
    fn pixel(
        &self,
        view: &View,
        x: u32,
        y: u32,
        options: &ReferenceOptions,
        layers: &mut Layers,
    ) -> Vec3 {
        layers.mean.fill(Vec3::ZERO);
        layers.sum.fill(DVec3::ZERO);
        let dir = view.primary_ray(x, y);
        let Some((t, triangle)) = self.bvh.closest_hit(view.eye, dir, 0.0, f32::INFINITY) else {
            return Vec3::ZERO;
        };
        // The same point and normal as `render_screen`, so the direct light is identical.
        let p = view.eye + dir * t;
        let first = self.vertex(triangle, p, view.eye - p, -dir);
        let mut radiance = Vec3::ZERO;
        if options.component.has_direct() {
            radiance += self.direct(&first);
            radiance += emitted_radiance(
                self.scene,
                first.material,
                self.textures,
                triangle,
                p,
                view.eye - p,
            );
        }
        if let Some(direct) = layers.mean.first_mut() {
            *direct = radiance;
        }
        if options.component.has_indirect() && options.bounces > 0 {
            let pixel = y as u64 * view.width as u64 + x as u64;
            let mut rng = pixel_rng(options.seed, pixel);
            let samples = options.samples_per_pixel.max(1);
            let mut sum = DVec3::ZERO;
            for _ in 0..samples {
                let mut l = self.indirect(&first, options.bounces, &mut rng, &mut layers.path);
                let mut scale = 1.0;
                if let Some(c) = options.clamp {
                    let largest = l.max_element();
                    if largest > c {
                        scale = c / largest;
                        l *= scale;
                    }
                }
                sum += l.as_dvec3();
                for (s, p) in layers.sum.iter_mut().zip(&layers.path) {
                    *s += (*p * scale).as_dvec3();
                }
            }
            radiance += (sum / samples as f64).as_vec3();
            for (m, s) in layers.mean.iter_mut().skip(1).zip(&layers.sum) {
                *m = (*s / samples as f64).as_vec3();
            }
        }
        radiance
    }

    /// One path from `first` of at most `bounces` bounces: the radiance it brings back to
    /// `first` along `first.v`, not counting the direct light at `first` (the spot lights'
    /// reflected once, and its own emission): the emitters' light reflected at vertices 0 to
    /// `bounces - 1` and the spot lights' at vertices 1 to `bounces`. With `per_bounce` not
    /// empty, the light of bounce `b + 1` goes to `per_bounce[b]` too.
    fn indirect(
        &self,
        first: &Vertex<'a>,
        bounces: u32,
        rng: &mut SplitMix64,
        per_bounce: &mut [Vec3],
    ) -> Vec3 {
        let emitters = !self.emitters.is_empty();
        let light_sampling = emitters && self.sampling != EmitterSampling::Bsdf;
        let bsdf_sampling = emitters && self.sampling != EmitterSampling::Light;
        let mut x = *first;
        let mut throughput = Vec3::ONE;
        let mut radiance = Vec3::ZERO;
        per_bounce.fill(Vec3::ZERO);
        for b in 0..bounces as usize {
            let mark = radiance;
            let goes_on = 'bounce: {
                // 1. The emitters' light reflected at x, by light sampling.
                if light_sampling {
                    radiance += throughput * self.emitter_light(&x, rng);
                }
                // 2. The continuation.
                let Some((wi, weight, pdf)) = sample_bounce(&x, rng) else {
                    break 'bounce false;
                };
                throughput *= weight;
                if throughput == Vec3::ZERO {
                    break 'bounce false;
                }
                // A direction the shading normal allows but the surface hides carries no light.
                if x.ng.dot(wi) <= 0.0 {
                    break 'bounce false;
                }
                let origin = x.p + x.ng * self.eps;
                let Some((t, triangle)) = self.bvh.closest_hit(origin, wi, 0.0, f32::INFINITY)
                else {
                    break 'bounce false;
                };
                let y = origin + wi * t;
                // 3. The emitters' light reflected at x, by BSDF sampling: the emitter met.
                if bsdf_sampling {
                    radiance += throughput * self.emitter_hit(&x, wi, pdf, triangle, y);
                }
                // 4. The spot lights' light reflected at the new vertex.
                x = self.vertex(triangle, y, -wi, -wi);
                radiance += throughput * self.direct(&x);
                true
            };
            if let Some(slot) = per_bounce.get_mut(b) {
                *slot = radiance - mark;
            }
            if !goes_on {
                break;
            }
        }
        radiance
    }
}

/// The random stream of pixel `pixel`: SplitMix64 started at `mix(seed) ^ mix(pixel)`, `mix`
/// being SplitMix64's output function (so neighbouring pixels' streams are unrelated, not
/// shifted copies of each other).
fn pixel_rng(seed: u64, pixel: u64) -> SplitMix64 {
    let mix = |v: u64| SplitMix64(v).next_u64();
    SplitMix64(mix(seed) ^ mix(pixel ^ 0x5851_F42D_4C95_7F2D))
}

/// Uniform in `[0, 1)` with 24 random bits (every value exact in `f32`, never 1).
fn uniform(rng: &mut SplitMix64) -> f32 {
    (rng.next_u64() >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Mean of the three channels.
fn mean(c: Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

/// Unit vector at polar angle `acos(cos_theta)` and azimuth `2 pi u` around the unit `axis`.
fn around(axis: Vec3, cos_theta: f32, u: f32) -> Vec3 {
    let (t, b) = axis.any_orthonormal_pair();
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (s, c) = (std::f32::consts::TAU * u).sin_cos();
    (t * (c * sin_theta) + b * (s * sin_theta) + axis * cos_theta).normalize()
}

/// The probabilities of the diffuse and the glossy lobe of [`sample_bounce`] at `x`, `None`
/// for a black material.
fn lobe_choice(x: &Vertex) -> Option<f32> {
    let diffuse_weight = mean(x.albedo).max(0.0);
    let glossy_weight = mean(Vec3::from(x.material.ks)).max(0.0);
    (diffuse_weight + glossy_weight > 0.0).then(|| diffuse_weight / (diffuse_weight + glossy_weight))
}

/// The density (per solid angle) with which [`sample_bounce`] draws the direction `wi` above
/// the surface at `x`: the mixture of the cosine lobe and the Phong lobe; zero below it.
fn bounce_pdf(x: &Vertex, wi: Vec3) -> f32 {
    use std::f32::consts::PI;
    let Some(p_diffuse) = lobe_choice(x) else {
        return 0.0;
    };
    let cos_i = x.n.dot(wi);
    if cos_i <= 0.0 {
        return 0.0;
    }
    let ns = x.material.ns;
    let mirror = (-x.v).reflect(x.n);
    let mut pdf = p_diffuse * cos_i / PI;
    if p_diffuse < 1.0 {
        pdf += (1.0 - p_diffuse) * ((ns + 1.0) / (2.0 * PI) * wi.dot(mirror).max(0.0).powf(ns));
    }
    pdf
}

/// Draws the direction `wi` a path continues in from `x` (towards the next vertex) from the
/// mixture of a cosine-weighted hemisphere (diffuse lobe) and the normalised Phong lobe around
/// the mirror direction of `x.v` (glossy lobe), chosen in proportion to the mean albedo and the
/// mean Ks; returns `wi`, `BRDF(wi, x.v) cos / pdf(wi)` and `pdf(wi)`, pdf being the mixture's
/// ([`bounce_pdf`]). `None` ends the path: a black material, or a direction below the surface
/// (the glossy lobe reaches below the horizon at grazing angles; those samples carry no light).
fn sample_bounce(x: &Vertex, rng: &mut SplitMix64) -> Option<(Vec3, Vec3, f32)> {
    let p_diffuse = lobe_choice(x)?;
    let ns = x.material.ns;
    let mirror = (-x.v).reflect(x.n);
    let (u0, u1, u2) = (uniform(rng), uniform(rng), uniform(rng));
    let wi = if u0 < p_diffuse {
        around(x.n, (1.0 - u1).sqrt(), u2)
    } else {
        around(mirror, (1.0 - u1).powf(1.0 / (ns + 1.0)), u2)
    };
    let cos_i = x.n.dot(wi);
    if cos_i <= 0.0 {
        return None;
    }
    let pdf = bounce_pdf(x, wi);
    if pdf.is_nan() || pdf <= 0.0 {
        return None;
    }
    let f = brdf(x.albedo, x.material, wi, x.n, x.v);
    Some((wi, f * (cos_i / pdf), pdf))
}

#[cfg(test)]
mod tests {
    use std::{collections::HashMap, path::Path, sync::OnceLock};

    use cssm_formats::scene::{Camera, Material, SpotLight};

    use super::*;
    use crate::{direct::cpu::render_screen, load::cpu_materials};

    /// A scene with what `render_reference` needs beside it.
    struct Setup {
        scene: Scene,
        materials: Vec<GpuMaterial>,
        textures: Vec<AlbedoTexture>,
        bvh: SceneBvh,
    }

    impl Setup {
        fn new(scene: Scene) -> Self {
            let (materials, textures) = cpu_materials(&scene).expect("textures");
            let bvh = SceneBvh::new(&scene);
            Self {
                scene,
                materials,
                textures,
                bvh,
            }
        }

        fn render(&self, w: u32, h: u32, options: &ReferenceOptions) -> Vec<Vec3> {
            self.render_converging(w, h, options).0
        }

        fn render_converging(
            &self,
            w: u32,
            h: u32,
            options: &ReferenceOptions,
        ) -> (Vec<Vec3>, Option<Convergence>) {
            let view = View::of_scene(&self.scene, w, h);
            render_reference_converging(
                &self.scene,
                &view,
                &self.materials,
                &self.textures,
                &self.bvh,
                options,
                &|_, _| {},
            )
        }
    }

    fn built_in(name: &str) -> Setup {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../scenes")
            .join(name);
        Setup::new(Scene::load(&dir).expect("built-in scene loads"))
    }

    fn cornell() -> &'static Setup {
        static S: OnceLock<Setup> = OnceLock::new();
        S.get_or_init(|| built_in("cornell-box"))
    }

    fn cornell_glossy() -> &'static Setup {
        static S: OnceLock<Setup> = OnceLock::new();
        S.get_or_init(|| built_in("cornell-glossy"))
    }

    fn options(spp: u32, bounces: u32, component: Component, seed: u64) -> ReferenceOptions {
        ReferenceOptions {
            samples_per_pixel: spp,
            bounces,
            converge: 0.0,
            component,
            seed,
            clamp: None,
            emitters: EmitterSampling::Mis,
        }
    }

    /// Root mean square of the channel differences.
    fn rms_difference(a: &[Vec3], b: &[Vec3]) -> f64 {
        let sum: f64 = a
            .iter()
            .zip(b)
            .map(|(x, y)| (*x - *y).length_squared() as f64)
            .sum();
        (sum / (3 * a.len()) as f64).sqrt()
    }

    #[test]
    fn component_names_round_trip() {
        for c in Component::ALL {
            assert_eq!(c.name().parse::<Component>(), Ok(c));
            assert_eq!(c.to_string(), c.name());
        }
        assert_eq!(Component::default(), Component::Full);
        assert!(
            "everything"
                .parse::<Component>()
                .unwrap_err()
                .contains("direct")
        );
    }

    #[test]
    fn direct_component_is_the_direct_light_reference() {
        let s = cornell();
        let (w, h) = (40, 30);
        let view = View::of_scene(&s.scene, w, h);
        let expected = render_screen(&s.scene, &view, &s.materials, &s.textures, &s.bvh);
        let calls = AtomicU64::new(0);
        let last = AtomicU64::new(0);
        let image = render_reference(
            &s.scene,
            &view,
            &s.materials,
            &s.textures,
            &s.bvh,
            &options(1, 0, Component::Direct, 1),
            &|done, total| {
                assert_eq!(total, (w * h) as u64);
                calls.fetch_add(1, Ordering::Relaxed);
                last.fetch_max(done, Ordering::Relaxed);
            },
        );
        assert_eq!(calls.into_inner(), h as u64, "one progress call per row");
        assert_eq!(last.into_inner(), (w * h) as u64);
        assert_eq!(image.len(), expected.len());
        let lit = expected.iter().filter(|p| p.lit != 0).count();
        assert!(lit > (w * h / 4) as usize, "only {lit} lit pixels");
        for (i, (got, want)) in image.iter().zip(&expected).enumerate() {
            let tolerance = 1e-6 * want.radiance.max_element().max(1e-30);
            assert!(
                (*got - want.radiance).abs().max_element() <= tolerance,
                "pixel {i}: {got} against {}",
                want.radiance
            );
        }
        // The direct light is exact, so more paths or bounces do not change it.
        let more = s.render(w, h, &options(4, 3, Component::Direct, 9));
        assert_eq!(more, image);
    }

    /// A sphere of radius 1 around the origin, an icosahedron subdivided `levels` times with its
    /// vertices pushed onto the sphere, of uniform Lambertian albedo `rho`, with an isotropic
    /// point light of intensity `intensity` at the centre: two spot lights of cutoff 90 degrees
    /// back to back (the scene model allows cutoffs in (0, 180) only). The camera sits at the
    /// centre too.
    fn lit_sphere(levels: u32, rho: f32, intensity: f32) -> Scene {
        let t = (1.0 + 5f32.sqrt()) / 2.0;
        let mut positions: Vec<Vec3> = [
            [-1.0, t, 0.0],
            [1.0, t, 0.0],
            [-1.0, -t, 0.0],
            [1.0, -t, 0.0],
            [0.0, -1.0, t],
            [0.0, 1.0, t],
            [0.0, -1.0, -t],
            [0.0, 1.0, -t],
            [t, 0.0, -1.0],
            [t, 0.0, 1.0],
            [-t, 0.0, -1.0],
            [-t, 0.0, 1.0],
        ]
        .iter()
        .map(|&p| Vec3::from(p).normalize())
        .collect();
        let mut triangles: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut midpoints = HashMap::new();
            let mut midpoint = |a: u32, b: u32| {
                *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let m = (positions[a as usize] + positions[b as usize]).normalize();
                    positions.push(m);
                    positions.len() as u32 - 1
                })
            };
            triangles = triangles
                .iter()
                .flat_map(|&[a, b, c]| {
                    let (ab, bc, ca) = (midpoint(a, b), midpoint(b, c), midpoint(c, a));
                    [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
                })
                .collect();
        }
        let spot = |direction: Vec3| SpotLight {
            position: Vec3::ZERO,
            direction,
            cutoff_deg: 90.0,
            intensity: [intensity; 3],
        };
        Scene {
            name: "lit-sphere".into(),
            path: std::path::PathBuf::from("/nonexistent"),
            triangle_materials: vec![0; triangles.len()],
            objects: vec![cssm_formats::SceneObject::whole_static(triangles.len())],
            positions,
            texcoords: Vec::new(),
            triangles,
            materials: vec![Material {
                kd: [rho; 3],
                ..Material::grey("grey")
            }],
            camera: Camera {
                position: Vec3::ZERO,
                target: Vec3::new(0.3, 0.2, 1.0),
                up: Vec3::Y,
                fov_y_deg: 70.0,
                resolution: [16, 12],
            },
            lights: vec![spot(Vec3::Y), spot(-Vec3::Y)],
            content_hash: [0; 32],
            files: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// The closed form. In a sphere of radius `R` with an isotropic point light of intensity
    /// `I` at its centre, the direct irradiance is `I / R^2` everywhere, and an enclosure of
    /// uniform radiance `L` gives the irradiance `pi L` at every point of it, so with albedo
    /// `rho` every bounce is uniform too and the radiance after `B` bounces is
    /// `rho / pi * I / R^2 * (1 + rho + ... + rho^B)`.
    ///
    /// The test sphere is a polyhedron: a point of a face whose plane lies at `r_f <= R` from the
    /// centre, at `d` in `[r_f, R]` from it, receives `I r_f / d^3`, between `I r_min / R^3` and
    /// `I / r_min^2` (`r_min` the smallest `r_f`). The uniform-radiance argument holds for any
    /// closed enclosure and the diffuse bounce weight is exactly `rho`, so every path, not just
    /// the mean, lies between those bounds times `(1 + rho + ... + rho^B)`: checked pixel by
    /// pixel, with bounds tight enough (0.5%) that a missing or extra bounce fails.
    #[test]
    fn sphere_with_a_central_point_light_matches_the_closed_form() {
        let (rho, intensity) = (0.7f32, 3.0f32);
        let s = Setup::new(lit_sphere(4, rho, intensity));
        let r_min = (0..s.scene.triangles.len())
            .map(|t| {
                let [a, b, c] = s.scene.triangle(t);
                (b - a).cross(c - a).normalize().dot(a).abs()
            })
            .fold(f32::INFINITY, f32::min);
        let r_max = s
            .scene
            .positions
            .iter()
            .map(|p| p.length())
            .fold(0.0f32, f32::max);
        let l_min = rho / std::f32::consts::PI * intensity * r_min / r_max.powi(3);
        let l_max = rho / std::f32::consts::PI * intensity / (r_min * r_min);
        assert!(l_max / l_min < 1.005, "tessellation too coarse: {r_min}");
        for bounces in [0, 1, 4] {
            let sum: f32 = (0..=bounces).map(|k| rho.powi(k as i32)).sum();
            for component in Component::ALL {
                let factor = match component {
                    Component::Direct => 1.0,
                    Component::Indirect => sum - 1.0,
                    Component::Full => sum,
                };
                let image = s.render(16, 12, &options(8, bounces, component, 3));
                let (lo, hi) = (factor * l_min * 0.9999, factor * l_max * 1.0001);
                for (i, p) in image.iter().enumerate() {
                    for c in p.to_array() {
                        assert!(
                            c >= lo && c <= hi,
                            "{component}, {bounces} bounces, pixel {i}: {c} outside [{lo}, {hi}]"
                        );
                    }
                }
            }
        }
    }

    /// In the same sphere bounce `k` adds `rho^k` of the light `1 + rho + ... + rho^k`: 5.7% at
    /// 5 bounces, 3.8% at 6 for rho 0.7, so a run converging at 5% keeps 6 bounces, the same
    /// image as 6 bounces asked for, and one at 1% runs out of its 8 first.
    #[test]
    fn a_converging_image_keeps_the_bounces_its_light_needs() {
        let (rho, intensity) = (0.7f32, 3.0f32);
        let s = Setup::new(lit_sphere(4, rho, intensity));
        let at = |fraction| ReferenceOptions {
            converge: fraction,
            ..options(4, 8, Component::Full, 3)
        };
        let (image, convergence) = s.render_converging(16, 12, &at(0.05));
        let convergence = convergence.expect("a converging run says where it ended");
        assert_eq!((convergence.bounces, convergence.converged), (6, true), "{convergence}");
        assert!((convergence.added - 0.038).abs() < 0.002, "{convergence}");
        // The same paths' first six bounces, but a path of 8 draws more numbers than one of 6,
        // so the later paths differ: by the tessellation's 0.5% at most, where a bounce more
        // or fewer is 3-6%.
        let six = s.render(16, 12, &options(4, 6, Component::Full, 3));
        for (a, b) in image.iter().zip(&six) {
            assert!((*a - *b).abs().max_element() <= 5e-3 * b.max_element(), "{a} {b}");
        }
        let (_, longer) = s.render_converging(16, 12, &at(0.01));
        let longer = longer.unwrap();
        assert_eq!((longer.bounces, longer.converged), (8, false), "{longer}");
        // Exactly: no layers, no convergence.
        assert_eq!(s.render_converging(8, 6, &options(2, 3, Component::Full, 3)).1, None);
    }

    #[test]
    fn same_options_same_image_whatever_the_threads() {
        let s = cornell_glossy();
        let o = options(4, 3, Component::Full, 5);
        let a = s.render(24, 18, &o);
        let b = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("thread pool")
            .install(|| s.render(24, 18, &o));
        assert!(a == b, "one thread and many differ");
        assert!(a.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
        let c = s.render(24, 18, &ReferenceOptions { seed: 6, ..o });
        let differ = a.iter().zip(&c).filter(|(x, y)| x != y).count();
        assert!(
            differ > a.len() / 2,
            "another seed changed only {differ} pixels"
        );
    }

    #[test]
    fn full_is_direct_plus_indirect() {
        let s = cornell_glossy();
        let (w, h) = (24, 18);
        let black = s.render(w, h, &options(4, 0, Component::Indirect, 2));
        assert!(black.iter().all(|&p| p == Vec3::ZERO));
        let direct = s.render(w, h, &options(4, 2, Component::Direct, 2));
        assert_eq!(s.render(w, h, &options(4, 0, Component::Full, 2)), direct);
        let indirect = s.render(w, h, &options(4, 2, Component::Indirect, 2));
        let full = s.render(w, h, &options(4, 2, Component::Full, 2));
        assert!(indirect.iter().filter(|p| p.max_element() > 0.0).count() > (w * h / 2) as usize);
        for ((f, d), i) in full.iter().zip(&direct).zip(&indirect) {
            assert!((*f - (*d + *i)).abs().max_element() <= 1e-6 * f.max_element());
        }
        // Clamping only ever darkens.
        let clamped = s.render(
            w,
            h,
            &ReferenceOptions {
                clamp: Some(0.05),
                ..options(4, 2, Component::Indirect, 2)
            },
        );
        assert!(
            clamped
                .iter()
                .zip(&indirect)
                .all(|(c, i)| c.cmple(*i + 1e-6).all())
        );
        assert!(clamped != indirect);
    }

    /// The error against a 512-path image shrinks like one over the square root of the path
    /// count (an independent seed for the reference): the estimator is consistent. On the
    /// glossy Cornell box, so both lobes are sampled.
    #[test]
    fn error_shrinks_with_more_paths() {
        let s = cornell_glossy();
        let (w, h) = (16, 12);
        let reference = s.render(w, h, &options(512, 2, Component::Indirect, 100));
        let error = |spp| {
            rms_difference(
                &s.render(w, h, &options(spp, 2, Component::Indirect, 7)),
                &reference,
            )
        };
        let (e4, e64) = (error(4), error(64));
        eprintln!("RMS error against 512 paths: {e4:.4} with 4, {e64:.4} with 64");
        // Expected ratio sqrt((1/64 + 1/512) / (1/4 + 1/512)) = 0.26.
        assert!(e64 < 0.45 * e4, "4 paths: {e4}, 64 paths: {e64}");
    }

    /// The mean of `BRDF cos / pdf` over drawn directions is the directional albedo
    /// `integral of BRDF cos` over the hemisphere, here by a midpoint rule in (theta, phi): the
    /// sampling weights match the sampling density, for both lobes and their mixture.
    #[test]
    fn bounce_weights_match_the_sampling_density() {
        let n = Vec3::Z;
        for (kd, ks, ns, view_angle) in [
            (0.5f32, 0.0f32, 1.0f32, 0.3f32),
            (0.0, 0.6, 20.0, 0.4),
            (0.3, 0.5, 50.0, 1.2),
            (0.2, 0.7, 5.0, 1.45),
        ] {
            let material = GpuMaterial {
                kd: [kd; 3],
                ns,
                ks: [ks; 3],
                ..Default::default()
            };
            let v = Vec3::new(view_angle.sin(), 0.0, view_angle.cos());
            let x = Vertex {
                p: Vec3::ZERO,
                n,
                ng: n,
                v,
                albedo: Vec3::splat(kd),
                material: &material,
            };
            let (steps_t, steps_p) = (2000, 2000);
            let (dt, dp) = (
                std::f64::consts::FRAC_PI_2 / steps_t as f64,
                std::f64::consts::TAU / steps_p as f64,
            );
            let mut exact = 0.0f64;
            for i in 0..steps_t {
                let theta = (i as f64 + 0.5) * dt;
                for j in 0..steps_p {
                    let phi = (j as f64 + 0.5) * dp;
                    let l = Vec3::new(
                        (theta.sin() * phi.cos()) as f32,
                        (theta.sin() * phi.sin()) as f32,
                        theta.cos() as f32,
                    );
                    let f = brdf(x.albedo, &material, l, n, v).x as f64;
                    exact += f * theta.cos() * theta.sin() * dt * dp;
                }
            }
            let mut rng = SplitMix64(42);
            let count = 400_000;
            let mut sum = 0.0f64;
            for _ in 0..count {
                if let Some((wi, weight, _)) = sample_bounce(&x, &mut rng) {
                    assert!((wi.length() - 1.0).abs() < 1e-5 && wi.dot(n) > 0.0);
                    sum += weight.x as f64;
                }
            }
            let estimate = sum / count as f64;
            eprintln!("kd {kd} ks {ks} ns {ns}: {estimate:.5} sampled, {exact:.5} integrated");
            assert!(
                (estimate - exact).abs() < 0.005 * exact,
                "kd {kd} ks {ks} ns {ns}: {estimate} sampled, {exact} integrated"
            );
        }
    }

    /// [`lit_sphere`]'s polyhedron lit by its own emission instead: no lights, every triangle
    /// of albedo `rho` emitting `le` from the side its winding faces, inwards when `inwards`.
    fn emissive_sphere(levels: u32, rho: f32, le: f32, inwards: bool) -> Scene {
        let mut scene = lit_sphere(levels, rho, 0.0);
        scene.lights.clear();
        scene.materials[0].emission = [le; 3];
        for tri in &mut scene.triangles {
            let [a, b, c] = tri.map(|v| scene.positions[v as usize]);
            let faces_in = (b - a).cross(c - a).dot(a) < 0.0;
            if faces_in != inwards {
                tri.swap(1, 2);
            }
        }
        scene
    }

    /// Inside a closed enclosure every point of which emits `Le` inwards, the irradiance is
    /// `pi Le` everywhere (the uniform-radiance argument of
    /// [`sphere_with_a_central_point_light_matches_the_closed_form`] holds for any closed
    /// enclosure), so with albedo `rho` the radiance is `Le` seen directly and
    /// `Le (rho + ... + rho^B)` after `B` bounces as indirect light. BSDF sampling alone gets it
    /// path by path (every continuation meets an emitter, every bounce weighs `rho`); light
    /// sampling and MIS get it on average. Wound outwards, nothing emits into the sphere and the
    /// image is black.
    #[test]
    fn emissive_sphere_matches_the_closed_form() {
        let (rho, le) = (0.6f32, 1.5f32);
        let s = Setup::new(emissive_sphere(3, rho, le, true));
        for bounces in [0u32, 1, 3] {
            let expected: f32 = (1..=bounces).map(|k| le * rho.powi(k as i32)).sum();
            for sampling in [
                EmitterSampling::Mis,
                EmitterSampling::Light,
                EmitterSampling::Bsdf,
            ] {
                let with = |component, spp| ReferenceOptions {
                    emitters: sampling,
                    ..options(spp, bounces, component, 11)
                };
                let direct = s.render(16, 12, &with(Component::Direct, 1));
                for p in &direct {
                    assert!((*p - Vec3::splat(le)).abs().max_element() < 1e-6, "{p}");
                }
                let image = s.render(16, 12, &with(Component::Indirect, 64));
                let mean = image.iter().map(|p| mean(*p) as f64).sum::<f64>() / image.len() as f64;
                eprintln!("{sampling:?}, {bounces} bounces: mean {mean:.5}, closed form {expected:.5}");
                if bounces == 0 {
                    assert!(image.iter().all(|&p| p == Vec3::ZERO));
                    continue;
                }
                assert!(
                    (mean / expected as f64 - 1.0).abs() < 0.01,
                    "{sampling:?}, {bounces} bounces: mean {mean}, closed form {expected}"
                );
                if sampling == EmitterSampling::Bsdf {
                    for (i, p) in image.iter().enumerate() {
                        assert!(
                            (*p - Vec3::splat(expected)).abs().max_element() < 1e-3 * expected,
                            "pixel {i}: {p} against {expected}"
                        );
                    }
                }
            }
        }
        let outwards = Setup::new(emissive_sphere(3, rho, le, false));
        for sampling in [EmitterSampling::Mis, EmitterSampling::Bsdf] {
            let o = ReferenceOptions {
                emitters: sampling,
                ..options(16, 3, Component::Full, 4)
            };
            let image = outwards.render(16, 12, &o);
            assert!(image.iter().all(|&p| p == Vec3::ZERO), "{sampling:?}");
        }
    }

    /// A floor of albedo `rho` (`y = 0`, facing up, 4 x 4) under a black square emitter of side
    /// 0.5 at height 0.5 emitting `le` (downwards, or upwards when `facing_up`), no lights, the
    /// camera above and to the side.
    fn lamp_over_floor(rho: f32, le: [f32; 3], facing_up: bool) -> Scene {
        let (f, r, h) = (2.0f32, 0.25f32, 0.5f32);
        let positions = vec![
            Vec3::new(-f, 0.0, f),
            Vec3::new(f, 0.0, f),
            Vec3::new(f, 0.0, -f),
            Vec3::new(-f, 0.0, -f),
            Vec3::new(-r, h, r),
            Vec3::new(r, h, r),
            Vec3::new(r, h, -r),
            Vec3::new(-r, h, -r),
        ];
        // The floor's winding faces +y; the lamp's faces -y unless `facing_up`.
        let lamp = if facing_up {
            [[4, 5, 6], [4, 6, 7]]
        } else {
            [[4, 6, 5], [4, 7, 6]]
        };
        let triangles = vec![[0, 1, 2], [0, 2, 3], lamp[0], lamp[1]];
        Scene {
            name: "lamp-over-floor".into(),
            path: std::path::PathBuf::from("/nonexistent"),
            triangle_materials: vec![0, 0, 1, 1],
            objects: vec![cssm_formats::SceneObject::whole_static(triangles.len())],
            positions,
            texcoords: Vec::new(),
            triangles,
            materials: vec![
                Material {
                    kd: [rho; 3],
                    ..Material::grey("floor")
                },
                Material {
                    kd: [0.0; 3],
                    emission: le,
                    ..Material::grey("lamp")
                },
            ],
            camera: Camera {
                position: Vec3::new(0.0, 2.5, 2.5),
                target: Vec3::new(0.0, 0.0, 0.0),
                up: Vec3::Y,
                fov_y_deg: 60.0,
                resolution: [32, 24],
            },
            lights: Vec::new(),
            content_hash: [0; 32],
            files: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// Irradiance at `p` (unit normal `n`) from a polygon of uniform radiance `le` wholly
    /// above `p`'s horizon and unoccluded: Lambert's formula, `E = le / 2 |sum_i theta_i
    /// n . (u_i x u_(i+1)) / |u_i x u_(i+1)||` over the edges, `u_i` the unit directions to the
    /// corners and `theta_i` the angle between consecutive ones.
    fn polygon_irradiance(p: Vec3, n: Vec3, corners: &[Vec3], le: f32) -> f32 {
        let u: Vec<glam::DVec3> = corners.iter().map(|c| (*c - p).as_dvec3().normalize()).collect();
        let mut sum = 0.0f64;
        for i in 0..u.len() {
            let (a, b) = (u[i], u[(i + 1) % u.len()]);
            let theta = a.dot(b).clamp(-1.0, 1.0).acos();
            sum += theta * n.as_dvec3().dot(a.cross(b).normalize());
        }
        (le as f64 / 2.0 * sum.abs()) as f32
    }

    /// One bounce of a square emitter's light on a floor is `rho / pi E` with `E` by Lambert's
    /// formula, pixel by pixel: the path tracer gets it with light sampling, BSDF sampling and
    /// MIS alike (each unbiased: their means agree within the noise), MIS with less noise than
    /// BSDF sampling alone. The lamp's back, which the camera sees, is dark; wound the other
    /// way the lamp lights nothing below it.
    #[test]
    fn square_lamp_over_a_floor_matches_lamberts_formula() {
        let (rho, le) = (0.6f32, 3.0f32);
        let s = Setup::new(lamp_over_floor(rho, [le; 3], false));
        let (w, h) = (32, 24);
        let view = View::of_scene(&s.scene, w, h);
        let corners = [0.25f32, -0.25].map(|x| [0.25f32, -0.25].map(|z| Vec3::new(x, 0.5, z)));
        let corners = [corners[0][0], corners[0][1], corners[1][1], corners[1][0]];
        // The exact value at every pixel that sees the floor.
        let exact: Vec<Option<f32>> = (0..w * h)
            .map(|i| {
                let dir = view.primary_ray(i % w, i / w);
                let (t, triangle) = s.bvh.closest_hit(view.eye, dir, 0.0, f32::INFINITY)?;
                (triangle < 2).then(|| {
                    let p = view.eye + dir * t;
                    rho / std::f32::consts::PI * polygon_irradiance(p, Vec3::Y, &corners, le)
                })
            })
            .collect();
        let floor = exact.iter().filter(|e| e.is_some()).count();
        assert!(floor > (w * h / 2) as usize, "{floor} floor pixels");
        let mut errors = Vec::new();
        for sampling in [
            EmitterSampling::Mis,
            EmitterSampling::Light,
            EmitterSampling::Bsdf,
        ] {
            let o = ReferenceOptions {
                emitters: sampling,
                ..options(128, 1, Component::Indirect, 21)
            };
            let image = s.render(w, h, &o);
            let (mut err, mut norm, mut sum, mut sum_exact) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for (p, e) in image.iter().zip(&exact) {
                match e {
                    Some(e) => {
                        let e = *e as f64;
                        err += (mean(*p) as f64 - e).powi(2);
                        norm += e * e;
                        sum += mean(*p) as f64;
                        sum_exact += e;
                    }
                    None => assert_eq!(*p, Vec3::ZERO, "the lamp reflects nothing"),
                }
            }
            let rmse = (err / norm).sqrt();
            // The pixels' errors are noise, independent from pixel to pixel: the standard
            // error of the sum is the root of their summed squares.
            let (bias, standard_error) = (sum / sum_exact - 1.0, err.sqrt() / sum_exact);
            eprintln!(
                "{sampling:?}: relative RMSE {rmse:.4}, mean off by {bias:+.4} (standard error \
                 {standard_error:.4})"
            );
            assert!(
                bias.abs() < 4.0 * standard_error + 1e-3,
                "{sampling:?}: mean off by {bias}, standard error {standard_error}"
            );
            errors.push(rmse);
        }
        assert!(errors[0] < 0.05, "MIS: relative RMSE {}", errors[0]);
        assert!(errors[0] < errors[2], "MIS {} no better than BSDF sampling {}", errors[0], errors[2]);
        // The camera sees the lamp's back: its direct light is nothing.
        let direct = s.render(w, h, &options(1, 1, Component::Direct, 1));
        assert!(direct.iter().all(|&p| p == Vec3::ZERO));
        // Wound upwards, the lamp lights the floor not at all, and the camera sees its front.
        let up = Setup::new(lamp_over_floor(rho, [le; 3], true));
        let indirect = up.render(w, h, &options(16, 2, Component::Indirect, 3));
        assert!(indirect.iter().all(|&p| p == Vec3::ZERO));
        let direct = up.render(w, h, &options(1, 1, Component::Direct, 1));
        assert!(direct.iter().filter(|&&p| p == Vec3::splat(le)).count() > 4);
    }

    /// With emitters too, an image depends on the options only (not the thread count) and the
    /// full light is the direct plus the indirect.
    #[test]
    fn emitters_keep_images_deterministic_and_components_additive() {
        let s = Setup::new(lamp_over_floor(0.5, [4.0, 2.0, 1.0], false));
        let o = options(8, 2, Component::Full, 5);
        let a = s.render(24, 18, &o);
        let b = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("thread pool")
            .install(|| s.render(24, 18, &o));
        assert!(a == b, "one thread and many differ");
        assert!(a.iter().any(|p| p.max_element() > 0.0));
        assert!(a.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
        let direct = s.render(24, 18, &options(8, 2, Component::Direct, 5));
        let indirect = s.render(24, 18, &options(8, 2, Component::Indirect, 5));
        for ((f, d), i) in a.iter().zip(&direct).zip(&indirect) {
            assert!((*f - (*d + *i)).abs().max_element() <= 1e-6 * f.max_element().max(1e-6));
        }
    }
}
