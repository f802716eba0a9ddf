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
//!
//! # Where it lives
//!
//! This file holds the method's entry ([`METHOD`]) and its options; the path tracer itself is
//! split by what each part does:
//!
//! - `render.rs`: [`render_reference`], the image: rows in parallel, each pixel's light kept
//!   per bounce when the image ends at convergence;
//! - `tracer.rs`: the integrator, a pixel's paths with next-event estimation to the spot
//!   lights and MIS between light and BSDF sampling of the emitters;
//! - `emitters.rs`: the emitting triangles, sampled in proportion to their power, and the
//!   power heuristic;
//! - `sampling.rs`: the random numbers of a pixel and the sampling of a bounce's direction
//!   (the diffuse and Phong lobes, and their density);
//! - `tests/`: closed forms (a sphere lit from its centre, an emissive sphere, a square lamp
//!   over a floor) and the estimator's properties.

mod emitters;
mod render;
mod sampling;
#[cfg(test)]
mod tests;
mod tracer;

use cssm_raycast::SceneBvh;

use crate::{
    RuntimeError,
    common::converge::BouncePlan,
    method::{self, Backend, Checks, CpuSetup, Energy, MethodEntry, OptionKind, OptionSpec},
};

pub use render::{render_reference, render_reference_converging};

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
    timing: method::Timing {
        about: "the CPU ground truth: its time is `cssm compare`'s and `cssm report error`'s",
        compare_with: &[],
        rows: &[],
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
