//! Final gathering per pixel with simplified GPU lightcuts (§4.4.1, §4.5): the hierarchy's
//! nodes, lit by the radiosity iteration ([`crate::radiosity`]), are VPLs; every pixel of the
//! G-buffer walks the tree like a receiver leaf, the oracle bounding the Phong BRDF, and
//! gathers the glossy last bounce towards the eye (`final_gather.wgsl`). With jittering, each
//! frame picks a random texel of every node of the cut and the frames are averaged.
//!
//! CPU twin: [`cpu::gather_pixel`] (test `final_gather_matches_cpu_twin`).

pub mod cpu;

use wgpu::util::DeviceExt;

use crate::{
    common::{gbuffer::GBuffer, layout, timestamps::PassTimer},
    gpu_types::GpuTraversalParams,
    load::{CssmGpu, SceneGpu},
    radiosity::HierarchyGpu,
    visibility::library_wgsl,
};

/// The final-gather pass: indirect radiance per pixel into [`Self::indirect`].
pub struct FinalGather {
    /// Per pixel `vec4f`: rgb indirect radiance (mean over the frames so far), w: cut size.
    pub indirect: wgpu::Buffer,
    params: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
    base: GpuTraversalParams,
}

impl FinalGather {
    /// The pass over `gbuffer`, gathering from `node_radiance` (per node `vec4f`).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        device: &wgpu::Device,
        view: &wgpu::Buffer,
        scene: &SceneGpu,
        gbuffer: &GBuffer,
        cssm: &CssmGpu,
        hierarchy: &HierarchyGpu,
        node_radiance: &wgpu::Buffer,
        threshold: f32,
        exposure: f32,
    ) -> Self {
        let (w, h) = (gbuffer.position.width(), gbuffer.position.height());
        let indirect = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("final gather"),
            size: 16 * (w * h) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let base = GpuTraversalParams {
            receiver_count: w * h,
            node_count: hierarchy.node_count,
            threshold,
            exposure,
            ..Default::default()
        };
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("final gather params"),
            contents: bytemuck::bytes_of(&base),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let module = layout::shader(
            device,
            "final gather",
            library_wgsl(1)
                + include_str!("../radiosity/transfer.wgsl")
                + include_str!("final_gather.wgsl"),
        );
        let entries = [
            layout::uniform(0, c),
            layout::uniform(1, c),
            layout::storage(2, true, c),
            layout::storage(3, true, c),
            layout::storage(4, true, c),
            layout::storage(5, true, c),
            layout::texture(6, d2, c),
            layout::texture(7, d2, c),
            layout::texture(8, d2, c),
            layout::texture(9, d2, c),
            layout::storage(10, false, c),
        ];
        let bind_layout = layout::bind_group_layout(device, "final gather", &entries);
        let pipeline = layout::compute_pipeline(
            device,
            "final gather",
            &module,
            &[&bind_layout, &cssm.bind_group_layout],
        );
        let views = [
            &gbuffer.position,
            &gbuffer.normal,
            &gbuffer.albedo,
            &gbuffer.atlas,
        ]
        .map(|t| t.create_view(&Default::default()));
        let mut resources = vec![
            params.as_entire_binding(),
            view.as_entire_binding(),
            hierarchy.nodes.as_entire_binding(),
            hierarchy.leaves.as_entire_binding(),
            node_radiance.as_entire_binding(),
            scene.materials.as_entire_binding(),
        ];
        resources.extend(views.iter().map(wgpu::BindingResource::TextureView));
        resources.push(indirect.as_entire_binding());
        let bind_group = layout::bind_group(device, "final gather", &bind_layout, &resources);
        Self {
            indirect,
            params,
            pipeline,
            bind_group,
            size: (w, h),
            base,
        }
    }

    /// Records frame `frame` of the progressive average: with `jitter` every sender is a random
    /// texel of its node (seeded by the frame), else the node's representative.
    pub fn run(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        cssm: &CssmGpu,
        timer: &mut PassTimer,
        frame: u32,
        jitter: bool,
    ) {
        let params = GpuTraversalParams {
            seed: frame_seed(frame),
            jitter: u32::from(jitter),
            frame,
            ..self.base
        };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("final gather"),
            timestamp_writes: timer.compute("final gather"),
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_bind_group(1, &cssm.bind_group, &[]);
        pass.dispatch_workgroups(self.size.0.div_ceil(8), self.size.1.div_ceil(8), 1);
    }
}

/// The seed of frame `frame`'s jitter (what [`FinalGather::run`] uploads).
pub fn frame_seed(frame: u32) -> u32 {
    crate::radiosity::transfer::pcg_hash(frame.wrapping_add(0x9e37_79b9))
}

#[cfg(test)]
mod tests {
    #[test]
    fn shader_validates_with_naga() {
        crate::tests::validate_wgsl(
            "lightcuts/final_gather",
            &(super::library_wgsl(1)
                + include_str!("../radiosity/transfer.wgsl")
                + include_str!("final_gather.wgsl")),
        );
    }
}
