//! `cssm report error`: per scene the reference path tracer's image, then every variant's,
//! measured against it ([`cssm::report::error`]) and written out
//! ([`cssm::report::error_write`]). The rendering is [`crate::measure`]'s; this file only
//! measures and writes.

use std::{process::ExitCode, time::Instant};

use cssm::{
    formats::CssmFile,
    report::{
        error::Figures,
        error_write::{self, ErrorReport, ErrorRow, Measured},
    },
    runtime,
};

use crate::{
    CliResult,
    cli::ErrorConfig,
    measure::{self, ReferenceFiles, ReferenceSpec, RenderSpec, write_text},
    render::{save_png, save_rgba_png},
};

pub fn run_error(config: ErrorConfig) -> CliResult {
    let start = Instant::now();
    let out = &config.out;
    measure::check_out_dir(out)?;
    let scenes = measure::load_scenes(&config.scenes)?;
    let output = |name: &str| crate::out_path(out, name, false);
    // The fixed names are checked before the first render, not after minutes of it.
    for name in ["error.md", "error.csv"] {
        output(name)?;
    }

    let (w, h) = (config.frame.width, config.frame.height);
    let mut gpu: Option<runtime::Gpu> = None;
    let (mut references, mut rows) = (Vec::new(), Vec::new());
    for scene in &scenes {
        // File names from the scene's name as one safe component (it may hold `/` or `..`).
        let scene_stem = cssm::safe_file_stem(&scene.name);
        let files = |ext: &str| output(&format!("{scene_stem}-reference.{ext}"));
        let measure::Reference {
            image: reference,
            summary,
        } = measure::reference_image(
            scene,
            &ReferenceSpec {
                frame: config.frame,
                samples: config.reference.count("samples"),
                bounces: config.reference.count("bounces"),
                component: config.component,
            },
            &ReferenceFiles {
                exr: files("exr")?,
                json: files("json")?,
                png: files("png")?,
            },
            config.reference_cache,
        )?;
        let mut strip = vec![reference.display.clone()];
        let mut cssm: Option<Result<CssmFile, String>> = None;
        for variant in &config.variants {
            let spec = RenderSpec {
                frame: config.frame,
                component: config.component,
                frames: config.frames,
                bake: &config.bake,
                timed: true,
            };
            let outcome = measure::render_variant(&spec, scene, variant, &mut gpu, &mut cssm)
                .and_then(|rendered| {
                    let image = rendered.image;
                    let figures = Figures::measure(
                        w,
                        h,
                        (&image.radiance, &image.display),
                        (&reference.radiance, &reference.display),
                    );
                    let stem = error_write::file_stem(&variant.spec);
                    save_png(&output(&format!("{scene_stem}-{stem}.png"))?, &image)?;
                    strip.push(image.display);
                    Ok(Measured {
                        figures,
                        gpu_ms: rendered.gpu.as_ref().map(|t| t.frame),
                        gpu_prepare_ms: rendered.gpu.as_ref().map(|t| t.prepare),
                        seconds: rendered.seconds,
                        on_gpu: variant.method.on_gpu(),
                    })
                });
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
            &output(&format!("{scene_stem}-strip.png"))?,
            strip_w,
            h,
            pixels,
        )?;
        references.push(summary);
    }

    let report = ErrorReport {
        command: measure::command_line(),
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
        write_text(&output(name)?, &text)?;
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
