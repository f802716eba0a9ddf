//! `cssm report error`: per scene the reference path tracer's image, then every variant's,
//! measured against it ([`cssm::report::error`]) and written out
//! ([`cssm::report::error_write`]). This file only renders and writes.

use std::{
    path::{Path, PathBuf},
    process::ExitCode,
    time::Instant,
};

use cssm::{
    formats, raycast,
    report::{
        error::{self, Figures},
        error_write::{
            self, ErrorReport, ErrorRow, Measured, ReferenceSettings, ReferenceSidecar,
            SceneReference,
        },
    },
    runtime,
};
use formats::{CssmFile, Scene};
use runtime::{
    Renderer, RendererSettings,
    common::{camera::View, readback::Image},
    method::{Backend, CpuSetup},
    reference::{ReferenceOptions, render_reference},
};

use crate::{
    CliResult,
    bake_cmd::bake_with_progress,
    cli::{ErrorConfig, Variant},
    load_scene,
    render::{save_exr, save_png, save_rgba_png},
};

/// Seeds of the reference's two halves; `--method reference` draws from seed 0, so its image
/// is independent of the reference's.
const REFERENCE_SEEDS: [u64; 2] = [1, 2];

pub fn run_error(config: ErrorConfig) -> CliResult {
    let start = Instant::now();
    let out = &config.out;
    if out.exists() && !out.is_dir() {
        return Err(format!(
            "--out {}: exists and is not a directory",
            out.display()
        ));
    }
    let dirs = if config.scenes.is_empty() {
        let builtin = |r: std::io::Result<PathBuf>| {
            r.map_err(|e| format!("cannot prepare the built-in scenes: {e}"))
        };
        vec![
            builtin(cssm::builtin::cornell_box())?,
            builtin(cssm::builtin::cornell_glossy())?,
        ]
    } else {
        config.scenes.clone()
    };
    let scenes = dirs
        .iter()
        .map(|d| load_scene(d))
        .collect::<Result<Vec<_>, _>>()?;
    for (i, s) in scenes.iter().enumerate() {
        if let Some(other) = scenes[..i].iter().find(|o| o.name == s.name) {
            return Err(format!(
                "{} and {} are both named '{}': the report's file names would clash",
                other.dir.display(),
                s.dir.display(),
                s.name
            ));
        }
    }
    std::fs::create_dir_all(out).map_err(|e| format!("--out {}: {e}", out.display()))?;

    let (w, h) = (config.frame.width, config.frame.height);
    let mut gpu: Option<runtime::Gpu> = None;
    let (mut references, mut rows) = (Vec::new(), Vec::new());
    for scene in &scenes {
        let (reference, summary) = reference_image(&config, scene)?;
        let mut strip = vec![reference.display.clone()];
        let mut cssm: Option<Result<CssmFile, String>> = None;
        for variant in &config.variants {
            let outcome = render_variant(&config, scene, variant, &mut gpu, &mut cssm).and_then(
                |(image, gpu_ms, seconds)| {
                    let figures = Figures::measure(
                        w,
                        h,
                        (&image.radiance, &image.display),
                        (&reference.radiance, &reference.display),
                    );
                    let stem = error_write::file_stem(&variant.spec);
                    save_png(&out.join(format!("{}-{stem}.png", scene.name)), &image)?;
                    strip.push(image.display);
                    Ok(Measured {
                        figures,
                        gpu_ms: gpu_ms.as_ref().map(|t| t.frame),
                        gpu_prepare_ms: gpu_ms.as_ref().map(|t| t.prepare),
                        seconds,
                        on_gpu: variant.method.on_gpu(),
                    })
                },
            );
            if let Err(e) = &outcome {
                eprintln!("error: {} with {}: {e}", scene.name, variant.spec);
            }
            rows.push(ErrorRow {
                scene: scene.name.clone(),
                spec: variant.spec.clone(),
                outcome,
            });
        }
        let images: Vec<&[u8]> = strip.iter().map(Vec::as_slice).collect();
        let (strip_w, pixels) = error_write::strip(w, h, &images);
        save_rgba_png(
            &out.join(format!("{}-strip.png", scene.name)),
            strip_w,
            h,
            pixels,
        )?;
        references.push(summary);
    }

    let command = std::iter::once("cssm".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ");
    let report = ErrorReport {
        command,
        commit: cssm::report::commit(),
        machine: cssm::report::machine(),
        device: gpu.as_ref().map(runtime::Gpu::describe),
        settings: format!(
            "{w}x{h}, reference {} paths per pixel, {} bounce(s), component {}, exposure x{}, \
             shadow maps {}, .cssm baked at atlas {}, cube {} where a method needs one",
            config.reference.count("samples"),
            config.reference.count("bounces"),
            config.component,
            config.frame.exposure,
            config.frame.shadow_resolution,
            config.bake.atlas_resolution,
            config.bake.cube_resolution
        ),
        references,
        rows,
        seconds: start.elapsed().as_secs_f64(),
    };
    for (name, text) in [
        ("error.md", error_write::markdown(&report)),
        ("error.csv", error_write::csv(&report)),
    ] {
        write_text(&out.join(name), &text)?;
    }
    print!("{}", error_write::table(&report));
    let failed = report.rows.iter().filter(|r| r.outcome.is_err()).count();
    if failed > 0 {
        return Err(format!(
            "{failed} of {} renders failed (see {})",
            report.rows.len(),
            out.join("error.md").display()
        ));
    }
    eprintln!("wrote {}", out.join("error.md").display());
    Ok(ExitCode::SUCCESS)
}

fn write_text(path: &Path, text: &str) -> Result<(), String> {
    formats::cssm::write_bytes_atomic(path, text.as_bytes()).map_err(|e| e.to_string())
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

/// The scene's reference: from `--reference-cache` when its sidecar matches, else path traced
/// in two halves and written (`SCENE-reference.exr`, `.json`); its PNG either way.
fn reference_image(config: &ErrorConfig, scene: &Scene) -> Result<(Image, SceneReference), String> {
    let (w, h) = (config.frame.width, config.frame.height);
    let samples = config.reference.count("samples");
    let halves = [samples.div_ceil(2), samples / 2];
    let settings = ReferenceSettings {
        cssm_version: env!("CARGO_PKG_VERSION").into(),
        scene: scene.name.clone(),
        content_hash: formats::hash_hex(&scene.content_hash),
        width: w,
        height: h,
        samples,
        bounces: config.reference.count("bounces"),
        component: config.component.name().into(),
        seeds: REFERENCE_SEEDS,
        halves,
    };
    let exr = config.out.join(format!("{}-reference.exr", scene.name));
    let json = config.out.join(format!("{}-reference.json", scene.name));
    let png = config.out.join(format!("{}-reference.png", scene.name));
    if config.reference_cache {
        match cached_reference(&exr, &json, &settings) {
            Ok((radiance, sidecar)) => {
                eprintln!("{}: reusing {}", scene.name, exr.display());
                let image = Image::from_cpu(w, h, radiance, config.frame.exposure);
                save_png(&png, &image)?;
                let summary = SceneReference {
                    scene: scene.name.clone(),
                    noise_floor: sidecar.noise_floor,
                    seconds: sidecar.seconds,
                    cached: true,
                };
                return Ok((image, summary));
            }
            Err(why) => eprintln!("{}: path tracing the reference ({why})", scene.name),
        }
    }
    let start = Instant::now();
    let fail = |e: runtime::RuntimeError| format!("{}: {e}", scene.dir.display());
    runtime::frame::check_size(w, h).map_err(fail)?;
    let (materials, textures) = runtime::load::cpu_materials(scene).map_err(fail)?;
    let bvh = raycast::SceneBvh::new(scene);
    let view = View::of_scene(scene, w, h);
    let parts = halves.iter().filter(|&&n| n > 0).count() as u64;
    let bar = rows_bar(
        parts * h as u64,
        format!("{}: reference, {samples} paths per pixel", scene.name),
    );
    let mut images = Vec::new();
    for (i, (&n, &seed)) in halves.iter().zip(&REFERENCE_SEEDS).enumerate() {
        if n == 0 {
            continue;
        }
        let options = ReferenceOptions {
            samples_per_pixel: n,
            bounces: settings.bounces,
            component: config.component,
            seed,
            clamp: None,
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
    let (radiance, noise_floor) = match images.as_slice() {
        [a, b] => (
            error::combine(a, halves[0], b, halves[1]),
            error::noise_floor(a, halves[0], b, halves[1]),
        ),
        [a] => (a.clone(), None),
        _ => unreachable!("at least one path per pixel"),
    };
    let seconds = start.elapsed().as_secs_f64();
    eprintln!(
        "{}: reference at {w}x{h}, {samples} paths per pixel, in {seconds:.1} s",
        scene.name
    );
    let image = Image::from_cpu(w, h, radiance, config.frame.exposure);
    // The sidecar goes first and comes back last, so a sidecar never describes another EXR.
    if json.exists() {
        std::fs::remove_file(&json).map_err(|e| format!("{}: {e}", json.display()))?;
    }
    save_exr(&exr, &image)?;
    let sidecar = ReferenceSidecar {
        settings,
        noise_floor,
        seconds,
    };
    let text = serde_json::to_string_pretty(&sidecar).map_err(|e| e.to_string())?;
    write_text(&json, &(text + "\n"))?;
    save_png(&png, &image)?;
    let summary = SceneReference {
        scene: scene.name.clone(),
        noise_floor,
        seconds,
        cached: false,
    };
    Ok((image, summary))
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

/// GPU milliseconds of a frame's passes, split by stage.
struct GpuMs {
    frame: f64,
    prepare: f64,
}

/// One variant's image, its GPU milliseconds and its wall-clock seconds.
fn render_variant(
    config: &ErrorConfig,
    scene: &Scene,
    variant: &Variant,
    gpu: &mut Option<runtime::Gpu>,
    cssm: &mut Option<Result<CssmFile, String>>,
) -> Result<(Image, Option<GpuMs>, f64), String> {
    let (w, h) = (config.frame.width, config.frame.height);
    let method = variant.method;
    let fail = |e: runtime::RuntimeError| format!("{}: {e}", scene.dir.display());
    match method.backend {
        Backend::Cpu(run) => {
            let start = Instant::now();
            let view = View::of_scene(scene, w, h);
            let bar = rows_bar(h as u64, format!("{}: {}", scene.name, variant.spec));
            let radiance = run(&CpuSetup {
                scene,
                view: &view,
                component: config.component,
                options: &variant.resolved,
                progress: &|done, _| bar.set_position(done / w.max(1) as u64),
            })
            .map_err(fail)?;
            bar.finish_and_clear();
            let image = Image::from_cpu(w, h, radiance, config.frame.exposure);
            Ok((image, None, start.elapsed().as_secs_f64()))
        }
        Backend::Gpu(_) => {
            let file = if method.needs_cssm {
                let baked = cssm.get_or_insert_with(|| {
                    eprintln!(
                        "{}: baking a .cssm at atlas {}, cube {}",
                        scene.name, config.bake.atlas_resolution, config.bake.cube_resolution
                    );
                    bake_with_progress(scene, &config.bake)
                        .map(|b| b.file)
                        .map_err(|e| {
                            format!("{}: bake: {}", scene.dir.display(), cssm::flag_error(&e))
                        })
                });
                Some(baked.as_ref().map_err(Clone::clone)?)
            } else {
                None
            };
            if gpu.is_none() {
                crate::quiet_mesa_wsi();
                *gpu = Some(runtime::Gpu::new_headless().map_err(|e| e.to_string())?);
            }
            let gpu = gpu.as_ref().expect("created above");
            eprintln!("{}: {} on {}", scene.name, variant.spec, gpu.describe());
            let start = Instant::now();
            let settings = RendererSettings {
                frame: config.frame,
                component: config.component,
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
            // `--frames` frames, the camera at rest; the first frame's passes that every frame
            // runs are the frame's GPU time, the others (shadow maps, radiosity over the atlas)
            // the prepare time.
            let image = runtime::common::readback::render_image(&mut renderer, config.frames)
                .map_err(fail)?;
            gpu.wait().map_err(fail)?;
            let gpu_ms = (!image.first_timings.is_empty()).then(|| {
                let schedule = runtime::frame::schedule(method.passes);
                let stage = |name: &str| {
                    schedule
                        .iter()
                        .find(|p| p.name == name)
                        .map_or(runtime::frame::Stage::Frame, |p| p.stage)
                };
                let sum = |wanted: runtime::frame::Stage| {
                    image
                        .first_timings
                        .iter()
                        .filter(|(name, _)| stage(name) == wanted)
                        .map(|(_, ms)| ms)
                        .sum::<f64>()
                };
                GpuMs {
                    frame: sum(runtime::frame::Stage::Frame),
                    prepare: sum(runtime::frame::Stage::Prepare),
                }
            });
            Ok((image, gpu_ms, start.elapsed().as_secs_f64()))
        }
    }
}
