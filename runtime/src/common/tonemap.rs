//! Tone mapping (`tonemap.wgsl`): linear radiance to display sRGB, exposure then the ACES
//! filmic curve. [`tonemap`] is the CPU twin.

use crate::{
    common::layout,
    frame::{FrameContext, FrameEncoder},
    shaders::Shader,
};

/// ACES filmic curve (Narkowicz 2015 fit) of one channel.
pub fn aces(x: f32) -> f32 {
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// sRGB encoding of one linear channel in [0, 1].
pub fn srgb_encode(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Display value (0 to 255) of linear `radiance` at `exposure`.
pub fn tonemap(radiance: [f32; 3], exposure: f32) -> [u8; 3] {
    radiance.map(|c| (srgb_encode(aces(c.max(0.0) * exposure)) * 255.0).round() as u8)
}

/// The tone-mapping pass: `hdr` (an `Rgba32Float` texture) drawn into the caller's target, a
/// swapchain texture or an offscreen one, of the format given at creation. Into an `*Srgb`
/// target the shader leaves the sRGB encoding to the hardware; into any other it encodes itself,
/// so an `Rgba8Unorm` target holds the bytes [`tonemap`] computes.
pub struct Tonemap {
    pipeline: wgpu::RenderPipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    format: wgpu::TextureFormat,
}

impl Tonemap {
    /// The pass from `hdr` into targets of `format`.
    pub fn new(ctx: &FrameContext, hdr: &wgpu::Texture, format: wgpu::TextureFormat) -> Self {
        let device = &ctx.device;
        let module = Shader::Tonemap.create(device);
        let stages = wgpu::ShaderStages::FRAGMENT;
        let bind_layout = layout::bind_group_layout(
            device,
            "tonemap",
            &[
                layout::uniform(0, stages),
                layout::texture(1, wgpu::TextureViewDimension::D2, stages),
            ],
        );
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("tonemap"),
            bind_group_layouts: &[Some(&bind_layout)],
            immediate_size: 0,
        });
        let encode = if format.is_srgb() { 0.0 } else { 1.0 };
        let constants = [("ENCODE_SRGB", encode)];
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("tonemap"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let bind_group = Self::bind(ctx, &bind_layout, hdr);
        Self {
            pipeline,
            bind_layout,
            bind_group,
            format,
        }
    }

    fn bind(
        ctx: &FrameContext,
        bind_layout: &wgpu::BindGroupLayout,
        hdr: &wgpu::Texture,
    ) -> wgpu::BindGroup {
        let hdr_view = hdr.create_view(&Default::default());
        layout::bind_group(
            &ctx.device,
            "tonemap",
            bind_layout,
            &[
                ctx.view.as_entire_binding(),
                wgpu::BindingResource::TextureView(&hdr_view),
            ],
        )
    }

    /// Reads a new `hdr` texture (after a resize).
    pub fn resize(&mut self, ctx: &FrameContext, hdr: &wgpu::Texture) {
        self.bind_group = Self::bind(ctx, &self.bind_layout, hdr);
    }

    /// The target format the pass was created for.
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// Records the pass into `target` (the image size, of [`Self::format`]).
    pub fn run(&self, frame: &mut FrameEncoder, target: &wgpu::TextureView) {
        let mut pass = frame
            .encoder
            .begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("tonemap"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: frame.timer.render("tonemap"),
                occlusion_query_set: None,
                multiview_mask: None,
            });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}
