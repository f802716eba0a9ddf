//! The edge-aware blur and joint bilateral up-sampling on the GPU ([`EdgeAwareFilter`]): the
//! pipelines of `filters.wgsl`, the buffers and bind groups that depend on the G-buffer's size,
//! and where the low-res guide comes from ([`LowGuide`]).

use wgpu::util::DeviceExt;

use super::{FilterOptions, SHADER, low_size};
use crate::{
    RuntimeError,
    common::{gbuffer::GBuffer, layout},
    frame::{FrameContext, FrameEncoder},
    shaders,
};

/// `FilterParams` of `filters.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct FilterParams {
    pub(super) full_size: [u32; 2],
    pub(super) low_size: [u32; 2],
    pub(super) factor: u32,
    pub(super) layers: u32,
    pub(super) radius: u32,
    pub(super) spatial_sigma: f32,
    pub(super) depth_sigma: f32,
    pub(super) normal_power: f32,
    pub(super) guide_buffers: u32,
    pub(super) guide_offset: u32,
}

/// Where the filters read the guide of a low-res pixel.
#[derive(Clone, Copy, Debug)]
pub enum LowGuide<'a> {
    /// The G-buffer at the pixel's [`representative`](super::representative) (a technique
    /// that samples there).
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

    /// The filter of a technique that gathers two planes (the diffuse and the lobe-weighted
    /// irradiance, for `common::resolve`) at the reduced image's representative pixels (rsm,
    /// vct, vf, lightcuts), over `ctx`'s G-buffer and view.
    ///
    /// # Errors
    /// As [`Self::new`].
    pub fn two_planes(ctx: &FrameContext, options: FilterOptions) -> Result<Self, RuntimeError> {
        Self::new(
            &ctx.device,
            &ctx.gbuffer,
            &ctx.view,
            2,
            options,
            LowGuide::Representative,
        )
    }

    /// [`Self::resize`] for a filter of [`Self::two_planes`], after `ctx`'s G-buffer was
    /// resized.
    pub fn resize_two_planes(&mut self, ctx: &FrameContext) {
        self.resize(
            &ctx.device,
            &ctx.gbuffer,
            &ctx.view,
            LowGuide::Representative,
        );
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
