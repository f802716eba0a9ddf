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

use glam::{Vec3, Vec4};
use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{gbuffer::GBuffer, layout},
    frame::FrameEncoder,
    method::{OptionKind, OptionSpec},
    shaders,
};

/// `common/filters.wgsl`: edge-aware blur (`blur_x`, `blur_y`) and joint bilateral up-sampling
/// (`upsample`), with `common/lowres.wgsl`.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("edge-aware filters", "common/filters.wgsl");

/// Largest blur radius (`filters.wgsl`: `MAX_TAPS` = 2 · 16 + 1).
pub const MAX_RADIUS: u32 = 16;

/// Largest reduction per side.
pub const MAX_FACTOR: u32 = 4;

/// The `downsample` option of a method whose light the filters up-sample ([`FilterOptions`]'s
/// factor), with its own help and default.
pub(crate) const fn downsample_option(help: &'static str, default: u32) -> OptionSpec {
    OptionSpec {
        name: "downsample",
        help,
        kind: OptionKind::Count {
            default,
            min: 1,
            max: MAX_FACTOR,
        },
    }
}

/// The `blur` option of a method whose light the filters blur ([`FilterOptions`]'s radius),
/// with its own help and default.
pub(crate) const fn blur_option(help: &'static str, default: u32) -> OptionSpec {
    OptionSpec {
        name: "blur",
        help,
        kind: OptionKind::Count {
            default,
            min: 0,
            max: MAX_RADIUS,
        },
    }
}

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

/// Parameters of the filters.
///
/// The defaults are starting values: the thesis' kernel of 17 taps (radius 8) at half
/// resolution, and tolerances that keep neighbouring surfaces apart in the Cornell box. Each
/// technique's measurements set its own defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterOptions {
    /// Reduction per side, 1 to [`MAX_FACTOR`].
    pub factor: u32,
    /// Blur taps on each side of the centre, 0 (no blur) to [`MAX_RADIUS`].
    pub radius: u32,
    /// Standard deviation of the blur's Gaussian, in low-res pixels.
    pub spatial_sigma: f32,
    /// Depth tolerance, relative to the reference's distance from the eye.
    pub depth_sigma: f32,
    /// Exponent of the normal weight `max(0, n_c·n_t)`; 0 ignores normals.
    pub normal_power: f32,
}

impl Default for FilterOptions {
    fn default() -> Self {
        Self {
            factor: 2,
            radius: 8,
            spatial_sigma: 4.0,
            depth_sigma: 0.1,
            normal_power: 8.0,
        }
    }
}

impl FilterOptions {
    /// A method's light at 1/`factor` of the resolution per side, blurred with `radius` taps on
    /// each side, the other settings at their defaults.
    pub fn reduced(factor: u32, radius: u32) -> Self {
        Self {
            factor,
            radius,
            ..Default::default()
        }
    }

    /// Refuses a factor outside 1 to [`MAX_FACTOR`], a radius above [`MAX_RADIUS`], sigmas
    /// that are not finite and positive, and a normal power that is not finite and
    /// non-negative.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] naming the value.
    pub fn check(&self) -> Result<(), RuntimeError> {
        let refuse = |msg: String| Err(RuntimeError::Unsupported(msg));
        if !(1..=MAX_FACTOR).contains(&self.factor) {
            return refuse(format!(
                "filter factor {} is out of range 1..={MAX_FACTOR}",
                self.factor
            ));
        }
        if self.radius > MAX_RADIUS {
            return refuse(format!(
                "filter radius {} is out of range 0..={MAX_RADIUS}",
                self.radius
            ));
        }
        for (name, sigma) in [
            ("spatial sigma", self.spatial_sigma),
            ("depth sigma", self.depth_sigma),
        ] {
            if !(sigma.is_finite() && sigma > 0.0) {
                return refuse(format!("filter {name} {sigma} must be finite and > 0"));
            }
        }
        if !(self.normal_power.is_finite() && self.normal_power >= 0.0) {
            return refuse(format!(
                "filter normal power {} must be finite and >= 0",
                self.normal_power
            ));
        }
        Ok(())
    }
}

/// `FilterParams` of `filters.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FilterParams {
    full_size: [u32; 2],
    low_size: [u32; 2],
    factor: u32,
    layers: u32,
    radius: u32,
    spatial_sigma: f32,
    depth_sigma: f32,
    normal_power: f32,
    guide_buffers: u32,
    guide_offset: u32,
}

/// Where the filters read the guide of a low-res pixel.
#[derive(Clone, Copy, Debug)]
pub enum LowGuide<'a> {
    /// The G-buffer at the pixel's [`representative`] (a technique that samples there).
    Representative,
    /// A technique's own low-res guide: `position` (xyz, w 1 where covered) and `normal` (xyz)
    /// per low-res pixel, row-major from element `offset` (a level of
    /// [`crate::common::pyramid::GBufferPyramid`]).
    Buffers {
        /// Positions, `vec4f` per pixel.
        position: &'a wgpu::Buffer,
        /// Normals, `vec4f` per pixel.
        normal: &'a wgpu::Buffer,
        /// Element of the low-res pixel (0, 0).
        offset: u32,
    },
}

/// What depends on the G-buffer's size.
struct Sized {
    full_size: (u32, u32),
    low_size: (u32, u32),
    input: wgpu::Buffer,
    output: wgpu::Buffer,
    /// Blur x and blur y bind groups (input -> scratch -> blurred), when `radius > 0`; the
    /// buffers are held by the bind groups.
    blur: Option<(wgpu::BindGroup, wgpu::BindGroup)>,
    upsample: wgpu::BindGroup,
}

/// The edge-aware blur and joint bilateral up-sampling on the GPU.
pub struct EdgeAwareFilter {
    options: FilterOptions,
    layers: u32,
    bind_layout: wgpu::BindGroupLayout,
    blur_x: wgpu::ComputePipeline,
    blur_y: wgpu::ComputePipeline,
    upsample: wgpu::ComputePipeline,
    sized: Sized,
}

impl EdgeAwareFilter {
    /// Buffers for `layers` planes at the G-buffer's size reduced by `options.factor`, the
    /// full-res guide read from `gbuffer`, the low-res one from `low_guide`, and the eye from
    /// the frame's `view` uniform.
    ///
    /// # Errors
    /// Options that [`FilterOptions::check`] refuses, or no layer.
    pub fn new(
        device: &wgpu::Device,
        gbuffer: &GBuffer,
        view: &wgpu::Buffer,
        layers: u32,
        options: FilterOptions,
        low_guide: LowGuide,
    ) -> Result<Self, RuntimeError> {
        options.check()?;
        if layers == 0 {
            return Err(RuntimeError::Unsupported(
                "an edge-aware filter of no layer".into(),
            ));
        }
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let bind_layout = layout::bind_group_layout(
            device,
            "edge-aware filters",
            &[
                layout::uniform(0, c),
                layout::uniform(1, c),
                layout::texture(2, d2, c),
                layout::texture(3, d2, c),
                layout::storage(4, true, c),
                layout::storage(5, false, c),
                layout::storage(6, true, c),
                layout::storage(7, true, c),
            ],
        );
        let module = SHADER.create(device);
        let pipeline = |label, entry| {
            layout::compute_pipeline_entry(device, label, &module, entry, &[&bind_layout])
        };
        let blur_x = pipeline("edge-aware blur x", "blur_x");
        let blur_y = pipeline("edge-aware blur y", "blur_y");
        let upsample = pipeline("upsample", "upsample");
        let sized = Self::bind(
            device,
            &bind_layout,
            gbuffer,
            view,
            layers,
            &options,
            low_guide,
        );
        Ok(Self {
            options,
            layers,
            bind_layout,
            blur_x,
            blur_y,
            upsample,
            sized,
        })
    }

    fn bind(
        device: &wgpu::Device,
        bind_layout: &wgpu::BindGroupLayout,
        gbuffer: &GBuffer,
        view: &wgpu::Buffer,
        layers: u32,
        options: &FilterOptions,
        low_guide: LowGuide,
    ) -> Sized {
        let full_size = gbuffer.size();
        let low = low_size(full_size, options.factor);
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("edge-aware filters params"),
            contents: bytemuck::bytes_of(&FilterParams {
                full_size: [full_size.0, full_size.1],
                low_size: [low.0, low.1],
                factor: options.factor,
                layers,
                radius: options.radius,
                spatial_sigma: options.spatial_sigma,
                depth_sigma: options.depth_sigma,
                normal_power: options.normal_power,
                guide_buffers: u32::from(matches!(low_guide, LowGuide::Buffers { .. })),
                guide_offset: match low_guide {
                    LowGuide::Buffers { offset, .. } => offset,
                    LowGuide::Representative => 0,
                },
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let planes = |label, (w, h): (u32, u32), usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16 * u64::from(w) * u64::from(h) * u64::from(layers),
                usage: wgpu::BufferUsages::STORAGE | usage,
                mapped_at_creation: false,
            })
        };
        let copy = wgpu::BufferUsages::COPY_SRC;
        let input = planes(
            "edge-aware filters input",
            low,
            copy | wgpu::BufferUsages::COPY_DST,
        );
        let output = planes("edge-aware filters output", full_size, copy);
        let position = gbuffer.position.create_view(&Default::default());
        let normal = gbuffer.normal.create_view(&Default::default());
        let unused = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("edge-aware filters unused guide"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let (low_position, low_normal) = match low_guide {
            LowGuide::Buffers {
                position, normal, ..
            } => (position, normal),
            LowGuide::Representative => (&unused, &unused),
        };
        let group = |label, from: &wgpu::Buffer, to: &wgpu::Buffer| {
            layout::bind_group(
                device,
                label,
                bind_layout,
                &[
                    params.as_entire_binding(),
                    view.as_entire_binding(),
                    wgpu::BindingResource::TextureView(&position),
                    wgpu::BindingResource::TextureView(&normal),
                    from.as_entire_binding(),
                    to.as_entire_binding(),
                    low_position.as_entire_binding(),
                    low_normal.as_entire_binding(),
                ],
            )
        };
        let (blur, upsample) = if options.radius > 0 {
            let scratch = planes("edge-aware blur scratch", low, wgpu::BufferUsages::empty());
            let blurred = planes("edge-aware blur", low, copy);
            let x = group("edge-aware blur x", &input, &scratch);
            let y = group("edge-aware blur y", &scratch, &blurred);
            (Some((x, y)), group("upsample", &blurred, &output))
        } else {
            (None, group("upsample", &input, &output))
        };
        Sized {
            full_size,
            low_size: low,
            input,
            output,
            blur,
            upsample,
        }
    }

    /// The low-res signal, `layers` planes of `vec4f` (index `(layer * low_h + y) * low_w +
    /// x`), which the technique's sampling pass writes.
    pub fn input(&self) -> &wgpu::Buffer {
        &self.sized.input
    }

    /// The filtered signal at full resolution, `layers` planes of `vec4f`; 0 where no surface
    /// covers the pixel.
    pub fn output(&self) -> &wgpu::Buffer {
        &self.sized.output
    }

    /// Width and height of the low-res signal.
    pub fn low_size(&self) -> (u32, u32) {
        self.sized.low_size
    }

    /// The options the filter was built with.
    pub fn options(&self) -> FilterOptions {
        self.options
    }

    /// New buffers and bind groups after the G-buffer was resized (pipelines stay), the
    /// low-res guide read from `low_guide`. The input is a new, zeroed buffer.
    pub fn resize(
        &mut self,
        device: &wgpu::Device,
        gbuffer: &GBuffer,
        view: &wgpu::Buffer,
        low_guide: LowGuide,
    ) {
        self.sized = Self::bind(
            device,
            &self.bind_layout,
            gbuffer,
            view,
            self.layers,
            &self.options,
            low_guide,
        );
    }

    /// Records blur x and blur y (timed together as "edge-aware blur"; none when the radius
    /// is 0) and "upsample".
    pub fn run(&self, frame: &mut FrameEncoder) {
        if let Some((x, y)) = &self.sized.blur {
            let (gx, gy) = shaders::groups_2d(self.sized.low_size);
            for (pipeline, group) in [(&self.blur_x, x), (&self.blur_y, y)] {
                let mut pass = frame.compute_pass("edge-aware blur");
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, group, &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
        }
        let mut pass = frame.compute_pass("upsample");
        pass.set_pipeline(&self.upsample);
        pass.set_bind_group(0, &self.sized.upsample, &[]);
        let (gx, gy) = shaders::groups_2d(self.sized.full_size);
        pass.dispatch_workgroups(gx, gy, 1);
    }
}

/// A low-res guide on the CPU: per low-res pixel, row-major, position (w 1 where covered) and
/// normal.
pub type LowRows = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// The G-buffer on the CPU, the guide of the CPU twins: full-res rows of the position
/// (xyz, w 1 where covered) and normal (xyz) targets, and the eye.
#[derive(Clone, Debug)]
pub struct CpuGuide {
    /// Full-res width.
    pub width: u32,
    /// Full-res height.
    pub height: u32,
    /// Per pixel xyz world position, w 1 where covered (`GBuffer::position`).
    pub position: Vec<[f32; 4]>,
    /// Per pixel xyz unit normal (`GBuffer::normal`).
    pub normal: Vec<[f32; 4]>,
    /// Eye position (`View::eye`).
    pub eye: Vec3,
    /// The low-res guide when the filter reads it from buffers ([`LowGuide::Buffers`]): per
    /// low-res pixel, row-major, position (w 1 where covered) and normal; `None` for the
    /// G-buffer at each low-res pixel's [`representative`].
    pub low: Option<LowRows>,
}

/// `filters.wgsl`: `Guide`.
struct Guide {
    covered: bool,
    distance: f32,
    normal: Vec3,
}

impl Guide {
    /// What [`bilateral_weight`] compares: distance from the eye and normal.
    fn key(&self) -> (f32, Vec3) {
        (self.distance, self.normal)
    }
}

impl CpuGuide {
    fn at(&self, (x, y): (u32, u32)) -> Guide {
        let i = (y * self.width + x) as usize;
        let p = self.position[i];
        Guide {
            covered: p[3] > 0.0,
            distance: self.eye.distance(Vec3::new(p[0], p[1], p[2])),
            normal: Vec4::from(self.normal[i]).truncate(),
        }
    }

    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// `filters.wgsl`: `low_guide_at`.
    fn low_at(&self, low: (u32, u32), factor: u32) -> Guide {
        match &self.low {
            None => self.at(representative(low, factor, self.size())),
            Some((position, normal)) => {
                let (lw, _) = low_size(self.size(), factor);
                let i = (low.1 * lw + low.0) as usize;
                let p = position[i];
                Guide {
                    covered: p[3] > 0.0,
                    distance: self.eye.distance(Vec3::new(p[0], p[1], p[2])),
                    normal: Vec4::from(normal[i]).truncate(),
                }
            }
        }
    }
}

/// `filters.wgsl`: `range_weight`, the depth and normal weight of `tap` against `centre`.
fn range_weight(centre: &Guide, tap: &Guide, options: &FilterOptions) -> f32 {
    bilateral_weight(
        centre.key(),
        tap.key(),
        options.depth_sigma,
        options.normal_power,
    )
}

/// `bilateral.wgsl`: `bilateral_weight`, the depth and normal weight of a tap (distance from
/// the eye, normal) against a centre whose distance is the reference; 0 for normals facing
/// apart.
pub fn bilateral_weight(
    (centre_distance, centre_normal): (f32, Vec3),
    (tap_distance, tap_normal): (f32, Vec3),
    depth_sigma: f32,
    normal_power: f32,
) -> f32 {
    let r = (tap_distance - centre_distance) / (depth_sigma * centre_distance.max(1e-6));
    let c = centre_normal.dot(tap_normal);
    if c <= 0.0 {
        return 0.0;
    }
    (-r * r).exp() * c.powf(normal_power)
}

/// `filters.wgsl`: `blur`, one pass along `axis`.
fn blur_pass(
    input: &[Vec4],
    layers: u32,
    guide: &CpuGuide,
    options: &FilterOptions,
    axis: (i32, i32),
) -> Vec<Vec4> {
    let (lw, lh) = low_size(guide.size(), options.factor);
    let plane = (lw * lh) as usize;
    let mut out = vec![Vec4::ZERO; plane * layers as usize];
    let radius = options.radius as i32;
    let s = options.spatial_sigma;
    for y in 0..lh {
        for x in 0..lw {
            let centre_index = (y * lw + x) as usize;
            let centre = guide.low_at((x, y), options.factor);
            if !centre.covered {
                continue;
            }
            let mut taps = Vec::with_capacity(2 * radius as usize + 1);
            for k in -radius..=radius {
                let (tx, ty) = (x as i32 + k * axis.0, y as i32 + k * axis.1);
                if tx < 0 || ty < 0 || tx >= lw as i32 || ty >= lh as i32 {
                    continue;
                }
                let (tx, ty) = (tx as u32, ty as u32);
                let tap = guide.low_at((tx, ty), options.factor);
                if !tap.covered {
                    continue;
                }
                let spatial = (-((k * k) as f32) / (2.0 * s * s)).exp();
                let w = spatial * range_weight(&centre, &tap, options);
                if w > 0.0 {
                    taps.push((w, (ty * lw + tx) as usize));
                }
            }
            for l in 0..layers as usize {
                let (mut sum, mut total) = (Vec4::ZERO, 0.0f32);
                for &(w, i) in &taps {
                    sum += w * input[l * plane + i];
                    total += w;
                }
                out[l * plane + centre_index] = sum / total;
            }
        }
    }
    out
}

/// CPU twin of the GPU blur (`blur_x`, then `blur_y`): `layers` low-res planes in, the same
/// out. Radius 0 returns the input unchanged (the GPU skips the blur).
///
/// # Panics
/// An `input` shorter than `layers` planes of the guide's low-res size.
pub fn blur(input: &[Vec4], layers: u32, guide: &CpuGuide, options: &FilterOptions) -> Vec<Vec4> {
    let (lw, lh) = low_size(guide.size(), options.factor);
    assert!(
        input.len() >= (lw * lh * layers) as usize,
        "blur: short input"
    );
    if options.radius == 0 {
        return input[..(lw * lh * layers) as usize].to_vec();
    }
    let scratch = blur_pass(input, layers, guide, options, (1, 0));
    blur_pass(&scratch, layers, guide, options, (0, 1))
}

/// CPU twin of the GPU up-sampling (`upsample`): `layers` low-res planes in, full-res planes
/// out.
///
/// # Panics
/// A `low` shorter than `layers` planes of the guide's low-res size.
pub fn upsample(low: &[Vec4], layers: u32, guide: &CpuGuide, options: &FilterOptions) -> Vec<Vec4> {
    let full = guide.size();
    let (lw, lh) = low_size(full, options.factor);
    assert!(
        low.len() >= (lw * lh * layers) as usize,
        "upsample: short input"
    );
    let (low_plane, full_plane) = ((lw * lh) as usize, (full.0 * full.1) as usize);
    let mut out = vec![Vec4::ZERO; full_plane * layers as usize];
    for y in 0..full.1 {
        for x in 0..full.0 {
            let pixel_index = (y * full.0 + x) as usize;
            let pixel = guide.at((x, y));
            if !pixel.covered {
                continue;
            }
            let f = options.factor as f32;
            let (qx, qy) = ((x as f32 + 0.5) / f - 0.5, (y as f32 + 0.5) / f - 0.5);
            let (bx, by) = (qx.floor(), qy.floor());
            let mut indices = [0usize; 4];
            let taps: [Guide; 4] = std::array::from_fn(|i| {
                let (ox, oy) = (i as i32 & 1, i as i32 >> 1);
                let sx = (bx as i32 + ox).clamp(0, lw as i32 - 1) as u32;
                let sy = (by as i32 + oy).clamp(0, lh as i32 - 1) as u32;
                indices[i] = (sy * lw + sx) as usize;
                guide.low_at((sx, sy), options.factor)
            });
            let weights = upsample_weights(
                pixel.key(),
                taps.map(|t| t.covered.then(|| t.key())),
                (qx - bx, qy - by),
                options.depth_sigma,
                options.normal_power,
            );
            for l in 0..layers as usize {
                let mut value = Vec4::ZERO;
                for i in 0..4 {
                    if weights[i] > 0.0 {
                        value += weights[i] * low[l * low_plane + indices[i]];
                    }
                }
                out[l * full_plane + pixel_index] = value;
            }
        }
    }
    out
}

/// `bilateral.wgsl`: `upsample_weights`, joint bilateral up-sampling from the 2x2 low-res taps
/// around a pixel (in the order (0,0), (1,0), (0,1), (1,1); `None` where uncovered), `t` the
/// pixel's fractional position between them: bilinear weights times [`bilateral_weight`]
/// against the pixel's (distance, normal), normalised; when every tap is rejected, weight 1 on
/// the covered tap nearest in distance; all 0 when none is covered.
pub fn upsample_weights(
    pixel: (f32, Vec3),
    taps: [Option<(f32, Vec3)>; 4],
    (tx, ty): (f32, f32),
    depth_sigma: f32,
    normal_power: f32,
) -> [f32; 4] {
    let mut weights = [0.0f32; 4];
    let mut total = 0.0f32;
    let mut nearest: Option<(usize, f32)> = None;
    for (i, tap) in taps.iter().enumerate() {
        let Some(tap) = *tap else { continue };
        let gap = (tap.0 - pixel.0).abs();
        if nearest.is_none_or(|(_, g)| gap < g) {
            nearest = Some((i, gap));
        }
        let wx = if i & 1 == 1 { tx } else { 1.0 - tx };
        let wy = if i >> 1 == 1 { ty } else { 1.0 - ty };
        weights[i] = wx * wy * bilateral_weight(pixel, tap, depth_sigma, normal_power);
        total += weights[i];
    }
    if total >= 1e-6 {
        return weights.map(|w| w / total);
    }
    let mut fallback = [0.0; 4];
    if let Some((i, _)) = nearest {
        fallback[i] = 1.0;
    }
    fallback
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filter_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "FilterParams",
            size_of::<FilterParams>(),
            &[
                ("full_size", offset_of!(FilterParams, full_size)),
                ("low_size", offset_of!(FilterParams, low_size)),
                ("factor", offset_of!(FilterParams, factor)),
                ("layers", offset_of!(FilterParams, layers)),
                ("radius", offset_of!(FilterParams, radius)),
                ("spatial_sigma", offset_of!(FilterParams, spatial_sigma)),
                ("depth_sigma", offset_of!(FilterParams, depth_sigma)),
                ("normal_power", offset_of!(FilterParams, normal_power)),
                ("guide_buffers", offset_of!(FilterParams, guide_buffers)),
                ("guide_offset", offset_of!(FilterParams, guide_offset)),
            ],
        );
    }

    #[test]
    fn representative_is_the_block_centre_clamped_to_the_image() {
        // Factor 1: the pixel itself.
        assert_eq!(representative((0, 0), 1, (5, 3)), (0, 0));
        assert_eq!(representative((4, 2), 1, (5, 3)), (4, 2));
        // Factor 2: the lower-right of the four centre pixels; the last column of an odd width
        // has only one full-res column, which it stands for.
        assert_eq!(representative((0, 0), 2, (5, 3)), (1, 1));
        assert_eq!(low_size((5, 3), 2), (3, 2));
        assert_eq!(representative((2, 1), 2, (5, 3)), (4, 2));
        // Factor 3 and 4, clamped at the border.
        assert_eq!(representative((1, 0), 3, (7, 7)), (4, 1));
        assert_eq!(low_size((7, 7), 3), (3, 3));
        assert_eq!(representative((2, 2), 3, (7, 7)), (6, 6));
        assert_eq!(representative((0, 0), 4, (1, 1)), (0, 0));
        assert_eq!(low_size((1, 1), 4), (1, 1));
        assert_eq!(representative((1, 0), 4, (6, 3)), (5, 2));
    }

    /// A deterministic pseudo-random number in [0, 1).
    fn hash(i: u32) -> f32 {
        let mut x = i.wrapping_mul(0x9E37_79B9) ^ 0x85EB_CA6B;
        x ^= x >> 16;
        x = x.wrapping_mul(0x7FEB_352D);
        x ^= x >> 15;
        (x >> 8) as f32 / (1u32 << 24) as f32
    }

    /// A guide of random positions and unit normals (some facing away from others), a fraction
    /// `holes` of the pixels uncovered.
    fn random_guide(width: u32, height: u32, holes: f32) -> CpuGuide {
        let n = (width * height) as usize;
        let mut position = Vec::with_capacity(n);
        let mut normal = Vec::with_capacity(n);
        for i in 0..n as u32 {
            let r = |k: u32| hash(8 * i + k);
            let covered = if r(0) < holes { 0.0 } else { 1.0 };
            position.push([
                r(1) * 2.0 - 1.0,
                r(2) * 2.0 - 1.0,
                -1.0 - 3.0 * r(3),
                covered,
            ]);
            let v = Vec3::new(r(4) - 0.5, r(5) - 0.5, r(6)).normalize();
            normal.push([v.x, v.y, v.z, 0.0]);
        }
        CpuGuide {
            width,
            height,
            position,
            normal,
            eye: Vec3::ZERO,
            low: None,
        }
    }

    fn close(a: Vec4, b: Vec4, tolerance: f32) -> bool {
        (a - b).abs().max_element() <= tolerance * b.abs().max_element().max(1e-6)
    }

    #[test]
    fn a_constant_signal_stays_constant() {
        let value = Vec4::new(0.25, 1.5, 3.0, 1.0);
        for holes in [0.0, 0.3] {
            let guide = random_guide(23, 17, holes);
            for factor in 1..=4 {
                for radius in [0, 1, 8] {
                    let options = FilterOptions {
                        factor,
                        radius,
                        ..Default::default()
                    };
                    let (lw, lh) = low_size((23, 17), factor);
                    let input = vec![value; (2 * lw * lh) as usize];
                    let blurred = blur(&input, 2, &guide, &options);
                    for (i, v) in blurred.iter().enumerate() {
                        let j = i as u32 % (lw * lh);
                        let low = representative((j % lw, j / lw), factor, (23, 17));
                        if radius == 0 || guide.at(low).covered {
                            assert!(close(*v, value, 1e-5), "blur {factor} {radius}: {v}");
                        } else {
                            assert_eq!(*v, Vec4::ZERO);
                        }
                    }
                    let full = upsample(&blurred, 2, &guide, &options);
                    for (i, v) in full.iter().enumerate() {
                        let j = i as u32 % (23 * 17);
                        let covered = guide.at((j % 23, j / 23)).covered;
                        if !covered {
                            assert_eq!(*v, Vec4::ZERO);
                        } else if holes == 0.0 {
                            assert!(close(*v, value, 1e-5), "upsample {factor} {radius}: {v}");
                        } else {
                            // Zero where none of the 2x2 samples is covered.
                            let ok = close(*v, value, 1e-5) || *v == Vec4::ZERO;
                            assert!(ok, "upsample {factor} {radius}: {v}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn radius_zero_is_the_identity() {
        let guide = random_guide(19, 11, 0.3);
        let options = FilterOptions {
            factor: 3,
            radius: 0,
            ..Default::default()
        };
        let (lw, lh) = low_size((19, 11), 3);
        let input: Vec<Vec4> = (0..2 * lw * lh)
            .map(|i| Vec4::new(hash(i), hash(i + 1000), hash(i + 2000), hash(i + 3000)))
            .collect();
        assert_eq!(blur(&input, 2, &guide, &options), input);
        // At factor 1 the up-sampling, too, is the identity on covered pixels.
        let options = FilterOptions {
            factor: 1,
            ..options
        };
        let input: Vec<Vec4> = (0..19 * 11).map(|i| Vec4::splat(hash(i))).collect();
        let out = upsample(&blur(&input, 1, &guide, &options), 1, &guide, &options);
        for (i, (o, v)) in out.iter().zip(&input).enumerate() {
            let covered = guide.position[i][3] > 0.0;
            assert_eq!(*o, if covered { *v } else { Vec4::ZERO }, "pixel {i}");
        }
    }

    /// Two flat regions facing the eye, the left at distance ~1 with value 1, the right at
    /// distance ~10 with value 5: neither the blur nor the up-sampling mixes them.
    #[test]
    fn a_depth_edge_is_not_crossed() {
        let (w, h) = (16u32, 8u32);
        let mut position = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let d = if x < w / 2 { 1.0 } else { 10.0 };
                position.push([(x as f32 - 8.0) * 0.01, (y as f32 - 4.0) * 0.01, -d, 1.0]);
            }
        }
        let guide = CpuGuide {
            width: w,
            height: h,
            position,
            normal: vec![[0.0, 0.0, 1.0, 0.0]; (w * h) as usize],
            eye: Vec3::ZERO,
            low: None,
        };
        let expected = |x: u32| Vec4::splat(if x < w / 2 { 1.0 } else { 5.0 });
        for factor in [1, 2] {
            let options = FilterOptions {
                factor,
                ..Default::default()
            };
            let (lw, lh) = low_size((w, h), factor);
            let input: Vec<Vec4> = (0..lw * lh)
                .map(|i| expected(representative((i % lw, i / lw), factor, (w, h)).0))
                .collect();
            let blurred = blur(&input, 1, &guide, &options);
            for (b, v) in blurred.iter().zip(&input) {
                assert!(close(*b, *v, 1e-6), "blur, factor {factor}: {b} for {v}");
            }
            let full = upsample(&blurred, 1, &guide, &options);
            for (i, v) in full.iter().enumerate() {
                let x = i as u32 % w;
                assert!(close(*v, expected(x), 1e-6), "upsample at {x}: {v}");
            }
        }
    }

    #[test]
    fn check_refuses_values_out_of_range() {
        assert!(FilterOptions::default().check().is_ok());
        let bad = [
            (
                FilterOptions {
                    factor: 0,
                    ..Default::default()
                },
                "factor",
            ),
            (
                FilterOptions {
                    factor: 5,
                    ..Default::default()
                },
                "factor",
            ),
            (
                FilterOptions {
                    radius: 17,
                    ..Default::default()
                },
                "radius",
            ),
            (
                FilterOptions {
                    spatial_sigma: 0.0,
                    ..Default::default()
                },
                "spatial sigma",
            ),
            (
                FilterOptions {
                    spatial_sigma: f32::NAN,
                    ..Default::default()
                },
                "spatial sigma",
            ),
            (
                FilterOptions {
                    depth_sigma: -1.0,
                    ..Default::default()
                },
                "depth sigma",
            ),
            (
                FilterOptions {
                    depth_sigma: f32::INFINITY,
                    ..Default::default()
                },
                "depth sigma",
            ),
            (
                FilterOptions {
                    normal_power: -0.5,
                    ..Default::default()
                },
                "normal power",
            ),
        ];
        for (options, name) in bad {
            match options.check() {
                Err(RuntimeError::Unsupported(msg)) => assert!(msg.contains(name), "{msg}"),
                other => panic!("{options:?}: {other:?}"),
            }
        }
        let edge = FilterOptions {
            factor: 4,
            radius: 0,
            normal_power: 0.0,
            ..Default::default()
        };
        assert!(edge.check().is_ok());
    }
}
