//! One method variant of `cssm report error` and `cssm compare` rendered: a CPU method directly,
//! a GPU method through a [`Renderer`] (with the `.cssm` baked in memory where it needs one),
//! its GPU milliseconds per pass from a warm frame and the GPU memory its renderer holds.

use std::time::Instant;

use cssm_bake::BakeOptions;
use cssm_formats::{CssmFile, Scene};
use cssm_runtime::{
    self as runtime, Renderer, RendererSettings,
    common::{camera::View, compose::Component, readback::Image},
    frame::{FrameSettings, Stage},
    method::{Backend, CpuSetup},
};

use super::{Host, Variant, rows_bar};
use crate::report::compare::PassTime;

/// GPU milliseconds of a method's passes in a warm frame that runs them all.
#[derive(Clone, Debug)]
pub struct GpuTimes {
    /// The passes every frame runs.
    pub frame: f64,
    /// The passes that run before the first frame and after a light or an object moves.
    pub prepare: f64,
    /// Each pass, in the order they ran.
    pub passes: Vec<PassTime>,
}

/// What rendering a method measured.
pub struct Rendered {
    /// The image after the last frame.
    pub image: Image,
    /// GPU times of a warm frame that runs every pass; `None` on the CPU, without timestamp
    /// queries, or when not [`RenderSpec::timed`].
    pub gpu: Option<GpuTimes>,
    /// Bytes of GPU memory its renderer held after its frames ([`runtime::gpu_memory_bytes`]);
    /// `None` on the CPU or where the backend counts none.
    pub memory: Option<u64>,
    /// Wall-clock seconds of the render (renderer set-up, frames and read-back; not the bake).
    pub seconds: f64,
}

/// How a variant is rendered.
pub struct RenderSpec<'a> {
    /// Image size, exposure, shadow maps.
    pub frame: FrameSettings,
    /// Which light the image holds.
    pub component: Component,
    /// Frames rendered, the camera at rest, before the image is read.
    pub frames: u32,
    /// The in-memory bake of the methods that need a `.cssm`.
    pub bake: &'a BakeOptions,
    /// Whether to time every pass in one more frame ([`Rendered::gpu`]); a second render of
    /// the same method (another component) needs no times of its own.
    pub timed: bool,
}

/// Renders one variant of `scene`: a CPU method directly, a GPU method through a
/// [`Renderer`] on `gpu` (opened on first use) with the `.cssm` from `cssm` (baked by `host`
/// on first use, and kept for the scene's other variants).
///
/// # Errors
/// The method's, the bake's or the GPU's, naming the scene.
pub fn render_variant(
    spec: &RenderSpec,
    scene: &Scene,
    variant: &Variant,
    host: &dyn Host,
    gpu: &mut Option<runtime::Gpu>,
    cssm: &mut Option<Result<CssmFile, String>>,
) -> Result<Rendered, String> {
    let (w, h) = (spec.frame.width, spec.frame.height);
    let method = variant.method;
    let fail = |e: runtime::RuntimeError| format!("{}: {e}", scene.path.display());
    match method.backend {
        Backend::Cpu(run) => {
            let start = Instant::now();
            let view = View::of_scene(scene, w, h);
            let bar = rows_bar(
                h as u64,
                format!("{}: {} ({})", scene.name, variant.spec, spec.component),
            );
            let radiance = run(&CpuSetup {
                scene,
                view: &view,
                component: spec.component,
                options: &variant.resolved,
                progress: &|done, _| bar.set_position(done / w.max(1) as u64),
                on_bounces: &|_| {},
            })
            .map_err(fail)?;
            bar.finish_and_clear();
            Ok(Rendered {
                image: Image::from_cpu(w, h, radiance, spec.frame.exposure),
                gpu: None,
                memory: None,
                seconds: start.elapsed().as_secs_f64(),
            })
        }
        Backend::Gpu(_) => {
            let file = if method.needs_cssm {
                let baked = cssm.get_or_insert_with(|| {
                    eprintln!(
                        "{}: baking a .cssm at atlas {}, cube {}",
                        scene.name, spec.bake.atlas_resolution, spec.bake.cube_resolution
                    );
                    host.bake(scene, spec.bake).map(|b| b.file).map_err(|e| {
                        format!(
                            "{}: bake: {}",
                            scene.path.display(),
                            cssm_output::flag_error(&e)
                        )
                    })
                });
                Some(baked.as_ref().map_err(Clone::clone)?)
            } else {
                None
            };
            if gpu.is_none() {
                *gpu = Some(runtime::Gpu::new_headless().map_err(|e| e.to_string())?);
            }
            let gpu = gpu.as_ref().expect("created above");
            eprintln!(
                "{}: {} ({}) on {}",
                scene.name,
                variant.spec,
                spec.component,
                gpu.describe()
            );
            gpu.wait().map_err(fail)?;
            let memory_before = runtime::gpu_memory_bytes(&gpu.device);
            let start = Instant::now();
            let settings = RendererSettings {
                frame: spec.frame,
                component: spec.component,
                ..Default::default()
            };
            let mut renderer = Renderer::new(
                &gpu.device,
                &gpu.queue,
                scene,
                file,
                method,
                &variant.values,
                &settings,
            )
            .map_err(fail)?;
            // `spec.frames` frames, the camera at rest, for the image.
            let image = runtime::common::readback::render_image(&mut renderer, spec.frames)
                .map_err(fail)?;
            // Waiting also frees the read-back's own target and buffers, so what is left is
            // the renderer's.
            gpu.wait().map_err(fail)?;
            let seconds = start.elapsed().as_secs_f64();
            let held = runtime::gpu_memory_bytes(&gpu.device).saturating_sub(memory_before);
            let memory = (held > 0).then_some(held);
            let gpu_times = if spec.timed {
                warm_times(&mut renderer, scene, gpu).map_err(fail)?
            } else {
                None
            };
            Ok(Rendered {
                image,
                gpu: gpu_times,
                memory,
                seconds,
            })
        }
    }
}

/// GPU times of every pass in a frame after the image's (their pipelines warm: a first frame
/// also pays for drivers that compile on first use, lavapipe's among them): the first light set
/// again as it is (in a scene without lights, the first object), so the view-independent passes
/// run too, then one frame. `None` without timestamp queries.
fn warm_times(
    renderer: &mut Renderer,
    scene: &Scene,
    gpu: &runtime::Gpu,
) -> Result<Option<GpuTimes>, runtime::RuntimeError> {
    if !gpu.has_timestamps() {
        return Ok(None);
    }
    if let Some(light) = scene.lights.first() {
        renderer.set_light(0, light)?;
    } else if let Some(object) = scene.objects.first() {
        // No light (a scene lit by its emitters alone): the first object placed where it is,
        // which runs the view-independent passes again as well.
        renderer.set_object_transform(0, object.transform)?;
    }
    let (width, height) = renderer.context().size();
    let target = runtime::common::readback::offscreen_target(&gpu.device, width, height);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    renderer.render(&mut encoder, &target.create_view(&Default::default()));
    gpu.queue.submit([encoder.finish()]);
    let timings = renderer.read_timings()?;
    gpu.wait()?;
    let schedule = runtime::frame::schedule(renderer.method().passes);
    let passes: Vec<PassTime> = timings
        .iter()
        .map(|&(name, ms)| PassTime {
            name: name.to_string(),
            prepare: schedule
                .iter()
                .find(|p| p.name == name)
                .is_some_and(|p| p.stage == Stage::Prepare),
            ms,
        })
        .collect();
    let sum = |prepare: bool| {
        passes
            .iter()
            .filter(|p| p.prepare == prepare)
            .map(|p| p.ms)
            .sum::<f64>()
    };
    Ok(Some(GpuTimes {
        frame: sum(false),
        prepare: sum(true),
        passes,
    }))
}
