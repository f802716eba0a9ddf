//! `ssil temporal` (`temporal.wgsl`, §4, Eq. 6): the previous frame's result reprojected
//! through the frame history (`common::history`: the previous camera and G-buffer) and blended
//! in with `temporal` (less on glossy pixels as the camera turns). CPU twin: [`super::cpu`]'s
//! `temporal`.

use crate::{
    common::{history::FrameHistory, layout},
    frame::{FrameContext, FrameEncoder},
    shaders,
};

/// `ssil/temporal.wgsl`: the reprojected history blended in.
pub const SHADER: shaders::Shader = shaders::shader!("ssil temporal", "ssil/temporal.wgsl");

/// `temporal.wgsl`'s `TemporalParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct TemporalParams {
    pub(super) previous_view_proj: [[f32; 4]; 4],
    pub(super) previous_eye: [f32; 3],
    pub(super) blend: f32,
    pub(super) history: u32,
    pub(super) padding: [u32; 3],
}

/// The pass's pipeline, created once; its bind group follows the image size ([`Self::bind`]).
pub(super) struct TemporalPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

/// What the temporal filter reads and writes at one image size.
pub(super) struct TemporalInputs<'a> {
    /// The frame's [`TemporalParams`] uniform.
    pub(super) params: &'a wgpu::Buffer,
    /// The previous frame's camera and G-buffer.
    pub(super) frames: &'a FrameHistory,
    /// The filters' output at full resolution (two planes).
    pub(super) filtered: &'a wgpu::Buffer,
    /// The previous frame's blended planes.
    pub(super) history: &'a wgpu::Buffer,
    /// This frame's blended planes.
    pub(super) blended: &'a wgpu::Buffer,
}

impl TemporalPass {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let layout = layout::bind_group_layout(
            device,
            "ssil temporal",
            &[
                layout::uniform(0, c),
                layout::uniform(1, c),
                layout::storage(2, true, c),
                layout::texture(3, d2, c),
                layout::texture(4, d2, c),
                layout::texture(5, d2, c),
                layout::texture(6, d2, c),
                layout::storage(7, true, c),
                layout::storage(8, true, c),
                layout::storage(9, false, c),
            ],
        );
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline(device, "ssil temporal", &module, &[&layout]);
        Self { layout, pipeline }
    }

    pub(super) fn bind(&self, ctx: &FrameContext, inputs: &TemporalInputs) -> wgpu::BindGroup {
        let texture_views = [
            &ctx.gbuffer.position,
            &ctx.gbuffer.normal,
            &inputs.frames.position,
            &inputs.frames.normal,
        ]
        .map(|t| t.create_view(&Default::default()));
        let mut resources = vec![
            ctx.view.as_entire_binding(),
            inputs.params.as_entire_binding(),
            ctx.scene.materials.as_entire_binding(),
        ];
        resources.extend(texture_views.iter().map(wgpu::BindingResource::TextureView));
        resources.extend([
            inputs.filtered.as_entire_binding(),
            inputs.history.as_entire_binding(),
            inputs.blended.as_entire_binding(),
        ]);
        layout::bind_group(&ctx.device, "ssil temporal", &self.layout, &resources)
    }

    /// Records the pass over an image of `size`.
    pub(super) fn run(&self, frame: &mut FrameEncoder, group: &wgpu::BindGroup, size: (u32, u32)) {
        let mut pass = frame.compute_pass("ssil temporal");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, group, &[]);
        let (x, y) = shaders::groups_2d(size);
        pass.dispatch_workgroups(x, y, 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "TemporalParams",
            size_of::<TemporalParams>(),
            &[
                (
                    "previous_view_proj",
                    offset_of!(TemporalParams, previous_view_proj),
                ),
                ("previous_eye", offset_of!(TemporalParams, previous_eye)),
                ("blend", offset_of!(TemporalParams, blend)),
                ("history", offset_of!(TemporalParams, history)),
            ],
        );
    }
}
