//! The far-field pass of `lightcuts`' texture-space final gather: the radiosity's gather
//! (`gather.wgsl` with `params.gather` 2) run once more over every texel from the iteration's
//! node radiance, every leaf within the near radius weighted out by
//! [`super::transfer::near_split_weight`] and, if asked, every emitter left out
//! ([`super::cpu::FarSplit`]), into a per-texel buffer the final gather looks up. Like the
//! bounces, it caches its cuts ([`super::links`], with [`super::links::LINKS_FAR`]) from the
//! second solve on: a moved light then runs one product over the radiosity's result.
//! CPU twin: [`super::cpu::far_field`], [`super::cpu::far_field_with_links`].

use wgpu::util::DeviceExt;

use super::{Radiosity, links};
use crate::{
    common::layout,
    frame::{CssmResources, FrameEncoder},
    gpu_types::GpuTraversalParams,
    shaders,
};

/// The far-field pass: see the module docs.
pub struct FarField {
    /// Per texel `vec4f`: rgb far-field irradiance of the last bounce.
    pub irradiance: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    leaf_count: u32,
    /// Its cached cuts, and what their passes bind: the hierarchy's nodes and leaves, the
    /// texels' direct light and albedo, the radiosity's result, the product's unused node
    /// radiance and its convergence word.
    links: links::Links,
    tree: [wgpu::Buffer; 2],
    link_buffers: [wgpu::Buffer; 5],
}

impl Radiosity {
    /// The far-field pass gathering from this iteration's result ([`Self::radiance`]) with
    /// what `split` leaves to the pixels left out, over `cssm` (the radiosity's); its links
    /// off where the radiosity's are.
    pub fn far_field(
        &self,
        device: &wgpu::Device,
        cssm: &CssmResources,
        split: super::cpu::FarSplit,
    ) -> FarField {
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
        let mut links = links::Links::new(
            device,
            &cssm.query,
            &cssm.moving,
            &cssm.hierarchy,
            self.options,
            Some(split),
        );
        if self.links.is_off() {
            links.turn_off();
        }
        FarField {
            pipeline: self.gather_pipeline.clone(),
            bind_group,
            leaf_count: self.leaf_count,
            links,
            tree: self.tree.clone(),
            link_buffers: [
                self.texel_direct.clone(),
                self.albedo.clone(),
                self.radiance().clone(),
                unused,
                // The product's convergence word: never converged.
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("far-field product: not converged"),
                    contents: bytemuck::cast_slice(&[0u32; 4]),
                    usage: wgpu::BufferUsages::STORAGE,
                }),
            ],
            irradiance,
        }
    }
}

impl FarField {
    /// Before the radiosity's iteration (so that its cuts are made for the radiance the last
    /// far field read): builds the links once a far field was recorded, or re-cuts the
    /// receivers the last product found stale ([`links::Links::before_iteration`]); a build
    /// that fails leaves the pass walking.
    pub fn update_links(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        cssm: &CssmResources,
        frame: &mut FrameEncoder,
    ) {
        let [direct, albedo, radiance, unused, zero] = &self.link_buffers;
        let inputs = links::LinkInputs {
            tree: &self.tree,
            texel_direct: direct,
            albedo,
            radiance,
            products: [Some([radiance, unused, &self.irradiance]), None],
            converged: zero,
        };
        if self
            .links
            .before_iteration(device, queue, cssm, &inputs, frame)
            .is_err()
        {
            self.links.turn_off();
        }
    }

    /// Records the pass, after the iteration it gathers from: the product of its links once
    /// built, else the walk.
    pub fn run(&mut self, frame: &mut FrameEncoder, cssm: &CssmResources) {
        if let Some(product) = self.links.product(0) {
            product.record(frame);
        } else {
            let mut pass = frame.compute_pass("lightcuts: far field");
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_bind_group(1, &cssm.query.bind_group, &[]);
            cssm.moving.bind(&mut pass, 2);
            pass.dispatch_workgroups(shaders::groups_1d(self.leaf_count), 1, 1);
        }
        self.links.ran();
    }

    /// How many links its product multiplies, once built; `None` before, or when it walks.
    pub fn link_count(&self) -> Option<u64> {
        self.links.count()
    }

    /// The receivers whose far-field cut the last product found stale, and the re-cuts that
    /// overflowed, as read back before the pass after it ([`Self::update_links`]).
    pub fn stale_links(&self) -> (u32, u32) {
        self.links.last_counters
    }
}
