//! `ssil sender` (`sender.wgsl`): the diffuse direct light leaving every pixel plus the radiance
//! it emits (the G-buffer's emission, zero where the eye sees an emitter's back: emission is
//! one-sided), the light the first bounce gathers (§3: the "direct illumination" G-buffer,
//! diffuse, §5.3). CPU twin: [`super::cpu::sender_radiance`].

use crate::{
    common::layout,
    direct::{light_entries, light_resources},
    frame::{FrameContext, FrameEncoder},
    shaders,
};

/// `ssil/sender.wgsl`: the diffuse direct light leaving every pixel, and the next bounce's.
pub const SHADER: shaders::Shader = shaders::shader!("ssil sender", "ssil/sender.wgsl");

/// The pass's pipeline, created once; its bind group follows the image size ([`Self::bind`]).
pub(super) struct SenderPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl SenderPass {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let mut entries = light_entries().to_vec();
        entries.extend([
            layout::texture(5, d2, c),
            layout::texture(6, d2, c),
            layout::texture(7, d2, c),
            layout::storage(8, false, c),
            layout::texture(9, d2, c),
        ]);
        let layout = layout::bind_group_layout(device, "ssil sender", &entries);
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline(device, "ssil sender", &module, &[&layout]);
        Self { layout, pipeline }
    }

    /// The bind group writing the light sent into `sender` (one element per pixel).
    pub(super) fn bind(&self, ctx: &FrameContext, sender: &wgpu::Buffer) -> wgpu::BindGroup {
        let gbuffer = [
            &ctx.gbuffer.position,
            &ctx.gbuffer.normal,
            &ctx.gbuffer.albedo,
        ]
        .map(|t| t.create_view(&Default::default()));
        let mut resources = light_resources(&ctx.view, &ctx.scene, &ctx.shadows).to_vec();
        resources.extend(gbuffer.iter().map(wgpu::BindingResource::TextureView));
        resources.push(sender.as_entire_binding());
        let emission = ctx.gbuffer.emission.create_view(&Default::default());
        resources.push(wgpu::BindingResource::TextureView(&emission));
        layout::bind_group(&ctx.device, "ssil sender", &self.layout, &resources)
    }

    /// Records the pass over an image of `size`.
    pub(super) fn run(&self, frame: &mut FrameEncoder, group: &wgpu::BindGroup, size: (u32, u32)) {
        let mut pass = frame.compute_pass("ssil sender");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, group, &[]);
        let (x, y) = shaders::groups_2d(size);
        pass.dispatch_workgroups(x, y, 1);
    }
}
