//! What the renderer benchmarks share (`frame_time.rs`, `method_time.rs`, `vct_pools.rs`,
//! `ssil_screen.rs`): their flags and the device, scene and target they start
//! from, the median, one frame, a persistent renderer's timed frames and how a table cell lists
//! its passes, the report written.

// Each benchmark includes this module and uses a part of it.
#![allow(dead_code)]

pub mod query_work;

use std::{
    path::{Path, PathBuf},
    str::FromStr,
    time::Instant,
};

use cssm::{
    formats::{Scene, scene::SpotLight},
    runtime::{self, Gpu, Renderer, RendererSettings, frame::FrameSettings, method::OptionValues},
};

/// The value after the flag `name`, if given.
pub fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
}

/// The size `WIDTHxHEIGHT` after the flag `name`, or `default`.
///
/// # Panics
/// A value that is not `WIDTHxHEIGHT`.
pub fn size_arg(args: &[String], name: &str, default: (u32, u32)) -> (u32, u32) {
    let Some(size) = arg(args, name) else {
        return default;
    };
    size.split_once('x')
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
        .unwrap_or_else(|| panic!("{name} takes WIDTHxHEIGHT, not {size}"))
}

/// The scene of `--scene DIR` (default the built-in Cornell box) baked at `--atlas` (128) and
/// `--cube` (32): its folder, the scene and the file.
///
/// # Panics
/// A scene that does not load or bake.
pub fn baked_scene(args: &[String]) -> (PathBuf, Scene, cssm::formats::CssmFile) {
    let dir = arg(args, "--scene")
        .map(PathBuf::from)
        .unwrap_or_else(|| cssm::builtin::cornell_box().expect("built-in scene"));
    let scene = Scene::load(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    let options = cssm::bake::BakeOptions {
        atlas_resolution: parsed(args, "--atlas", 128),
        cube_resolution: parsed(args, "--cube", 32),
        ..Default::default()
    };
    let file = cssm::bake::bake(&scene, &options, &mut |_| {})
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .file;
    (dir, scene, file)
}

/// Best GPU milliseconds of `reps` runs of `work`, which records one timed pass (the query
/// benchmarks); `None` when the adapter timed nothing.
pub fn best_ms(
    gpu: &runtime::Gpu,
    reps: u32,
    mut work: impl FnMut(&mut runtime::common::timestamps::PassTimer),
) -> Option<f64> {
    let mut timer = runtime::common::timestamps::PassTimer::new(&gpu.device, &gpu.queue);
    let mut best: Option<f64> = None;
    for _ in 0..reps {
        work(&mut timer);
        let t = timer.read(&gpu.device, &gpu.queue).expect("timestamps");
        let ms: f64 = t.iter().map(|(_, ms)| ms).sum();
        if !t.is_empty() {
            best = Some(best.map_or(ms, |b: f64| b.min(ms)));
        }
    }
    best
}

/// The value of the flag `name` parsed, or `default` when the flag is absent or does not parse.
pub fn parsed<T: FromStr>(args: &[String], name: &str, default: T) -> T {
    arg(args, name)
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

/// What a renderer benchmark of one scene starts from: `--size` (or its default), `--frames`
/// (5), `--shadow-resolution`, `--scene` (the built-in Cornell box), `--out`; the headless
/// device, the scene, the settings and an offscreen target of the size.
pub struct Bench {
    /// The command line.
    pub args: Vec<String>,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Timed frames after the first.
    pub frames: usize,
    /// Shadow-map (and RSM) resolution.
    pub shadow_resolution: u32,
    /// Where the report goes.
    pub out: Option<PathBuf>,
    /// The device.
    pub gpu: Gpu,
    /// The scene.
    pub scene: Scene,
    /// The renderers' settings.
    pub settings: RendererSettings,
    /// The offscreen target's view.
    pub view: wgpu::TextureView,
}

impl Bench {
    /// Parses the flags, opens the device and loads the scene.
    pub fn new(default_size: (u32, u32)) -> Self {
        let args: Vec<String> = std::env::args().collect();
        let (width, height) = size(&args, default_size);
        let frames = parsed(&args, "--frames", 5);
        let shadow_resolution = parsed(
            &args,
            "--shadow-resolution",
            runtime::common::shadow_map::DEFAULT_RESOLUTION,
        );
        let dir = arg(&args, "--scene")
            .map(PathBuf::from)
            .unwrap_or_else(|| cssm::builtin::cornell_box().expect("built-in scene"));
        let out = arg(&args, "--out").map(PathBuf::from);
        let gpu = Gpu::new_headless().unwrap_or_else(|e| panic!("{e}"));
        let scene = Scene::load(&dir).unwrap_or_else(|e| panic!("{e}"));
        let settings = RendererSettings {
            frame: FrameSettings {
                width,
                height,
                shadow_resolution,
                ..Default::default()
            },
            ..Default::default()
        };
        let target = runtime::common::readback::offscreen_target(&gpu.device, width, height);
        let view = target.create_view(&Default::default());
        Self {
            args,
            width,
            height,
            frames,
            shadow_resolution,
            out,
            gpu,
            scene,
            settings,
            view,
        }
    }

    /// What the report's first line says of the run: the scene and its triangles, the size,
    /// the shadow maps' resolution, the device, the frames timed.
    pub fn setting(&self) -> String {
        format!(
            "{} ({} triangles), {}x{}, shadow maps and RSM {}², on {}; median of {} frames \
             after the first",
            self.scene.name,
            self.scene.triangle_materials.len(),
            self.width,
            self.height,
            self.shadow_resolution,
            self.gpu.describe(),
            self.frames
        )
    }

    /// [`timed_frames`] of `renderer` into the bench's target.
    pub fn timed(
        &self,
        renderer: &mut Renderer,
        light: Option<&SpotLight>,
    ) -> (f64, Vec<(&'static str, f64)>) {
        timed_frames(&self.gpu, renderer, &self.view, self.frames, light)
    }

    /// A renderer of method `name` with `values` on the scene.
    pub fn renderer(&self, name: &str, values: &OptionValues) -> Renderer {
        let entry = runtime::method::find(name).expect("method");
        Renderer::new(
            &self.gpu.device,
            &self.gpu.queue,
            &self.scene,
            None,
            entry,
            values,
            &self.settings,
        )
        .expect("renderer")
    }
}

/// `--size WxH`, or `default`.
pub fn size(args: &[String], default: (u32, u32)) -> (u32, u32) {
    arg(args, "--size")
        .and_then(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .unwrap_or(default)
}

/// The median of `v` (the upper one of an even count).
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Records one frame into `target`, submits it and waits for the GPU.
pub fn frame(gpu: &Gpu, renderer: &mut Renderer, target: &wgpu::TextureView) {
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    renderer.render(&mut encoder, target);
    gpu.queue.submit([encoder.finish()]);
    gpu.wait().expect("frame");
}

/// A first frame, then the median wall-clock milliseconds of `frames` frames from submit to the
/// GPU's idle, `light` set before each when given (the light moves every frame), and the GPU
/// passes of the last.
pub fn timed_frames(
    gpu: &Gpu,
    renderer: &mut Renderer,
    target: &wgpu::TextureView,
    frames: usize,
    light: Option<&SpotLight>,
) -> (f64, Vec<(&'static str, f64)>) {
    frame(gpu, renderer, target);
    let mut passes = Vec::new();
    let times: Vec<f64> = (0..frames.max(1))
        .map(|_| {
            if let Some(light) = light {
                renderer.set_light(0, light).expect("light");
            }
            let start = Instant::now();
            frame(gpu, renderer, target);
            let ms = start.elapsed().as_secs_f64() * 1e3;
            passes = renderer.read_timings().expect("timings");
            ms
        })
        .collect();
    (median(times), passes)
}

/// A table cell of GPU milliseconds per pass and their sum, or "no timestamps".
pub fn passes_cell(passes: &[(&str, f64)]) -> String {
    if passes.is_empty() {
        return "no timestamps".into();
    }
    let total: f64 = passes.iter().map(|(_, t)| t).sum();
    let list: Vec<String> = passes.iter().map(|(n, t)| format!("{n} {t:.2}")).collect();
    format!("{} (sum {total:.2})", list.join(", "))
}

/// Writes `report` to `out` when given.
pub fn write_report(out: Option<&Path>, report: &str) {
    if let Some(out) = out {
        std::fs::write(out, report).unwrap_or_else(|e| panic!("{}: {e}", out.display()));
        println!("wrote {}", out.display());
    }
}
