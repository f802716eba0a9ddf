//! `cssm report error`'s run: per scene the reference path tracer's image, then every
//! variant's, measured against it ([`crate::report::error`]) and written out
//! ([`crate::report::error_write`]: error.md, error.csv, each image and each scene's strip).
//! The rendering is [`super::reference`]'s and [`super::render`]'s.

use std::{path::PathBuf, time::Instant};

use cssm_bake::BakeOptions;
use cssm_formats::CssmFile;
use cssm_runtime::{
    self as runtime,
    common::{compose::Component, readback},
    frame::FrameSettings,
    method::Resolved,
};

use super::{Host, Reference, ReferenceFiles, ReferenceSpec, RenderSpec, Variant, write_text};
use crate::report::{
    error::Figures,
    error_write::{self, ErrorReport, ErrorRow, Measured},
};

/// `cssm report error`, checked.
pub struct ErrorConfig {
    /// Scene directories or mesh files; empty: the host's built-in scenes.
    pub scenes: Vec<PathBuf>,
    /// The variants, in the order given.
    pub variants: Vec<Variant>,
    /// Image size, exposure (a multiplier) and shadow-map resolution, checked.
    pub frame: FrameSettings,
    /// The reference's options (`samples`, `bounces`), checked by its table entry.
    pub reference: Resolved,
    /// Which light the images hold.
    pub component: Component,
    /// The in-memory bake of the methods that need a `.cssm`.
    pub bake: BakeOptions,
    /// Report directory.
    pub out: PathBuf,
    /// `--reference-cache`: reuse a cached reference of the same scene and settings.
    pub reference_cache: bool,
    /// Frames rendered per GPU variant, at least one.
    pub frames: u32,
}

/// Runs `cssm report error` as `command` (the command line, which the report names): writes
/// the report into `config.out` and prints its table.
///
/// # Errors
/// A scene, a reference or a file that fails, or any variant's render that failed (after the
/// report is written, which tells each one's error).
pub fn run(config: &ErrorConfig, command: &str, host: &dyn Host) -> Result<(), String> {
    let start = Instant::now();
    let out = &config.out;
    super::check_out_dir(out)?;
    let scenes = super::load_scenes(&config.scenes, host)?;
    let output = |name: &str| super::output(out, name, false);
    // The fixed names are checked before the first render, not after minutes of it.
    for name in ["error.md", "error.csv"] {
        output(name)?;
    }

    let (w, h) = (config.frame.width, config.frame.height);
    let mut gpu: Option<runtime::Gpu> = None;
    let (mut references, mut rows) = (Vec::new(), Vec::new());
    for scene in &scenes {
        // File names from the scene's name as one safe component (it may hold `/` or `..`).
        let scene_stem = cssm_formats::files::safe_file_stem(&scene.name);
        let files = |ext: &str| output(&format!("{scene_stem}-reference.{ext}"));
        let Reference {
            image: reference,
            summary,
        } = super::reference_image(
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
            let outcome = super::render_variant(&spec, scene, variant, host, &mut gpu, &mut cssm)
                .and_then(|rendered| {
                    let image = rendered.image;
                    let figures = Figures::measure(
                        w,
                        h,
                        (&image.radiance, &image.display),
                        (&reference.radiance, &reference.display),
                    );
                    let stem = error_write::file_stem(&variant.spec);
                    readback::save_png(&output(&format!("{scene_stem}-{stem}.png"))?, &image)?;
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
        readback::save_rgba_png(
            &output(&format!("{scene_stem}-strip.png"))?,
            strip_w,
            h,
            pixels,
        )?;
        references.push(summary);
    }

    let report = ErrorReport {
        command: command.to_string(),
        commit: crate::report::commit(),
        machine: crate::report::machine(),
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
    Ok(())
}
