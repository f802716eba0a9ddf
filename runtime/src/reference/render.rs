//! [`render_reference`]: the path tracer's image. Rows are rendered in parallel into one
//! preallocated image; with [`ReferenceOptions::converge`] above 0 each pixel's light is kept
//! per bounce, and the image ends at the first bounce whose share of the image's mean falls
//! under it, as the GPU methods' converged runs end (`crate::common::converge`).

use std::sync::atomic::{AtomicU64, Ordering};

use cssm_formats::Scene;
use cssm_raycast::SceneBvh;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::{ReferenceOptions, emitters::Emitters, tracer::Tracer};
use crate::{
    common::{
        camera::View,
        converge::{BouncePlan, Convergence, run_plan},
    },
    direct::cpu::ray_epsilon,
    gpu_types::GpuMaterial,
    load::AlbedoTexture,
};

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
    layers
        .par_chunks_mut(w * n)
        .enumerate()
        .for_each(|(y, row)| {
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
pub(super) struct Layers {
    /// Per layer (0: the direct light, `b`: bounce `b`), the mean over the pixel's paths.
    pub(super) mean: Vec<Vec3>,
    /// One path's light per bounce.
    pub(super) path: Vec<Vec3>,
    /// Per bounce, the sum over the pixel's paths.
    pub(super) sum: Vec<DVec3>,
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
