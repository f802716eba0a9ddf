//! `cssm compare`'s run: per scene the reference path tracer's full image and indirect light
//! (cached in `OUT/reference-cache/`), then every method's, measured against them
//! ([`crate::report::error`], the reference's noise taken out by [`crate::report::compare`])
//! and written as a page ([`crate::report::compare_html`]), CSV, JSON and Markdown. The
//! rendering is [`super::reference`]'s and [`super::render`]'s.

use std::{
    path::{Path, PathBuf},
    time::Instant,
};

use cssm_bake::BakeOptions;
use cssm_formats::{CssmFile, Scene};
use cssm_runtime::{
    self as runtime,
    common::{
        compose::Component,
        readback::{self, Image},
    },
    frame::FrameSettings,
    method::Resolved,
};

use super::{Host, ReferenceFiles, ReferenceSpec, RenderSpec, Variant, write_text};
use crate::report::{
    compare::{
        self, CompareReport, CompareSettings, ComponentFigures, Components, MethodComparison,
        MethodImages, MethodMeasured, ReferenceEntry, SceneComparison,
    },
    compare_html,
    error::{self, Figures},
    error_write::file_stem,
};

/// `cssm compare`, checked.
pub struct CompareConfig {
    /// Scene directories or mesh files; empty: the host's built-in scenes.
    pub scenes: Vec<PathBuf>,
    /// The methods, in the order given.
    pub variants: Vec<Variant>,
    /// Image size, exposure (a multiplier) and shadow-map resolution, checked.
    pub frame: FrameSettings,
    /// Exposure in stops, as given.
    pub exposure_stops: f32,
    /// The reference's options (`samples`, `bounces`), checked by its table entry.
    pub reference: Resolved,
    /// The in-memory bake of the methods that need a `.cssm`.
    pub bake: BakeOptions,
    /// Page directory.
    pub out: PathBuf,
    /// Whether cached references may be reused.
    pub reuse_references: bool,
    /// Frames rendered per GPU method, at least one.
    pub frames: u32,
}

/// The page's own files in OUT, which a run replaces (besides `images/` and
/// `reference-cache/`).
const PAGE_FILES: [&str; 5] = [
    "index.html",
    "chart.svg",
    "compare.csv",
    "compare.json",
    "compare.md",
];

/// Runs `cssm compare` as `command` (the command line, which the page names): writes the page
/// and its files into `config.out` and prints the Markdown table.
///
/// # Errors
/// A scene, a reference or a file that fails, or any method's render that failed (after the
/// page is written, which tells each one's error).
pub fn run(config: &CompareConfig, command: &str, host: &dyn Host) -> Result<(), String> {
    let start = Instant::now();
    let out = &config.out;
    super::check_out_dir(out)?;
    let scenes = super::load_scenes(&config.scenes, host)?;
    // Every fixed name is checked before the first render: a link planted as `index.html`
    // or `images` is refused now, not after minutes of rendering (and never written through).
    for name in PAGE_FILES {
        output(out, name)?;
    }
    let cache = super::output(out, "reference-cache", true)?;
    let mut gpu: Option<runtime::Gpu> = None;
    let mut comparisons = Vec::new();
    for scene in &scenes {
        comparisons.push(compare_scene(config, scene, &cache, host, &mut gpu)?);
    }
    let report = CompareReport {
        command: command.to_string(),
        commit: crate::report::commit(),
        machine: crate::report::machine(),
        device: gpu.as_ref().map(runtime::Gpu::describe),
        settings: CompareSettings {
            width: config.frame.width,
            height: config.frame.height,
            samples: config.reference.count("samples"),
            bounces: config.reference.count("bounces"),
            frames: config.frames,
            exposure_stops: config.exposure_stops,
            shadow_resolution: config.frame.shadow_resolution,
            atlas: config.bake.atlas_resolution,
            cube: config.bake.cube_resolution,
        },
        scenes: comparisons,
        seconds: start.elapsed().as_secs_f64(),
    };
    // The chart and the data first, the page that links them last.
    write_text(
        &output(out, "chart.svg")?,
        &compare_html::chart_svg(&report)?,
    )?;
    write_text(&output(out, "compare.csv")?, &compare::csv(&report))?;
    write_text(&output(out, "compare.json")?, &compare::json(&report)?)?;
    let md = compare::markdown(&report);
    write_text(&output(out, "compare.md")?, &md)?;
    write_text(&output(out, "index.html")?, &compare_html::html(&report))?;
    print!("{md}");
    let failed: Vec<String> = report
        .scenes
        .iter()
        .flat_map(|s| {
            s.methods
                .iter()
                .filter(|m| m.measured.is_none())
                .map(move |m| format!("{} on {}", m.spec, s.name))
        })
        .collect();
    eprintln!("wrote {}", out.join("index.html").display());
    if !failed.is_empty() {
        return Err(format!(
            "{} of {} renders failed ({}; see {})",
            failed.len(),
            report.scenes.iter().map(|s| s.methods.len()).sum::<usize>(),
            failed.join(", "),
            out.join("index.html").display()
        ));
    }
    Ok(())
}

/// `name` inside `--out`, never through a link ([`super::output`]).
fn output(out: &Path, name: &str) -> Result<PathBuf, String> {
    super::output(out, name, false)
}

/// The reference cache's file of `scene`'s `component` reference at these settings, with
/// `ext`: one file per scene, component and settings, so runs at other sizes keep theirs.
fn cache_file(
    cache: &Path,
    scene: &Scene,
    component: Component,
    config: &CompareConfig,
) -> impl Fn(&str) -> PathBuf {
    let stem = format!(
        "{}-{component}-{}x{}-{}spp-{}b",
        file_stem(&scene.name),
        config.frame.width,
        config.frame.height,
        config.reference.count("samples"),
        config.reference.count("bounces")
    );
    let cache = cache.to_path_buf();
    move |ext| cache.join(format!("{stem}.{ext}"))
}

/// Both references of `scene` and every method's figures against them; its images written
/// under `OUT/images/SCENE/`.
fn compare_scene(
    config: &CompareConfig,
    scene: &Scene,
    cache: &Path,
    host: &dyn Host,
    gpu: &mut Option<runtime::Gpu>,
) -> Result<SceneComparison, String> {
    let out = &config.out;
    // The scene's name as one path component: a name with `/` or `..` in it (it comes from the
    // scene's own file) writes nowhere outside OUT.
    let images_rel = format!("images/{}", file_stem(&scene.name));
    let (w, h) = (config.frame.width, config.frame.height);

    let reference = |component: Component| -> Result<(Image, ReferenceEntry), String> {
        let file = cache_file(cache, scene, component, config);
        let png_rel = format!("{images_rel}/reference-{component}.png");
        let reference = super::reference_image(
            scene,
            &ReferenceSpec {
                frame: config.frame,
                samples: config.reference.count("samples"),
                bounces: config.reference.count("bounces"),
                component,
            },
            &ReferenceFiles {
                exr: file("exr"),
                json: file("json"),
                png: output(out, &png_rel)?,
            },
            config.reuse_references,
        )?;
        let entry = ReferenceEntry::new(&reference.summary, png_rel);
        Ok((reference.image, entry))
    };
    let full_ref = reference(Component::Full)?;
    let indirect_ref = reference(Component::Indirect)?;

    let mut cssm: Option<Result<CssmFile, String>> = None;
    let mut methods = Vec::new();
    for variant in &config.variants {
        // The full image's render is timed; the indirect light's is the same passes again.
        let mut render = |component| {
            let spec = RenderSpec {
                frame: config.frame,
                component,
                frames: config.frames,
                bake: &config.bake,
                timed: component == Component::Full,
            };
            super::render_variant(&spec, scene, variant, host, gpu, &mut cssm)
        };
        let stem = file_stem(&variant.spec);
        let measured = render(Component::Full).and_then(|full| {
            let indirect = render(Component::Indirect)?;
            let against = |image: &Image, reference: &(Image, ReferenceEntry)| {
                let figures = Figures::measure(
                    w,
                    h,
                    (&image.radiance, &image.display),
                    (&reference.0.radiance, &reference.0.display),
                );
                ComponentFigures::new(&figures, &reference.1)
            };
            let paths = MethodImages {
                full: format!("{images_rel}/{stem}-full.png"),
                indirect: format!("{images_rel}/{stem}-indirect.png"),
                indirect_error: format!("{images_rel}/{stem}-indirect-error.png"),
            };
            readback::save_png(&output(out, &paths.full)?, &full.image)?;
            readback::save_png(&output(out, &paths.indirect)?, &indirect.image)?;
            let map = error::flip_map(w, h, &indirect_ref.0.display, &indirect.image.display);
            readback::save_rgba_png(&output(out, &paths.indirect_error)?, w, h, map)?;
            Ok(MethodMeasured {
                figures: Components {
                    full: against(&full.image, &full_ref),
                    indirect: against(&indirect.image, &indirect_ref),
                },
                gpu_frame_ms: full.gpu.as_ref().map(|t| t.frame),
                gpu_prepare_ms: full.gpu.as_ref().map(|t| t.prepare),
                passes: full.gpu.map(|t| t.passes).unwrap_or_default(),
                memory_bytes: full.memory,
                seconds: full.seconds,
                images: paths,
            })
        });
        methods.push(comparison(scene, variant, measured));
    }
    Ok(SceneComparison {
        name: scene.name.clone(),
        reference: Components {
            full: full_ref.1,
            indirect: indirect_ref.1,
        },
        methods,
    })
}

/// One method's row of the page: its figures, or the error its render failed with (told on
/// stderr as well).
fn comparison(
    scene: &Scene,
    variant: &Variant,
    measured: Result<MethodMeasured, String>,
) -> MethodComparison {
    if let Err(e) = &measured {
        eprintln!("error: {} with {}: {e}", scene.name, variant.spec);
    }
    let (measured, error) = match measured {
        Ok(m) => (Some(m), None),
        Err(e) => (None, Some(e)),
    };
    MethodComparison {
        spec: variant.spec.clone(),
        method: variant.method.name.to_string(),
        on_gpu: variant.method.on_gpu(),
        error,
        measured,
    }
}
