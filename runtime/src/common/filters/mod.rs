//! Edge-aware filters for indirect light computed at reduced resolution, shared by the
//! techniques that need them (`filters.wgsl`, with `lowres.wgsl`).
//!
//! A technique that samples its indirect light at `factor` times fewer pixels per side
//! (§4.5, Bang 2011) writes it into [`EdgeAwareFilter::input`]; the filter then
//!
//! 1. blurs it at low resolution with a separable cross-bilateral kernel guided by the
//!    G-buffer at each low-res pixel's [`representative`] pixel (`blur_x`, `blur_y`; timed
//!    together as "edge-aware blur"): the thesis smooths its reduced-resolution final gather
//!    with a kernel of 17 taps that does not blur across depth or normal discontinuities;
//! 2. brings it back to full resolution with joint bilateral up-sampling (Kopf et al. 2007,
//!    "Joint bilateral upsampling"): the 2x2 low-res samples around each full-res pixel,
//!    bilinear weights times depth and normal weights against that pixel's own G-buffer, so
//!    that edges stay where the full-res geometry has them ("upsample").
//!
//! Weights, for a reference guide `c` (the blur's centre, or the up-sampled pixel) and a tap
//! or sample `t`, with `d` the distance from the eye:
//! `exp(-(d_t - d_c)² / (depth_sigma d_c)²) · max(0, n_c·n_t)^normal_power`, times
//! `exp(-k² / (2 spatial_sigma²))` for the blur's tap at offset `k` and the bilinear weight for
//! the up-sampling. The depth tolerance is relative to the distance, so that it means the same
//! near and far from the eye.
//!
//! The CPU twins [`blur`] and [`upsample`] do the same arithmetic in `f32`; the GPU test
//! `tests/gpu/filters.rs` holds the two together on a rendered G-buffer.
//!
//! # Where it lives
//!
//! This file holds the shader, the limits, the low-res geometry both sides share
//! ([`low_size`], [`representative`]) and the passes as a method declares them; `options.rs`
//! the filters' parameters ([`FilterOptions`]) and the method options that set them; `gpu.rs`
//! the passes on the GPU ([`EdgeAwareFilter`]); `cpu.rs` the CPU twins and the weights they
//! share with `bilateral.wgsl` ([`bilateral_weight`], [`upsample_weights`]); `tests.rs` the
//! twins' tests.

mod cpu;
mod gpu;
mod options;
#[cfg(test)]
mod tests;

pub use cpu::{CpuGuide, LowRows, bilateral_weight, blur, upsample, upsample_weights};
pub use gpu::{EdgeAwareFilter, LowGuide};
pub use options::FilterOptions;
pub(crate) use options::{blur_option, downsample_option};

/// `common/filters.wgsl`: edge-aware blur (`blur_x`, `blur_y`) and joint bilateral up-sampling
/// (`upsample`), with `common/lowres.wgsl`.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("edge-aware filters", "common/filters.wgsl");

/// Largest blur radius (`filters.wgsl`: `MAX_TAPS` = 2 · 16 + 1).
pub const MAX_RADIUS: u32 = 16;

/// Largest reduction per side.
pub const MAX_FACTOR: u32 = 4;

/// Size of the low-res image for a full-res `(width, height)` reduced by `factor` per side.
pub fn low_size((w, h): (u32, u32), factor: u32) -> (u32, u32) {
    (w.div_ceil(factor), h.div_ceil(factor))
}

/// The full-res pixel low-res pixel `low` stands for: the centre of its `factor` x `factor`
/// block, clamped to the `full` image (`lowres.wgsl`: `lowres_representative`). A technique's
/// sampling pass reads the G-buffer there, and the filters take their guide from it.
pub fn representative(low: (u32, u32), factor: u32, full: (u32, u32)) -> (u32, u32) {
    (
        (low.0 * factor + factor / 2).min(full.0 - 1),
        (low.1 * factor + factor / 2).min(full.1 - 1),
    )
}

/// The filters' passes as a method declares them ([`crate::method::MethodEntry::passes`]):
/// the blur over the reduced light, then the up-sampling to the G-buffer's resolution.
pub const PASSES: [crate::frame::PassInfo; 2] = {
    use crate::frame::{PassInfo, Slot, Stage};
    [
        PassInfo {
            name: "edge-aware blur",
            stage: Stage::Frame,
            reads: &[Slot::Reduced, Slot::GBuffer, Slot::View],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "upsample",
            stage: Stage::Frame,
            reads: &[Slot::Reduced, Slot::GBuffer, Slot::View],
            writes: &[Slot::Upsampled],
        },
    ]
};
