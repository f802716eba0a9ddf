//! What `cssm report error` and `cssm compare` share: the reference path tracer's image in two
//! independent halves (its noise measured, cached beside the report by the scene's content and
//! the settings), and one method's image with its GPU milliseconds per pass and the GPU memory
//! its renderer holds.

use std::{
    path::{Path, PathBuf},
    time::Instant,
};

use cssm::{
    bake, formats, raycast,
    report::{
        compare::PassTime,
        error::{self, ReferenceNoise},
        error_write::{ReferenceSettings, ReferenceSidecar, SceneReference},
    },
    runtime,
};
use formats::{CssmFile, Scene};
use runtime::{
    Renderer, RendererSettings,
    common::{camera::View, compose::Component, readback::Image},
    frame::{FrameSettings, Stage},
    method::{Backend, CpuSetup},
    reference::{EmitterSampling, ReferenceOptions, render_reference},
};

use crate::{
    bake_cmd::bake_with_progress,
    cli::Variant,
    render::{save_exr, save_png},
};

/// The scenes in `dirs`, loaded; none: the built-in Cornell box and its glossy variant. Two
/// scenes of one name are refused (a report's file names are the scenes').
pub fn load_scenes(dirs: &[PathBuf]) -> Result<Vec<Scene>, String> {
    let dirs = if dirs.is_empty() {
        let builtin = |r: std::io::Result<PathBuf>| {
            r.map_err(|e| format!("cannot prepare the built-in scenes: {e}"))
        };
        vec![
            builtin(cssm::builtin::cornell_box())?,
            builtin(cssm::builtin::cornell_glossy())?,
        ]
    } else {
        dirs.to_vec()
    };
    let scenes = dirs
        .iter()
        .map(|d| crate::load_scene(d))
        .collect::<Result<Vec<_>, _>>()?;
    for (i, s) in scenes.iter().enumerate() {
        if let Some(other) = scenes[..i].iter().find(|o| o.name == s.name) {
            return Err(format!(
                "{} and {} are both named '{}': the report's file names would clash",
                other.path.display(),
                s.path.display(),
                s.name
            ));
        }
    }
    Ok(scenes)
}

/// Refuses an `--out` directory that exists as something else (a report never replaces a
/// file of the user's with a directory).
pub fn check_out_dir(out: &Path) -> Result<(), String> {
    if out.exists() && !out.is_dir() {
        return Err(format!(
            "--out {}: exists and is not a directory",
            out.display()
        ));
    }
    Ok(())
}

/// The command line as typed (`cssm` and its arguments), for a report to name.
pub fn command_line() -> String {
    std::iter::once("cssm".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Seeds of the reference's two halves; `--method reference` draws from seed 0, so its image
/// is independent of the reference's.
const REFERENCE_SEEDS: [u64; 2] = [1, 2];

/// What a reference image is path traced with.
pub struct ReferenceSpec {
    /// Image size, exposure (a multiplier) of its PNG.
    pub frame: FrameSettings,
    /// Paths per pixel in all (split into two halves).
    pub samples: u32,
    /// Indirect bounces.
    pub bounces: u32,
    /// Which light it holds.
    pub component: Component,
}

/// Where a reference is kept: its linear radiance (EXR), its sidecar (what it was rendered
/// from, its noise) and its tone-mapped PNG.
pub struct ReferenceFiles {
    /// The EXR.
    pub exr: PathBuf,
    /// The sidecar (JSON).
    pub json: PathBuf,
    /// The PNG.
    pub png: PathBuf,
}

/// A reference image and what is known of it.
pub struct Reference {
    /// The image (the mean of both halves).
    pub image: Image,
    /// Its noise, time and whether it came from the cache.
    pub summary: SceneReference,
}

/// A progress bar of `rows` image rows on stderr.
fn rows_bar(rows: u64, message: String) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(rows);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg} [{bar:32}] {pos}/{len} rows, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(message);
    bar
}

/// The scene's reference: from `files` when `reuse` is set and its sidecar matches the scene's
/// content and `spec`, else path traced in two halves and written there; its PNG either way.
pub fn reference_image(
    scene: &Scene,
    spec: &ReferenceSpec,
    files: &ReferenceFiles,
    reuse: bool,
) -> Result<Reference, String> {
    let (w, h) = (spec.frame.width, spec.frame.height);
    let samples = spec.samples;
    let halves = [samples.div_ceil(2), samples / 2];
    let settings = ReferenceSettings {
        cssm_version: env!("CARGO_PKG_VERSION").into(),
        light_model: cssm_runtime::reference::LIGHT_MODEL,
        scene: scene.name.clone(),
        content_hash: formats::hash_hex(&scene.content_hash),
        width: w,
        height: h,
        samples,
        bounces: spec.bounces,
        component: spec.component.name().into(),
        seeds: REFERENCE_SEEDS,
        halves,
    };
    let summary = |noise: ReferenceNoise, seconds: f64, cached: bool| SceneReference {
        scene: scene.name.clone(),
        noise_floor: noise.relative_rmse,
        flip_floor: noise.flip,
        bias_noise: noise.bias,
        seconds,
        cached,
    };
    if reuse {
        match cached_reference(&files.exr, &files.json, &settings) {
            Ok((radiance, sidecar)) => {
                eprintln!("{}: reusing {}", scene.name, files.exr.display());
                let image = Image::from_cpu(w, h, radiance, spec.frame.exposure);
                save_png(&files.png, &image)?;
                let noise = ReferenceNoise {
                    relative_rmse: sidecar.noise_floor,
                    flip: sidecar.flip_floor,
                    bias: sidecar.bias_noise,
                };
                return Ok(Reference {
                    image,
                    summary: summary(noise, sidecar.seconds, true),
                });
            }
            Err(why) => eprintln!("{}: path tracing the reference ({why})", scene.name),
        }
    }
    let start = Instant::now();
    let fail = |e: runtime::RuntimeError| format!("{}: {e}", scene.path.display());
    runtime::frame::check_size(w, h).map_err(fail)?;
    let (materials, textures) = runtime::load::cpu_materials(scene).map_err(fail)?;
    let bvh = raycast::SceneBvh::new(scene);
    let view = View::of_scene(scene, w, h);
    let parts = halves.iter().filter(|&&n| n > 0).count() as u64;
    let bar = rows_bar(
        parts * h as u64,
        format!(
            "{}: reference ({}), {samples} paths per pixel",
            scene.name, spec.component
        ),
    );
    let mut images = Vec::new();
    for (i, (&n, &seed)) in halves.iter().zip(&REFERENCE_SEEDS).enumerate() {
        if n == 0 {
            continue;
        }
        let options = ReferenceOptions {
            samples_per_pixel: n,
            bounces: spec.bounces,
            converge: 0.0,
            component: spec.component,
            seed,
            clamp: None,
            emitters: EmitterSampling::Mis,
        };
        let before = i as u64 * h as u64;
        let image = render_reference(
            scene,
            &view,
            &materials,
            &textures,
            &bvh,
            &options,
            &|done, _| bar.set_position(before + done / w.max(1) as u64),
        );
        images.push(
            image
                .iter()
                .map(|c| [c.x, c.y, c.z, 1.0])
                .collect::<Vec<_>>(),
        );
    }
    bar.finish_and_clear();
    let radiance = match images.as_slice() {
        [a, b] => error::combine(a, halves[0], b, halves[1]),
        [a] => a.clone(),
        _ => unreachable!("at least one path per pixel"),
    };
    let image = Image::from_cpu(w, h, radiance, spec.frame.exposure);
    let noise = match images.as_slice() {
        [a, b] => ReferenceNoise::measure(
            (w, h),
            (a, halves[0]),
            (b, halves[1]),
            (
                &image.display,
                &Image::from_cpu(w, h, a.clone(), spec.frame.exposure).display,
            ),
        ),
        _ => ReferenceNoise::default(),
    };
    let seconds = start.elapsed().as_secs_f64();
    eprintln!(
        "{}: reference ({}) at {w}x{h}, {samples} paths per pixel, in {seconds:.1} s",
        scene.name, spec.component
    );
    // The sidecar goes first and comes back last, so a sidecar never describes another EXR.
    if files.json.exists() {
        std::fs::remove_file(&files.json).map_err(|e| format!("{}: {e}", files.json.display()))?;
    }
    save_exr(&files.exr, &image)?;
    let sidecar = ReferenceSidecar {
        settings,
        noise_floor: noise.relative_rmse,
        flip_floor: noise.flip,
        bias_noise: noise.bias,
        seconds,
    };
    let text = serde_json::to_string_pretty(&sidecar).map_err(|e| e.to_string())?;
    write_text(&files.json, &(text + "\n"))?;
    save_png(&files.png, &image)?;
    Ok(Reference {
        image,
        summary: summary(noise, seconds, false),
    })
}

/// Writes `text` with the project's atomic write (never a half-written file).
pub fn write_text(path: &Path, text: &str) -> Result<(), String> {
    formats::cssm::write_bytes_atomic(path, text.as_bytes()).map_err(|e| e.to_string())
}

/// The cached reference's radiance and sidecar, or why it cannot be used.
fn cached_reference(
    exr: &Path,
    json: &Path,
    settings: &ReferenceSettings,
) -> Result<(Vec<[f32; 4]>, ReferenceSidecar), String> {
    let text = std::fs::read_to_string(json).map_err(|_| format!("no {}", json.display()))?;
    let sidecar: ReferenceSidecar =
        serde_json::from_str(&text).map_err(|e| format!("{} unreadable: {e}", json.display()))?;
    if sidecar.settings != *settings {
        return Err(format!("{} has other settings", json.display()));
    }
    let image = ::image::open(exr)
        .map_err(|e| format!("{}: {e}", exr.display()))?
        .to_rgba32f();
    if image.dimensions() != (settings.width, settings.height) {
        return Err(format!("{} has another size", exr.display()));
    }
    let radiance = image
        .as_raw()
        .chunks_exact(4)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect();
    Ok((radiance, sidecar))
}

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
    pub bake: &'a bake::BakeOptions,
    /// Whether to time every pass in one more frame ([`Rendered::gpu`]); a second render of
    /// the same method (another component) needs no times of its own.
    pub timed: bool,
}

/// Renders one variant of `scene`: a CPU method directly, a GPU method through a
/// [`Renderer`] on `gpu` (opened on first use) with the `.cssm` from `cssm` (baked on first
/// use, and kept for the scene's other variants).
pub fn render_variant(
    spec: &RenderSpec,
    scene: &Scene,
    variant: &Variant,
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
                    bake_with_progress(scene, spec.bake)
                        .map(|b| b.file)
                        .map_err(|e| {
                            format!("{}: bake: {}", scene.path.display(), cssm::flag_error(&e))
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
/// run too, then one frame. `None` without
/// timestamp queries.
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
