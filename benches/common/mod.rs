//! What the renderer benchmarks share (`frame_time.rs`, `rsm_time.rs`, `vct_time.rs`): their
//! flags, the median, one frame, a persistent renderer's timed frames and how a table cell lists
//! its passes, the report written.

use std::{path::Path, time::Instant};

use cssm::{
    formats::scene::SpotLight,
    runtime::{Gpu, Renderer},
};

/// The value after the flag `name`, if given.
pub fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
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
