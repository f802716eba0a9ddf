//! `cssm render`: the command line's loop over the runtime's [`Renderer`], and the image files
//! it writes. Every method and option comes from the runtime's method table
//! ([`runtime::method::METHODS`]); every range is checked there.

use std::{
    path::{Path, PathBuf},
    process::ExitCode,
};

use cssm::{bake, formats, runtime};
use formats::{CssmFile, Scene};
use runtime::{
    Renderer, RendererSettings,
    common::{compose::Component, readback},
    frame::FrameSettings,
    method::{Backend, CpuSetup, MethodEntry, OptionValue, OptionValues},
};

use crate::{CliResult, bake_with_progress, builtin, check_writable, load_scene};

/// `--help`'s text after the options: the method table, then examples.
pub fn after_help() -> String {
    format!(
        "Methods and their options (--set NAME=VALUE; --bounces, --threshold and --samples are \
         short for those options):\n{}\n\
         Every method marked [needs .cssm] takes the scene's .cssm: --cssm FILE, else one is \
         baked first (atlas 64, cube 32; a few seconds for the Cornell box).\n\n\
         Examples:\n  cssm render --out cornell.png\n  \
         cssm bake -o cornell-box.cssm && cssm render --cssm cornell-box.cssm --method lightcuts --bounces 2 --out gi.png\n  \
         cssm render scenes/cornell-glossy --method lightcuts --frames 16 --out glossy.png\n  \
         cssm render --method lightmap --component indirect --exr indirect.exr\n  \
         cssm render --method reference --bounces 3 --samples 1024 --exr truth.exr\n  \
         cssm render scenes/cornell-glossy --method direct --out glossy.png --exr glossy.exr --size 1280x720 --timings",
        runtime::method::describe_methods()
    )
}

#[derive(clap::Args)]
pub struct RenderArgs {
    /// Scene directory. Default: the built-in Cornell box.
    scene: Option<PathBuf>,
    /// Rendering method (see the list below).
    #[arg(long, default_value = "direct", value_parser = parse_method)]
    method: &'static MethodEntry,
    /// Output PNG (tone-mapped sRGB).
    #[arg(long, default_value = "render.png")]
    out: PathBuf,
    /// Also write linear radiance to this OpenEXR file.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Image size WIDTHxHEIGHT. Default: the scene camera's resolution.
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Exposure in stops (radiance is scaled by 2^EV before tone mapping).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    exposure: f32,
    /// Shadow-map resolution in texels per side.
    #[arg(long, default_value_t = runtime::common::shadow_map::DEFAULT_RESOLUTION)]
    shadow_resolution: u32,
    /// Print GPU milliseconds per pass (timestamp queries): the first frame, which also runs
    /// the view-independent passes, and the last (one more frame is rendered to time it warm).
    #[arg(long)]
    timings: bool,
    /// The scene's baked CSSM (`cssm bake`), for the methods that need one. Default: bake one
    /// in memory at atlas 64, cube 32.
    #[arg(long)]
    cssm: Option<PathBuf>,
    /// Indirect bounces (the option `bounces`; lightcuts: the final gather is the last).
    /// Default: the method's.
    #[arg(long)]
    bounces: Option<u32>,
    /// Oracle threshold (the option `threshold`, §4.3): a sender is refined while the
    /// tone-mapped upper bound of what it sends is above this; smaller is slower and closer.
    #[arg(long, allow_negative_numbers = true)]
    threshold: Option<f32>,
    /// Paths per pixel of `--method reference` (the option `samples`).
    #[arg(long)]
    samples: Option<u32>,
    /// Set a method option, NAME=VALUE (see the list below); repeatable.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
    /// Frames to render and average, 1 to 4096 (lightcuts: every frame jitters its senders
    /// over their nodes' surfaces, §4.5, so the average converges for glossy scenes).
    #[arg(long, default_value_t = 1)]
    frames: u32,
    /// Which light the image holds: direct, indirect or full.
    #[arg(long, default_value = "full")]
    component: Component,
}

fn parse_method(s: &str) -> Result<&'static MethodEntry, String> {
    runtime::method::find(s).map_err(|e| e.to_string())
}

/// `WIDTHxHEIGHT`; the range is the renderer's to check.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT (for example 640x480)"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{s}': each side must be a whole number"))
    };
    Ok((parse(w)?, parse(h)?))
}

/// Most frames `--frames` takes.
const MAX_FRAMES: u32 = 4096;

/// The method options the user gave: the short flags, then `--set` in order. A short flag for
/// an option the method does not have is ignored with a warning (`--bounces` with `direct`);
/// `--set` of an unknown option is an error, from the method table.
fn option_values(args: &RenderArgs) -> Result<OptionValues, String> {
    let method = args.method;
    let mut values = OptionValues::default();
    let short = [
        ("bounces", args.bounces.map(OptionValue::Count)),
        ("threshold", args.threshold.map(OptionValue::Number)),
        ("samples", args.samples.map(OptionValue::Count)),
    ];
    for (name, value) in short {
        let Some(value) = value else { continue };
        if method.option(name).is_some() {
            values.set(name, value);
        } else {
            eprintln!("warning: --{name} has no effect on method {method}");
        }
    }
    // Several frames of lightcuts jitter unless told otherwise (§4.5).
    if args.frames > 1 && method.option("jitter").is_some() {
        values.set("jitter", OptionValue::Switch(true));
    }
    for assignment in &args.set {
        let (name, text) = assignment
            .split_once('=')
            .ok_or_else(|| format!("--set {assignment}: expected NAME=VALUE"))?;
        let spec = method.option(name.trim()).ok_or_else(|| {
            let known: Vec<&str> = method.options.iter().map(|o| o.name).collect();
            format!(
                "--set {assignment}: method {method} has no option '{}' (its options: {})",
                name.trim(),
                if known.is_empty() {
                    "none".into()
                } else {
                    known.join(", ")
                }
            )
        })?;
        values.set(spec.name, spec.parse(text)?);
    }
    Ok(values)
}

pub fn run_render(args: RenderArgs) -> CliResult {
    let dir = match &args.scene {
        Some(dir) => dir.clone(),
        None => builtin::cornell_box()
            .map_err(|e| format!("cannot prepare the built-in Cornell box: {e}"))?,
    };
    if !(1..=MAX_FRAMES).contains(&args.frames) {
        return Err(format!(
            "--frames {} is out of range 1..={MAX_FRAMES}",
            args.frames
        ));
    }
    let method = args.method;
    let values = option_values(&args)?;
    let resolved = method.resolve(&values).map_err(|e| e.to_string())?;
    check_writable(&args.out)?;
    if let Some(exr) = &args.exr {
        check_writable(exr)?;
    }
    let scene = load_scene(&dir)?;
    let (width, height) = args
        .size
        .unwrap_or((scene.camera.resolution[0], scene.camera.resolution[1]));
    let settings = RendererSettings {
        frame: FrameSettings {
            width,
            height,
            exposure: args.exposure.exp2(),
            shadow_resolution: args.shadow_resolution,
        },
        component: args.component,
        ..Default::default()
    };
    settings
        .frame
        .check()
        .map_err(|e| format!("{}: {e}", dir.display()))?;
    let image = match method.backend {
        Backend::Cpu(run) => render_on_cpu(&args, &scene, &settings, run, &resolved)?,
        Backend::Gpu(_) => {
            let file = if method.needs_cssm {
                Some(render_cssm(&args, &scene)?)
            } else {
                None
            };
            crate::quiet_mesa_wsi();
            let gpu = runtime::Gpu::new_headless().map_err(|e| e.to_string())?;
            let gpu_error = |e: runtime::RuntimeError| format!("{}: {e}", dir.display());
            let mut renderer = Renderer::new(
                &gpu.device,
                &gpu.queue,
                &scene,
                file.as_ref(),
                method,
                &values,
                &settings,
            )
            .map_err(gpu_error)?;
            let frames = args.frames + u32::from(args.timings);
            let image = readback::render_image(&mut renderer, frames).map_err(gpu_error)?;
            gpu.wait().map_err(gpu_error)?;
            if args.timings {
                print_timings(&gpu.describe(), &image);
            }
            eprintln!(
                "rendered {} with {method} at {width}x{height} on {}",
                scene.name,
                gpu.describe()
            );
            image
        }
    };
    save_png(&args.out, &image)?;
    if let Some(exr) = &args.exr {
        save_exr(exr, &image)?;
    }
    eprintln!(
        "wrote {}{}",
        args.out.display(),
        args.exr
            .as_ref()
            .map(|p| format!(", {}", p.display()))
            .unwrap_or_default()
    );
    Ok(ExitCode::SUCCESS)
}

fn print_timings(device: &str, image: &readback::Image) {
    if image.timings.is_empty() {
        println!("GPU timings: not supported by this adapter (no timestamp queries)");
        return;
    }
    let table = |title: &str, timings: &[(&'static str, f64)]| {
        println!("{title}");
        let mut total = 0.0;
        for (pass, ms) in timings {
            println!("  {pass:<30} {ms:8.3} ms");
            total += ms;
        }
        println!("  {:<30} {total:8.3} ms", "total");
    };
    table(
        &format!("GPU time per pass, first frame (with the view-independent passes; {device}):"),
        &image.first_timings,
    );
    table(
        &format!("GPU time per pass, last frame ({device}):"),
        &image.timings,
    );
}

/// A CPU method (the reference path tracer), with a progress bar; tone-mapped on the CPU with
/// the GPU's curve.
fn render_on_cpu(
    args: &RenderArgs,
    scene: &Scene,
    settings: &RendererSettings,
    run: fn(&CpuSetup) -> Result<Vec<[f32; 4]>, runtime::RuntimeError>,
    resolved: &runtime::method::Resolved,
) -> Result<readback::Image, String> {
    let (w, h) = (settings.frame.width, settings.frame.height);
    let bar = indicatif::ProgressBar::new(h as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg} [{bar:32}] {pos}/{len} rows, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(format!("{} with {}", scene.name, args.method));
    let view = runtime::common::camera::View::of_scene(scene, w, h);
    let radiance = run(&CpuSetup {
        scene,
        view: &view,
        component: settings.component,
        options: resolved,
        progress: &|done, _| bar.set_position(done / w.max(1) as u64),
    })
    .map_err(|e| format!("{}: {e}", scene.dir.display()))?;
    bar.finish_and_clear();
    let exposure = settings.frame.exposure;
    let display = radiance
        .iter()
        .flat_map(|c| {
            let [r, g, b] = runtime::common::tonemap::tonemap([c[0], c[1], c[2]], exposure);
            [r, g, b, 255]
        })
        .collect();
    let options: Vec<String> = resolved.iter().map(|(k, v)| format!("{k} {v}")).collect();
    eprintln!(
        "{} {} at {w}x{h} on the CPU ({})",
        args.method,
        scene.name,
        options.join(", ")
    );
    Ok(readback::Image {
        width: w,
        height: h,
        radiance,
        display,
        first_timings: Vec::new(),
        timings: Vec::new(),
    })
}

/// The CSSM `cssm render` uses: `--cssm`, checked against the scene, else a small one baked in
/// memory.
fn render_cssm(args: &RenderArgs, scene: &Scene) -> Result<CssmFile, String> {
    if let Some(path) = &args.cssm {
        return runtime::load::read_cssm(path, scene).map_err(|e| e.to_string());
    }
    eprintln!(
        "no --cssm given: baking {} at atlas 64, cube 32 first (bake once with `cssm bake` and \
         pass --cssm to skip this)",
        scene.name
    );
    let options = bake::BakeOptions {
        atlas_resolution: 64,
        cube_resolution: 32,
        ..Default::default()
    };
    Ok(bake_with_progress(scene, &options)?.file)
}

/// Encodes `image` as `format` in memory and writes it with the project's one atomic write
/// (`formats::cssm::write_bytes_atomic`): a failed write never leaves a half-written image.
fn save_image(
    path: &Path,
    image: ::image::DynamicImage,
    format: ::image::ImageFormat,
) -> Result<(), String> {
    let fail = |reason: String| format!("{}: {reason}", path.display());
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut bytes, format)
        .map_err(|e| fail(e.to_string()))?;
    formats::cssm::write_bytes_atomic(path, bytes.get_ref()).map_err(|e| match e {
        // The error names the path already; keep just the cause.
        formats::cssm::CssmError::Io { error, .. } => fail(error.to_string()),
        other => fail(other.to_string()),
    })
}

/// The tone-mapped image as PNG.
fn save_png(path: &Path, image: &readback::Image) -> Result<(), String> {
    let img = ::image::RgbaImage::from_raw(image.width, image.height, image.display.clone())
        .ok_or_else(|| format!("{}: the display image has the wrong size", path.display()))?;
    save_image(path, img.into(), ::image::ImageFormat::Png)
}

/// The linear radiance as OpenEXR (32-bit float RGBA).
fn save_exr(path: &Path, image: &readback::Image) -> Result<(), String> {
    let data: Vec<f32> = image.radiance.iter().flatten().copied().collect();
    let img = ::image::Rgba32FImage::from_raw(image.width, image.height, data)
        .ok_or_else(|| format!("{}: the radiance image has the wrong size", path.display()))?;
    save_image(path, img.into(), ::image::ImageFormat::OpenExr)
}
