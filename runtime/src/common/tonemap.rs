//! Tone mapping (`tonemap.wgsl`): linear radiance to display sRGB, exposure then the ACES
//! filmic curve. [`tonemap`] is the CPU twin.

use crate::{
    common::layout,
    frame::{FrameContext, FrameEncoder},
};

/// `common/tonemap.wgsl`.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("tonemap", "common/tonemap.wgsl");

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

/// Rec. 709 luminance of a linear RGB colour: what the automatic exposure meters, the path
/// tracer's emitter sampling weighs and the converged bounces compare.
pub fn luminance(c: glam::Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Where automatic exposure puts the image's log-average luminance: middle grey (Reinhard et
/// al. 2002, "Photographic Tone Reproduction for Digital Images", §2: the scene's "key").
pub const AUTO_EXPOSURE_KEY: f32 = 0.18;

/// Automatic exposure in stops: the exposure that brings the log-average luminance (Rec. 709
/// weights) of the pixels of `radiance` that hold light to [`AUTO_EXPOSURE_KEY`], as engines
/// meter a frame. Pixels without light (the void around a box seen through its open side,
/// surfaces no light reaches) are left out: they would expose for the dark. Clamped to ±32
/// stops; `None` when no pixel holds light.
pub fn auto_exposure_stops(radiance: &[[f32; 4]]) -> Option<f32> {
    let (sum, count) = radiance
        .iter()
        .map(|c| luminance(glam::Vec3::new(c[0], c[1], c[2])))
        .filter(|l| *l > 0.0 && l.is_finite())
        .fold((0.0f64, 0u64), |(sum, n), l| {
            (sum + f64::from(l).ln(), n + 1)
        });
    (count > 0).then(|| {
        let log_average = sum / count as f64;
        ((f64::from(AUTO_EXPOSURE_KEY).ln() - log_average) / std::f64::consts::LN_2)
            .clamp(-32.0, 32.0) as f32
    })
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
        let module = SHADER.create(device);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_exposure_brings_the_lit_pixels_log_average_to_middle_grey() {
        // Half the pixels at luminance 2, half at 8: log-average 4, so 0.18 / 4 = 2^-4.47.
        let mut image = vec![[2.0, 2.0, 2.0, 1.0]; 50];
        image.extend(vec![[8.0, 8.0, 8.0, 1.0]; 50]);
        let stops = auto_exposure_stops(&image).unwrap();
        assert!((stops - (0.18f32 / 4.0).log2()).abs() < 1e-4, "{stops}");
        // Pixels of no light do not drag it down; a non-finite one is left out.
        image.extend(vec![[0.0; 4]; 1000]);
        image.push([f32::INFINITY, 0.0, 0.0, 1.0]);
        assert!((auto_exposure_stops(&image).unwrap() - stops).abs() < 1e-4);
        assert_eq!(auto_exposure_stops(&[[0.0; 4]; 10]), None);
        assert_eq!(auto_exposure_stops(&[[1e-30, 0.0, 0.0, 1.0]]), Some(32.0));
    }
}
