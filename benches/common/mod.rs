//! What the renderer benchmarks share (`frame_time.rs`, `rsm_time.rs`): their flags, the median,
//! one timed frame.

use cssm::runtime::{Gpu, Renderer};

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
