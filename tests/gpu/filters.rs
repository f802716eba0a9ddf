//! The edge-aware filters (`cssm_runtime::common::filters`, §4.5 of Bang 2011 and Kopf et al.
//! 2007) on the GPU against their CPU twins, guided by a G-buffer the renderer drew of the
//! Cornell box at odd sizes (so that the last low-res row and column are clamped).

use cssm_formats::Scene;
use cssm_runtime::{
    Renderer, RendererSettings,
    common::{
        filters::{self, CpuGuide, EdgeAwareFilter, FilterOptions, LowGuide},
        readback::{read_buffer, read_texture, render_image},
        timestamps::PassTimer,
    },
    frame::{FrameContext, FrameEncoder, FrameSettings},
    method::{self, OptionValues},
};
use glam::Vec4;

use super::gpu;

/// Little-endian `f32` quadruples.
fn quads(bytes: &[u8]) -> Vec<[f32; 4]> {
    bytes
        .chunks_exact(16)
        .map(|q| {
            std::array::from_fn(|i| f32::from_le_bytes(q[4 * i..4 * i + 4].try_into().unwrap()))
        })
        .collect()
}

/// The renderer's G-buffer read back as the CPU twins' guide.
fn guide(ctx: &FrameContext) -> CpuGuide {
    let read = |texture| {
        quads(&read_texture(&ctx.device, &ctx.queue, texture, 16).expect("read G-buffer"))
    };
    let (width, height) = ctx.gbuffer.size();
    CpuGuide {
        width,
        height,
        position: read(&ctx.gbuffer.position),
        normal: read(&ctx.gbuffer.normal),
        eye: ctx.gpu_view().eye.into(),
        low: None,
    }
}

/// A deterministic pseudo-random signal in [0.05, 1.05), away from zero so that the relative
/// difference means something.
fn signal(len: usize, seed: u32) -> Vec<Vec4> {
    let mut state = seed.wrapping_mul(0x9E37_79B9) | 1;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        0.05 + (state >> 8) as f32 / (1u32 << 24) as f32
    };
    (0..len)
        .map(|_| Vec4::new(next(), next(), next(), next()))
        .collect()
}

/// Runs `filter` on a random signal of two layers and returns the largest relative difference
/// of its output from the CPU twins', and the pass timings.
fn run_and_compare(
    ctx: &FrameContext,
    filter: &EdgeAwareFilter,
    guide: &CpuGuide,
    seed: u32,
) -> (f32, Vec<(&'static str, f64)>) {
    let (device, queue) = (&ctx.device, &ctx.queue);
    let options = filter.options();
    let (lw, lh) = filter.low_size();
    assert_eq!((lw, lh), filters::low_size(ctx.size(), options.factor));
    let input = signal((2 * lw * lh) as usize, seed);
    let bytes: Vec<u8> = input
        .iter()
        .flat_map(|v| v.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    queue.write_buffer(filter.input(), 0, &bytes);
    let mut timer = PassTimer::new(device, queue);
    let mut encoder = device.create_command_encoder(&Default::default());
    filter.run(&mut FrameEncoder {
        encoder: &mut encoder,
        timer: &mut timer,
        index: 0,
    });
    timer.resolve(&mut encoder);
    queue.submit([encoder.finish()]);
    // GPU validation errors of the filter's creation or run.
    gpu().wait().expect("filter on the GPU");
    let timings = timer.read(device, queue).expect("timings");
    let output = filter.output();
    let gpu_out = quads(&read_buffer(device, queue, output, 0, output.size()).expect("read"));
    let cpu_out = filters::upsample(
        &filters::blur(&input, 2, guide, &options),
        2,
        guide,
        &options,
    );
    assert_eq!(gpu_out.len(), cpu_out.len());
    let mut worst = 0.0f32;
    for (g, c) in gpu_out.iter().zip(&cpu_out) {
        let g = Vec4::from(*g);
        let difference = (g - *c).abs().max_element() / c.abs().max_element().max(1e-3);
        worst = worst.max(difference);
    }
    (worst, timings)
}

#[test]
fn filters_match_cpu_twin() {
    let gpu = gpu();
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    let scene = Scene::load(&dir).expect("built-in scene loads");
    let settings = |width, height| RendererSettings {
        frame: FrameSettings {
            width,
            height,
            shadow_resolution: 64,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut renderer = Renderer::new(
        &gpu.device,
        &gpu.queue,
        &scene,
        None,
        method::find("direct").expect("direct"),
        &OptionValues::default(),
        &settings(37, 29),
    )
    .expect("renderer");
    render_image(&mut renderer, 1).expect("frame");
    let ctx = renderer.context();
    let cpu_guide = guide(ctx);
    let covered = cpu_guide.position.iter().filter(|p| p[3] > 0.0).count();
    eprintln!("G-buffer 37x29: {covered} of {} pixels covered", 37 * 29);
    let limit = 1e-4;
    let mut seed = 1;
    for factor in [1, 2, 3] {
        for radius in [0, 8] {
            let options = FilterOptions {
                factor,
                radius,
                ..Default::default()
            };
            let filter = EdgeAwareFilter::new(
                &ctx.device,
                &ctx.gbuffer,
                &ctx.view,
                2,
                options,
                LowGuide::Representative,
            )
            .expect("filter");
            let (worst, timings) = run_and_compare(ctx, &filter, &cpu_guide, seed);
            seed += 1;
            eprintln!(
                "factor {factor} radius {radius}: max relative difference GPU vs CPU {worst:.3e} \
                 (timings {timings:?})"
            );
            assert!(worst < limit, "factor {factor} radius {radius}: {worst}");
            if !timings.is_empty() {
                let names: Vec<_> = timings.iter().map(|(n, _)| *n).collect();
                let expected: &[&str] = if radius > 0 {
                    &["edge-aware blur", "upsample"]
                } else {
                    &["upsample"]
                };
                assert_eq!(names, expected);
            }
        }
    }

    // After a resize, the filter follows the new G-buffer.
    let options = FilterOptions::default();
    let mut filter = EdgeAwareFilter::new(
        &ctx.device,
        &ctx.gbuffer,
        &ctx.view,
        2,
        options,
        LowGuide::Representative,
    )
    .expect("filter");
    renderer.resize(21, 13).expect("resize");
    render_image(&mut renderer, 1).expect("frame");
    let ctx = renderer.context();
    filter.resize(
        &ctx.device,
        &ctx.gbuffer,
        &ctx.view,
        LowGuide::Representative,
    );
    assert_eq!(filter.low_size(), (11, 7));
    let (worst, _) = run_and_compare(ctx, &filter, &guide(ctx), seed);
    eprintln!("after resize to 21x13: max relative difference {worst:.3e}");
    assert!(worst < limit, "after resize: {worst}");
}
