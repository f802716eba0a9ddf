//! Tone mapping (`tonemap.wgsl`): linear radiance to display sRGB, exposure then the ACES
//! filmic curve. [`tonemap`] is the CPU twin.

use crate::{common::layout, gpu_types::TYPES_WGSL};

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

/// The tone-mapping pass: `hdr` (an `Rgba32Float` texture) into an `Rgba8Unorm` image.
pub struct Tonemap {
    /// The output image.
    pub ldr: wgpu::Texture,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

impl Tonemap {
    /// The pass reading `hdr` with the view constants `view`.
    pub fn new(device: &wgpu::Device, view: &wgpu::Buffer, hdr: &wgpu::Texture) -> Self {
        let (w, h) = (hdr.width(), hdr.height());
        let ldr = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("tone-mapped"),
            size: hdr.size(),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let source = format!("{TYPES_WGSL}\n{}", include_str!("tonemap.wgsl"));
        let module = layout::shader(device, "tonemap", source);
        let stages = wgpu::ShaderStages::COMPUTE;
        let bind_layout = layout::bind_group_layout(
            device,
            "tonemap",
            &[
                layout::uniform(0, stages),
                layout::texture(1, wgpu::TextureViewDimension::D2, stages),
                layout::storage_texture(2, wgpu::TextureFormat::Rgba8Unorm, stages),
            ],
        );
        let pipeline = layout::compute_pipeline(device, "tonemap", &module, &[&bind_layout]);
        let hdr_view = hdr.create_view(&Default::default());
        let ldr_view = ldr.create_view(&Default::default());
        let bind_group = layout::bind_group(
            device,
            "tonemap",
            &bind_layout,
            &[
                view.as_entire_binding(),
                wgpu::BindingResource::TextureView(&hdr_view),
                wgpu::BindingResource::TextureView(&ldr_view),
            ],
        );
        Self {
            ldr,
            pipeline,
            bind_group,
            size: (w, h),
        }
    }

    /// Records the pass.
    pub fn run(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut crate::common::timestamps::PassTimer,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("tonemap"),
            timestamp_writes: timer.compute("tonemap"),
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.dispatch_workgroups(self.size.0.div_ceil(8), self.size.1.div_ceil(8), 1);
    }
}
