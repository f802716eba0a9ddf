//! The resolve of two planes of gathered light into the indirect radiance towards the eye
//! (`resolve.wgsl`), shared by the techniques that gather a diffuse and a lobe-weighted
//! irradiance per pixel (`rsm`, `ssil`): `albedo / pi * diffuse + Ks * lobe-weighted`.

use crate::{common::layout, frame::FrameContext, frame::FrameEncoder, shaders};

/// `common/resolve.wgsl`, two planes of gathered light reflected towards the eye (`rsm`, `ssil`).
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("resolve", "common/resolve.wgsl");

/// The resolve pass, into its own per-pixel indirect buffer.
pub struct PlaneResolve {
    name: &'static str,
    indirect: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

impl PlaneResolve {
    /// The pass (timed as `name`) reading `planes`: two full-res planes of `vec4f`, the
    /// diffuse irradiance then the lobe-weighted irradiance.
    pub fn new(ctx: &FrameContext, name: &'static str, planes: &wgpu::Buffer) -> Self {
        let device = &ctx.device;
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let entries = [
            layout::uniform(0, c),
            layout::storage(1, true, c),
            layout::texture(2, d2, c),
            layout::texture(3, d2, c),
            layout::storage(4, true, c),
            layout::storage(5, false, c),
        ];
        let bind_layout = layout::bind_group_layout(device, name, &entries);
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline(device, name, &module, &[&bind_layout]);
        let (indirect, bind_group) = Self::bind(ctx, name, &bind_layout, planes);
        Self {
            name,
            indirect,
            pipeline,
            bind_layout,
            bind_group,
            size: ctx.size(),
        }
    }

    fn bind(
        ctx: &FrameContext,
        name: &str,
        bind_layout: &wgpu::BindGroupLayout,
        planes: &wgpu::Buffer,
    ) -> (wgpu::Buffer, wgpu::BindGroup) {
        let indirect = ctx.pixel_buffer(name);
        let views =
            [&ctx.gbuffer.normal, &ctx.gbuffer.albedo].map(|t| t.create_view(&Default::default()));
        let mut resources = vec![
            ctx.view.as_entire_binding(),
            ctx.scene.materials.as_entire_binding(),
        ];
        resources.extend(views.iter().map(wgpu::BindingResource::TextureView));
        resources.push(planes.as_entire_binding());
        resources.push(indirect.as_entire_binding());
        let bind_group = layout::bind_group(&ctx.device, name, bind_layout, &resources);
        (indirect, bind_group)
    }

    /// A new indirect buffer of the context's size, reading the new `planes`.
    pub fn resize(&mut self, ctx: &FrameContext, planes: &wgpu::Buffer) {
        (self.indirect, self.bind_group) = Self::bind(ctx, self.name, &self.bind_layout, planes);
        self.size = ctx.size();
    }

    /// The indirect radiance per pixel (`vec4f`, w 1).
    pub fn indirect(&self) -> &wgpu::Buffer {
        &self.indirect
    }

    /// Records the pass.
    pub fn run(&self, frame: &mut FrameEncoder) {
        let mut pass = frame.compute_pass(self.name);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        let (x, y) = shaders::groups_2d(self.size);
        pass.dispatch_workgroups(x, y, 1);
    }
}
