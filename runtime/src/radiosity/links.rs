//! The radiosity's cached links (issue 49, item 1): every receiver leaf's cut, as the gather
//! walks it, stored once with its transfer (`links.wgsl`), so that every later bounce is a
//! sparse matrix-vector product (`product.wgsl`) that queries no visibility: a moved light
//! re-runs the direct light into the atlas and the products.
//!
//! The cuts are made for the node radiance of the iteration before (the oracle needs light to
//! bound, §4.3): the first iteration walks as the gather always did, and the next one builds
//! the links from its result before it runs (a count pass read back, its prefix sums, a write
//! pass), then multiplies. Each receiver's slot holds its cut with room to spare
//! ([`slot_capacity`]). A cut made under one light can go stale under the next: where the new
//! light makes a coarse node of it bright enough that the oracle would refine it. The product
//! tests every link's node as it multiplies (its bound of unit radiance stored beside the
//! link), flags the receivers whose cut went stale ([`STALE_MARGIN`]) and counts them; every
//! iteration first re-cuts the flagged receivers for the radiance of the one before, in place
//! where the new cut fits their slot. Where one does not, the old cut stays and the links are
//! built again, slots and all, at the next iteration (its counters read back then: one wait a
//! light move). A file with moving objects keeps walking: its visibility changes as they
//! move, and so does a device whose binding limit the links exceed.
//!
//! `lightcuts`' far field ([`super::FarField`]) caches its own cuts the same way
//! ([`LINKS_FAR`]: the near field and the emitters left out, as `gather.wgsl` with `gather` 2
//! walks them): its pass becomes one product over the radiosity's result.
//!
//! CPU twin: [`super::cpu::build_links`], [`super::cpu::radiosity_with_links`],
//! [`super::cpu::far_field_with_links`].

use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{layout, readback},
    frame::{CssmResources, FrameEncoder},
    gpu_types::GpuTraversalParams,
    load::{CssmGpu, storage_binding_bytes},
    shaders,
};

use super::{HierarchyGpu, RadiosityOptions};

/// `radiosity/links.wgsl` with the CSSM library and `radiosity/transfer.wgsl`.
pub const LINKS_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("radiosity links", "radiosity/links.wgsl");

/// `radiosity/product.wgsl`.
pub const PRODUCT_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("radiosity product", "radiosity/product.wgsl");

/// The count word's flag of a receiver whose cut went stale (`links.wgsl`, `product.wgsl`).
pub const LINK_STALE: u32 = 0x8000_0000;

/// `params.gather`'s flag of the far field's cuts (`links.wgsl`, `product.wgsl`): the cuts of
/// [`super::cpu::FarSplit`], the product writing the texels' irradiance alone.
pub const LINKS_FAR: u32 = 4;

/// How far past the oracle's threshold a node of a cut must be for the cut to count as
/// stale: its bound of the node's light above this times the threshold's, on the linear
/// bound (16 is the oracle at `16^(1/2.2)`, 3.5 times its tone-mapped threshold). Chosen by
/// measurement (reports/final-gather.md, "Radiosity with cached links"): closer margins
/// re-cut almost every receiver after a small light move for an answer hardly closer to the
/// walk's.
pub const STALE_MARGIN: f32 = 16.0;

/// The slot of a receiver with `count` links: a quarter more and 8, so that the cut of a
/// light a little brighter at the receiver is re-cut in place.
pub fn slot_capacity(count: u32) -> u32 {
    count + count / 4 + 8
}

/// Where the links stand.
enum State {
    /// Never: the iteration always walks (moving objects, or `links=walk`).
    Off,
    /// Not built yet; `ran` once an iteration has been recorded whose result they can be
    /// built for.
    Unbuilt { ran: bool },
    /// Built: each bounce multiplies (a bind group per [`LinkInputs::products`] entry), each
    /// iteration first re-cuts the stale receivers (`recut_group`).
    Built {
        product_groups: Vec<wgpu::BindGroup>,
        recut_group: wgpu::BindGroup,
        count: u64,
    },
    /// Beyond the device's binding limit: the iteration walks.
    TooLarge { count: u64 },
}

/// The links of a [`super::Radiosity`] (or of its far field) and the passes that build and
/// multiply them.
pub(super) struct Links {
    state: State,
    /// The re-cut's and the product's pass names.
    names: [&'static str; 2],
    build_pipeline: wgpu::ComputePipeline,
    build_layout: wgpu::BindGroupLayout,
    product_pipeline: wgpu::ComputePipeline,
    product_layout: wgpu::BindGroupLayout,
    /// The node radiance the cuts are made for (a copy of the iteration's result).
    cut_radiance: wgpu::Buffer,
    /// The link table: per leaf its slot's start and its link count (with [`LINK_STALE`]),
    /// then the slots' total, the receivers the products flagged this iteration and the
    /// re-cuts that overflowed their slot.
    table: wgpu::Buffer,
    /// The build's and the products' constants (threshold, exposure, counts; `gather` 0
    /// counts, 1 writes, 2 re-cuts).
    params: [wgpu::Buffer; 3],
    leaf_count: u32,
    /// The receivers the last iteration's products flagged, and its re-cuts' overflows, as
    /// read back at the start of this one.
    pub(super) last_counters: (u32, u32),
}

/// What the link passes read and write.
pub(super) struct LinkInputs<'a> {
    /// The hierarchy's nodes and leaves.
    pub tree: &'a [wgpu::Buffer; 2],
    /// Per texel, its direct radiance.
    pub texel_direct: &'a wgpu::Buffer,
    /// Per texel, its albedo.
    pub albedo: &'a wgpu::Buffer,
    /// The node radiance the cuts are made for: the last recorded iteration's result.
    pub radiance: &'a wgpu::Buffer,
    /// Per product bind group ([`Links::product`]'s index): the node radiance it multiplies,
    /// the node radiance it writes the leaves of (the far field's: unused), and the per-texel
    /// irradiance it writes.
    pub products: [Option<[&'a wgpu::Buffer; 3]>; 2],
    /// The convergence test's state, whose first word the product reads (1: converged, the
    /// bounce does nothing); the far field's: a zero.
    pub converged: &'a wgpu::Buffer,
}

impl Links {
    /// The passes over `cssm`'s texels and `hierarchy`, for the radiosity's cuts (`far`
    /// `None`) or for the far field's of that split; a file with moving objects keeps them
    /// off.
    pub(super) fn new(
        device: &wgpu::Device,
        cssm: &CssmGpu,
        moving: &crate::visibility::moving::MovingGpu,
        hierarchy: &HierarchyGpu,
        options: RadiosityOptions,
        far: Option<super::cpu::FarSplit>,
    ) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let module = LINKS_SHADER.create_for_scene(device, cssm.shape(), moving.csm_count);
        let build_layout = layout::bind_group_layout(
            device,
            "radiosity links",
            &[
                layout::uniform(0, c),
                layout::storage(1, true, c),
                layout::storage(2, true, c),
                layout::storage(3, true, c),
                layout::storage(4, true, c),
                layout::storage(5, false, c),
                layout::storage(6, false, c),
                layout::storage(7, false, c),
            ],
        );
        let build_pipeline = layout::compute_pipeline(
            device,
            "radiosity links",
            &module,
            &moving.with_layout(&[&build_layout, &cssm.bind_group_layout]),
        );
        let product_layout = layout::bind_group_layout(
            device,
            "radiosity product",
            &[
                layout::uniform(0, c),
                layout::storage(1, true, c),
                layout::storage(2, true, c),
                layout::storage(3, true, c),
                layout::storage(4, true, c),
                layout::storage(5, false, c),
                layout::storage(6, false, c),
                layout::storage(7, false, c),
                layout::storage(8, true, c),
                layout::storage(9, true, c),
                layout::storage(10, true, c),
            ],
        );
        let product_pipeline = layout::compute_pipeline(
            device,
            "radiosity product",
            &PRODUCT_SHADER.create(device),
            &[&product_layout],
        );
        let split = far.unwrap_or(super::cpu::FarSplit::WHOLE);
        let far_flag = if split.near_radius > 0.0 {
            LINKS_FAR
        } else {
            0
        };
        let params = [0, 1, 2].map(|gather| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("radiosity links params"),
                contents: bytemuck::bytes_of(&GpuTraversalParams {
                    receiver_count: hierarchy.leaf_count,
                    node_count: hierarchy.node_count,
                    threshold: options.threshold,
                    exposure: options.exposure,
                    gather: gather | far_flag,
                    near_radius: split.near_radius,
                    emitters: u32::from(split.emitters_apart),
                    ..Default::default()
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        });
        let cut_radiance = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("radiosity cut radiance"),
            size: 16 * u64::from(hierarchy.node_count.max(1)),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let table = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("radiosity link table"),
            size: 4 * (2 * u64::from(hierarchy.leaf_count) + 3),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let state = if moving.csm_count == 0 {
            State::Unbuilt { ran: false }
        } else {
            State::Off
        };
        Self {
            state,
            names: if far.is_some() {
                [
                    "lightcuts: far-field re-cut",
                    "lightcuts: far-field product",
                ]
            } else {
                ["radiosity: re-cut", "radiosity: product"]
            },
            build_pipeline,
            build_layout,
            product_pipeline,
            product_layout,
            cut_radiance,
            table,
            params,
            leaf_count: hierarchy.leaf_count,
            last_counters: (0, 0),
        }
    }

    /// Never builds them: every bounce walks.
    pub(super) fn turn_off(&mut self) {
        self.state = State::Off;
    }

    /// Whether they are never built ([`Self::turn_off`], or a file with moving objects).
    pub(super) fn is_off(&self) -> bool {
        matches!(self.state, State::Off)
    }

    /// The links' count once built (also when over the binding limit and left out).
    pub(super) fn count(&self) -> Option<u64> {
        match self.state {
            State::Built { count, .. } | State::TooLarge { count } => Some(count),
            _ => None,
        }
    }

    /// The product of [`LinkInputs::products`]' entry `which` (the radiosity's: the buffer
    /// it writes), once the links are built: its pass name, pipeline and bind group.
    pub(super) fn product(&self, which: usize) -> Option<Product<'_>> {
        match &self.state {
            State::Built { product_groups, .. } => Some(Product {
                name: self.names[1],
                pipeline: &self.product_pipeline,
                group: product_groups.get(which)?,
                leaf_count: self.leaf_count,
            }),
            _ => None,
        }
    }

    /// An iteration was recorded: the next call of [`Self::build_if_due`] builds the links for
    /// its result.
    pub(super) fn ran(&mut self) {
        if let State::Unbuilt { ran } = &mut self.state {
            *ran = true;
        }
    }

    /// Before an iteration: builds the links for the node radiance `inputs.radiance` holds
    /// if an iteration ran since they were due, or again if the last iteration's re-cuts
    /// overflowed their slots (its counters read back: submitting and waiting for the GPU);
    /// else, once built, records into `frame` the re-cut of the receivers the last
    /// iteration's products flagged, for that same radiance, and zeroes the counters.
    ///
    /// # Errors
    /// A failed read-back.
    pub(super) fn before_iteration(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        cssm: &CssmResources,
        inputs: &LinkInputs,
        frame: &mut FrameEncoder,
    ) -> Result<(), RuntimeError> {
        let radiance = inputs.radiance;
        match &self.state {
            State::Off | State::TooLarge { .. } | State::Unbuilt { ran: false } => return Ok(()),
            State::Unbuilt { ran: true } => {
                return self.build(device, queue, cssm, inputs, radiance);
            }
            State::Built { .. } => {}
        }
        let counters_at = 4 * 2 * u64::from(self.leaf_count) + 4;
        let bytes = readback::read_buffer(device, queue, &self.table, counters_at, 8)?;
        let counters: &[u32] = bytemuck::cast_slice(&bytes);
        self.last_counters = (counters[0], counters[1]);
        if counters[1] > 0 {
            return self.build(device, queue, cssm, inputs, radiance);
        }
        queue.write_buffer(&self.table, counters_at, bytemuck::cast_slice(&[0u32; 2]));
        if counters[0] == 0 {
            return Ok(());
        }
        let State::Built { recut_group, .. } = &self.state else {
            return Ok(());
        };
        frame
            .encoder
            .copy_buffer_to_buffer(radiance, 0, &self.cut_radiance, 0, radiance.size());
        let mut pass = frame.compute_pass(self.names[0]);
        self.record_build_pass(&mut pass, cssm, recut_group);
        Ok(())
    }

    /// Builds every receiver's links for the node radiance `radiance` (submitting and waiting
    /// for the GPU): its count read back, slots of [`slot_capacity`], then the links written.
    fn build(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        cssm: &CssmResources,
        inputs: &LinkInputs,
        radiance: &wgpu::Buffer,
    ) -> Result<(), RuntimeError> {
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(radiance, 0, &self.cut_radiance, 0, radiance.size());
        // Counting writes no link, but the layout has the bindings.
        let none = |label| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 8,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let count_group = self.build_group(
            device,
            inputs,
            0,
            (
                &none("radiosity links: none"),
                &none("radiosity link bounds: none"),
            ),
        );
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            self.record_build_pass(&mut pass, cssm, &count_group);
        }
        queue.submit([encoder.finish()]);
        let bytes = readback::read_buffer(
            device,
            queue,
            &self.table,
            0,
            4 * 2 * u64::from(self.leaf_count),
        )?;
        let words: &[u32] = bytemuck::cast_slice(&bytes);
        let mut table = Vec::with_capacity(words.len() + 3);
        let (mut slots, mut count) = (0u64, 0u64);
        for leaf in words.chunks(2) {
            table.extend([slots as u32, leaf[1]]);
            slots += u64::from(slot_capacity(leaf[1]));
            count += u64::from(leaf[1]);
        }
        table.extend([slots as u32, 0, 0]);
        let binding = storage_binding_bytes(&device.limits());
        if 8 * slots > binding || slots > u64::from(LINK_STALE) {
            self.state = State::TooLarge { count };
            return Ok(());
        }
        queue.write_buffer(&self.table, 0, bytemuck::cast_slice(&table));
        let buffer = |label, bytes: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(8),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let links = (
            buffer("radiosity links", 8 * slots),
            buffer("radiosity link bounds", 4 * slots),
        );
        let write_group = self.build_group(device, inputs, 1, (&links.0, &links.1));
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            self.record_build_pass(&mut pass, cssm, &write_group);
        }
        queue.submit([encoder.finish()]);
        let product_groups = inputs
            .products
            .iter()
            .flatten()
            .map(|[radiance_in, radiance_out, irradiance]| {
                layout::bind_group(
                    device,
                    "radiosity product",
                    &self.product_layout,
                    &[
                        self.params[1].as_entire_binding(),
                        inputs.tree[1].as_entire_binding(),
                        inputs.texel_direct.as_entire_binding(),
                        inputs.albedo.as_entire_binding(),
                        radiance_in.as_entire_binding(),
                        radiance_out.as_entire_binding(),
                        irradiance.as_entire_binding(),
                        self.table.as_entire_binding(),
                        links.0.as_entire_binding(),
                        links.1.as_entire_binding(),
                        inputs.converged.as_entire_binding(),
                    ],
                )
            })
            .collect();
        self.state = State::Built {
            product_groups,
            recut_group: self.build_group(device, inputs, 2, (&links.0, &links.1)),
            count,
        };
        Ok(())
    }

    /// The build pass's bind group: counting (`gather` 0), writing (1) or re-cutting (2) into
    /// `links` and their bounds.
    fn build_group(
        &self,
        device: &wgpu::Device,
        inputs: &LinkInputs,
        gather: usize,
        (links, bounds): (&wgpu::Buffer, &wgpu::Buffer),
    ) -> wgpu::BindGroup {
        layout::bind_group(
            device,
            "radiosity links",
            &self.build_layout,
            &[
                self.params[gather].as_entire_binding(),
                inputs.tree[0].as_entire_binding(),
                inputs.tree[1].as_entire_binding(),
                inputs.albedo.as_entire_binding(),
                self.cut_radiance.as_entire_binding(),
                self.table.as_entire_binding(),
                links.as_entire_binding(),
                bounds.as_entire_binding(),
            ],
        )
    }

    /// Records the build pass of `group` into `pass`.
    fn record_build_pass(
        &self,
        pass: &mut wgpu::ComputePass,
        cssm: &CssmResources,
        group: &wgpu::BindGroup,
    ) {
        pass.set_pipeline(&self.build_pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.set_bind_group(1, &cssm.query.bind_group, &[]);
        cssm.moving.bind(pass, 2);
        pass.dispatch_workgroups(shaders::groups_1d(self.leaf_count), 1, 1);
    }
}

/// One product pass of built links ([`Links::product`]).
pub(super) struct Product<'a> {
    name: &'static str,
    pipeline: &'a wgpu::ComputePipeline,
    group: &'a wgpu::BindGroup,
    leaf_count: u32,
}

impl Product<'_> {
    /// Records the pass into `frame`: a workgroup a receiver leaf ([`product_groups`]).
    pub(super) fn record(&self, frame: &mut FrameEncoder) {
        let mut pass = frame.compute_pass(self.name);
        pass.set_pipeline(self.pipeline);
        pass.set_bind_group(0, self.group, &[]);
        let (x, y) = product_groups(self.leaf_count);
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// The product's workgroups for `leaves` receiver leaves, one each (`product.wgsl`: leaf
/// `x + y * width`), at most 65,535 across, the limit of a dispatch's dimension.
pub fn product_groups(leaves: u32) -> (u32, u32) {
    let x = leaves.clamp(1, 65_535);
    (x, leaves.div_ceil(x).max(1))
}
