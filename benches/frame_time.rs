//! Frame time of the persistent renderer (issue: the renderer seam, "Speed"): the second and
//! later frames of one [`Renderer`] against a one-shot render that builds every pipeline,
//! buffer and bind group and runs the view-independent passes before its one frame (what
//! `frame::render` did before the renderer existed), for `direct`, `lightmap` and `lightcuts`
//! on the Cornell box, measured in the same run on the same device.
//!
//! ```text
//! cargo bench --bench frame_time -- [--size 640x480] [--frames 5] [--one-shots 3]
//!     [--methods direct,lightmap,lightcuts] [--method NAME:OPTION=VALUE,...]... [--atlas 64]
//!     [--cube 32] [--moving-light] [--out FILE.md]
//! ```
//!
//! `--methods all` names every GPU method of the method table at its defaults; `--method SPEC`
//! (repeatable, instead of `--methods`) a variant with options, as `cssm render --method` takes
//! it (`lightcuts:gather=walk`), and beside `--methods all` replaces that method's defaults;
//! `--one-shots 0` times the
//! persistent renderer alone. `--moving-light` adds a row per method whose light is set again
//! before every frame, as a dragged light is: the prepare passes (shadow maps, and the
//! radiosity of the CSSM methods) run in every frame (issue 49's "light moving" frame).
//!
//! Wall-clock milliseconds per frame from submit to the GPU's idle (median), and GPU
//! milliseconds per pass from timestamp queries where the adapter has them. On lavapipe the
//! ratio says what the persistent renderer saves on the CPU side; absolute GPU times count only
//! from a real GPU (`reports/runtime.sh`).

use std::{path::PathBuf, time::Instant};

use cssm::{bake, formats, runtime};
use runtime::{Gpu, Renderer, RendererSettings, frame::FrameSettings, method};

#[path = "common/mod.rs"]
mod common;

use common::{arg, frame, median, passes_cell, timed_frames, write_report};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (width, height) = common::size(&args, (640, 480));
    let frames: usize = arg(&args, "--frames")
        .and_then(|s| s.parse().ok())
        .unwrap_or(5);
    let one_shots: usize = arg(&args, "--one-shots")
        .and_then(|s| s.parse().ok())
        .unwrap_or(3);
    let atlas: u32 = arg(&args, "--atlas")
        .and_then(|s| s.parse().ok())
        .unwrap_or(64);
    let cube: u32 = arg(&args, "--cube")
        .and_then(|s| s.parse().ok())
        .unwrap_or(32);
    let methods = arg(&args, "--methods").unwrap_or_else(|| "direct,lightmap,lightcuts".into());
    let specs: Vec<&str> = args
        .windows(2)
        .filter(|w| w[0] == "--method")
        .map(|w| w[1].as_str())
        .collect();
    let methods: Vec<&str> = if methods == "all" {
        // A `--method NAME:OPTIONS` beside `--methods all` stands in for NAME's defaults (the
        // smoke run's `vct:resolution=16`, whose default voxel grid takes minutes on lavapipe).
        runtime::METHODS
            .iter()
            .filter(|m| m.on_gpu())
            .map(|m| {
                specs
                    .iter()
                    .copied()
                    .find(|s| s.split(':').next() == Some(m.name))
                    .unwrap_or(m.name)
            })
            .collect()
    } else if !specs.is_empty() {
        specs
    } else {
        methods.split(',').map(str::trim).collect()
    };
    let out: Option<PathBuf> = arg(&args, "--out").map(PathBuf::from);
    let moving_light = args.iter().any(|a| a == "--moving-light");

    let gpu = Gpu::new_headless().unwrap_or_else(|e| panic!("{e}"));
    let dir = cssm::builtin::cornell_box().expect("built-in scene");
    let scene = formats::Scene::load(&dir).expect("scene loads");
    let options = bake::BakeOptions {
        atlas_resolution: atlas,
        cube_resolution: cube,
        ..Default::default()
    };
    let file = bake::bake(&scene, &options, &mut |_| {})
        .expect("bake")
        .file;
    let settings = RendererSettings {
        frame: FrameSettings {
            width,
            height,
            ..Default::default()
        },
        ..Default::default()
    };
    let target = runtime::common::readback::offscreen_target(&gpu.device, width, height);
    let view = target.create_view(&Default::default());
    let one_shot_medians = if one_shots == 0 {
        "no one-shot render".to_string()
    } else {
        format!("median of {one_shots} one-shot renders")
    };
    let mut report = format!(
        "Cornell box (atlas {atlas}, cube {cube}), {width}x{height}, on {}; {one_shot_medians} \
         and median of {frames} persistent frames after the first.\n\n\
         | method | one-shot ms | persistent frame ms | ratio | GPU ms per pass, persistent frame |\n\
         | --- | --- | --- | --- | --- |\n",
        gpu.describe()
    );
    for name in methods {
        let (method_name, options) = name.split_once(':').unwrap_or((name, ""));
        let entry = method::find(method_name).unwrap_or_else(|e| panic!("{e}"));
        let values = entry
            .parse_options(options)
            .unwrap_or_else(|e| panic!("--method {name}: {e}"));
        let cssm = entry.needs_cssm.then_some(&file);
        let build = || {
            Renderer::new(
                &gpu.device,
                &gpu.queue,
                &scene,
                cssm,
                entry,
                &values,
                &settings,
            )
            .expect("renderer")
        };
        // `--one-shots 0` times the persistent renderer alone (one renderer built, not three:
        // on a CPU device each build's prepare passes take most of the run).
        let one_shot = (one_shots > 0).then(|| {
            // Warm the driver's shader caches once, outside both measurements.
            frame(&gpu, &mut build(), &view);
            let times: Vec<f64> = (0..one_shots)
                .map(|_| {
                    let start = Instant::now();
                    frame(&gpu, &mut build(), &view);
                    start.elapsed().as_secs_f64() * 1e3
                })
                .collect();
            median(times)
        });
        let mut renderer = build();
        let (b, passes) = timed_frames(&gpu, &mut renderer, &view, frames, None);
        let (a, ratio) = match one_shot {
            Some(a) => (format!("{a:.1}"), format!("{:.1}x", a / b)),
            None => ("-".into(), "-".into()),
        };
        let row = format!(
            "| {name} | {a} | {b:.1} | {ratio} | {} |\n",
            passes_cell(&passes)
        );
        print!("{row}");
        report += &row;
        if moving_light && let Some(light) = scene.lights.first() {
            let (b, passes) = timed_frames(&gpu, &mut renderer, &view, frames, Some(light));
            let row = format!(
                "| {name}, light moving | - | {b:.1} | - | {} |\n",
                passes_cell(&passes)
            );
            print!("{row}");
            report += &row;
        }
    }
    write_report(out.as_deref(), &report);
}
