//! The far-field pass of `lightcuts`' texture-space final gather: the radiosity's gather
//! (`gather.wgsl` with `params.gather` 2) run once more over every texel from the iteration's
//! node radiance, every leaf within the near radius weighted out by
//! [`super::transfer::near_split_weight`] and, if asked, every emitter left out
//! ([`super::cpu::FarSplit`]), into a per-texel buffer the final gather looks up.
//! CPU twin: [`super::cpu::far_field`].

use wgpu::util::DeviceExt;

use super::Radiosity;
use crate::{common::layout, frame::FrameEncoder, gpu_types::GpuTraversalParams, shaders};

/// The far-field pass: see the module docs.
pub struct FarField {
    /// Per texel `vec4f`: rgb far-field irradiance of the last bounce.
    pub irradiance: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    leaf_count: u32,
}

impl Radiosity {
    /// The far-field pass gathering from this iteration's result ([`Self::radiance`]) with
    /// what `split` leaves to the pixels left out.
    pub fn far_field(&self, device: &wgpu::Device, split: super::cpu::FarSplit) -> FarField {
        let texels = 16 * u64::from(self.leaf_count.max(1));
        let irradiance = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("texel far-field irradiance"),
            size: texels,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("far-field params"),
            contents: bytemuck::bytes_of(&GpuTraversalParams {
                receiver_count: self.leaf_count,
                node_count: self.node_count,
                threshold: self.options.threshold,
                exposure: self.options.exposure,
                gather: 2,
                near_radius: split.near_radius,
                emitters: u32::from(split.emitters_apart),
                ..Default::default()
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        // The gather writes no node radiance with `gather` 2, but its layout has the binding.
        let unused = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("far-field unused radiance"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let bind_group = layout::bind_group(
            device,
            "far field",
            &self.gather_layout,
            &[
                params.as_entire_binding(),
                self.tree[0].as_entire_binding(),
                self.tree[1].as_entire_binding(),
                self.texel_direct.as_entire_binding(),
                self.albedo.as_entire_binding(),
                self.radiance().as_entire_binding(),
                unused.as_entire_binding(),
                irradiance.as_entire_binding(),
            ],
        );
        FarField {
            irradiance,
            pipeline: self.gather_pipeline.clone(),
            bind_group,
            leaf_count: self.leaf_count,
        }
    }
}

impl FarField {
    /// Records the pass, after the iteration it gathers from.
    pub fn run(&self, frame: &mut FrameEncoder, cssm: &crate::frame::CssmResources) {
        let mut pass = frame.compute_pass("lightcuts: far field");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_bind_group(1, &cssm.query.bind_group, &[]);
        cssm.moving.bind(&mut pass, 2);
        pass.dispatch_workgroups(shaders::groups_1d(self.leaf_count), 1, 1);
    }
}
