//! Light into the sparse voxel octree (Crassin et al. 2011 §4.1, §4.2.3, §8.2): the brick pool
//! and the reads of the octree every pass shares ([`Svo`], `svo.wgsl`), and the passes that fill
//! it after the octree's build ([`VoxelRadiance`], `radiance.wgsl`):
//!
//! 1. `plan`: the indirect arguments of the passes below from the build's level ranges, and the
//!    fixed point of the flux;
//! 2. `inject`: every texel of every spot light's RSM adds its reflected flux into the leaf
//!    holding its surface point (§8.2: the light-view pass that splats photons into the
//!    leaves, here the RSM raster the shadow maps already draw), integer atomics;
//! 3. `leaves`: an occupied leaf is opaque and holds its lit surface's radiance, its texels'
//!    flux over pi over the area they cover;
//! 4. `mip`, coarsest last: every subdivided node the mean of its eight children (§4.2.3);
//! 5. `fill bricks`: every tile's 5x5x5 brick, the vertex-centred values of its 2x2x2 nodes
//!    (§4.1's 3³ bricks with their shared borders), the mean of the cells touching each
//!    vertex, so the hardware's trilinear filter inside a brick interpolates the level's
//!    voxel-centred values exactly as a dense mipmapped grid would.
//!
//! What the paper does otherwise: its MIP-mapping weighs the children's 3³ brick voxels by a
//! Gaussian (§4.2.3) where this takes the box filter of a mipmapped grid, which makes the
//! sparse octree and a dense pyramid of the same values ([`super::cpu::Pyramid`]) sample alike
//! and the CPU twin exact; its bricks are per node and found through neighbour pointers where
//! these are per tile and their border cells looked up from the root.

use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{
        converge::{BouncePlan, ConvergeGpu, ConvergeInputs, Convergence},
        layout,
        shadow_map::ShadowMaps,
        voxelize::{VoxelGrid, Voxelizer, split_groups},
    },
    frame::FrameEncoder,
    shaders,
};

use super::{octree::OctreeBuild, trace::TraceParams};

/// `vct/radiance.wgsl` with `vct/svo.wgsl`: light injection, leaves, MIP-mapping, bricks.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("voxel radiance", "vct/radiance.wgsl");

/// Texels per side of a tile's brick: 2x2x2 nodes of 3x3x3 vertex-centred texels sharing their
/// borders.
pub const BRICK: u32 = 5;

/// Format of the brick pool: half floats, filterable, writable from a compute pass.
pub const BRICK_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// `svo.wgsl`'s `SvoParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SvoParams {
    /// World position of the grid's corner.
    pub origin: [f32; 3],
    /// Leaf voxels per world unit.
    pub inv_voxel: f32,
    /// Levels below the root.
    pub max_level: u32,
    /// Leaf voxels per side.
    pub resolution: u32,
    /// Bricks per row and per slice of rows in the pool.
    pub bricks_per_side: u32,
    /// World size of a leaf voxel.
    pub voxel: f32,
    /// Bricks per tile: 1 isotropic, 6 anisotropic (one per direction of view, §9).
    pub faces: u32,
    /// 1: a cone's sample has its opacity corrected for a step shorter than its voxel (§5).
    pub correct_opacity: u32,
    /// Anisotropic: bricks of the tiles above the leaves, six a tile, first in the pool.
    pub inner_bricks: u32,
    /// Bricks the pool holds.
    pub brick_capacity: u32,
}

impl SvoParams {
    /// The parameters of `grid`, `faces` bricks per tile and a pool of `bricks_per_side`.
    pub fn new(grid: &VoxelGrid, faces: u32, bricks_per_side: u32) -> Self {
        Self {
            origin: grid.origin.to_array(),
            inv_voxel: 1.0 / grid.voxel,
            max_level: super::octree::max_level(grid.resolution),
            resolution: grid.resolution,
            bricks_per_side,
            voxel: grid.voxel,
            faces,
            correct_opacity: 0,
            inner_bricks: 0,
            brick_capacity: 0,
        }
    }

    /// The brick of face `face` of tile `tile`, whose nodes are at `level`, where the leaves'
    /// tiles begin at `first_leaf_tile`; `None` beyond the pool (`svo_brick_of`). Isotropic:
    /// the tile's one; anisotropic: six a tile above the leaves, then one a tile of leaves.
    pub fn brick(&self, tile: u32, face: u32, level: u32, first_leaf_tile: u32) -> Option<u32> {
        let brick = if self.faces == 1 {
            tile
        } else if level == self.max_level {
            self.inner_bricks + (tile - first_leaf_tile)
        } else {
            Some(tile * FACES + face).filter(|&b| b < self.inner_bricks)?
        };
        (brick < self.brick_capacity).then_some(brick)
    }

    /// The first texel of brick `brick` in the pool (`svo_brick_origin`).
    pub fn brick_origin(&self, brick: u32) -> [u32; 3] {
        let b = self.bricks_per_side;
        [brick % b, (brick / b) % b, brick / (b * b)].map(|c| c * BRICK)
    }
}

/// Faces of view of an anisotropic voxel: +x, -x, +y, -y, +z, -z.
pub const FACES: u32 = 6;

/// The smallest `b` with `b³ >= tiles`: bricks per side of a pool holding `tiles`.
fn bricks_per_side(tiles: u32) -> u32 {
    let mut b = 1u64;
    while b * b * b < tiles as u64 {
        b += 1;
    }
    b as u32
}

/// The brick pool and the octree's reads (`cssm::svo`): its parameters, the node pool, the
/// bricks and their sampler.
pub struct Svo {
    /// The parameters as uploaded.
    pub params: SvoParams,
    /// [`BRICK_FORMAT`] 3D texture of every tile's brick.
    pub bricks: wgpu::Texture,
    /// Bindings 0, 1 and 4 (parameters, nodes, levels): the passes that fill the bricks.
    pub nodes_layout: wgpu::BindGroupLayout,
    /// The group of [`Self::nodes_layout`].
    pub nodes_group: wgpu::BindGroup,
    /// Bindings 0 to 4 (also the bricks and a trilinear sampler): the passes that sample.
    pub sample_layout: wgpu::BindGroupLayout,
    /// The group of [`Self::sample_layout`].
    pub sample_group: wgpu::BindGroup,
}

/// How the brick pool is laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PoolLayout {
    /// Six bricks a tile above the leaves (§9), else one a tile.
    pub anisotropic: bool,
    /// Anisotropic: the tiles above the leaves (tile 0, the root's, among them) the pool has
    /// room for.
    pub inner_tiles: u32,
    /// Anisotropic: the tiles of leaves it has room for.
    pub leaf_tiles: u32,
}

impl Svo {
    /// The pool of `octree`'s tiles on `grid` laid out as `pool` (isotropic: one brick per
    /// tile of the octree's pool); cones read it with the opacity correction of §5 when
    /// `correct_opacity`.
    ///
    /// # Errors
    /// A pool larger than the device's 3D textures.
    pub fn new(
        device: &wgpu::Device,
        octree: &OctreeBuild,
        grid: &VoxelGrid,
        pool: PoolLayout,
        correct_opacity: bool,
    ) -> Result<Self, RuntimeError> {
        let too_many =
            || RuntimeError::Unsupported(format!("a brick pool for {pool:?}: too many bricks"));
        let (faces, inner_bricks, count) = if pool.anisotropic {
            let inner = pool.inner_tiles.checked_mul(FACES).ok_or_else(too_many)?;
            (
                FACES,
                inner,
                inner.checked_add(pool.leaf_tiles).ok_or_else(too_many)?,
            )
        } else {
            (1, octree.tile_capacity, octree.tile_capacity)
        };
        let per_side = bricks_per_side(count);
        let slices = count.div_ceil(per_side * per_side);
        let size = wgpu::Extent3d {
            width: per_side * BRICK,
            height: per_side * BRICK,
            depth_or_array_layers: slices * BRICK,
        };
        let limit = device.limits().max_texture_dimension_3d;
        if size.width > limit || size.depth_or_array_layers > limit {
            return Err(RuntimeError::Unsupported(format!(
                "a brick pool of {count} bricks ({}x{}x{} texels): the device's 3D textures \
                 are at most {limit} per side",
                size.width, size.height, size.depth_or_array_layers
            )));
        }
        let bricks = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("svo bricks"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D3,
            format: BRICK_FORMAT,
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let params = SvoParams {
            correct_opacity: u32::from(correct_opacity),
            inner_bricks,
            brick_capacity: count,
            ..SvoParams::new(grid, faces, per_side)
        };
        let params_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("svo params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("svo bricks"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let all = wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::FRAGMENT;
        let nodes_entries = [
            layout::uniform(0, all),
            layout::storage(1, true, all),
            layout::storage(4, true, all),
        ];
        let nodes_layout = layout::bind_group_layout(device, "svo nodes", &nodes_entries);
        let sample_entries = [
            nodes_entries[0],
            nodes_entries[1],
            layout::filterable_texture(2, wgpu::TextureViewDimension::D3, all),
            layout::filtering_sampler(3, all),
            nodes_entries[2],
        ];
        let sample_layout = layout::bind_group_layout(device, "svo sample", &sample_entries);
        let nodes_group = layout::bind_group_at(
            device,
            "svo nodes",
            &nodes_layout,
            &[
                (0, params_buffer.as_entire_binding()),
                (1, octree.nodes.as_entire_binding()),
                (4, octree.levels.as_entire_binding()),
            ],
        );
        let view = bricks.create_view(&Default::default());
        let sample_group = layout::bind_group(
            device,
            "svo sample",
            &sample_layout,
            &[
                params_buffer.as_entire_binding(),
                octree.nodes.as_entire_binding(),
                wgpu::BindingResource::TextureView(&view),
                wgpu::BindingResource::Sampler(&sampler),
                octree.levels.as_entire_binding(),
            ],
        );
        Ok(Self {
            params,
            bricks,
            nodes_layout,
            nodes_group,
            sample_layout,
            sample_group,
        })
    }

    /// Bytes of the node pool (nodes, their cells, the tiles' cells), of the brick pool, and
    /// of what the radiance passes keep per node ([`VoxelRadiance`]'s flux, values and
    /// surface).
    pub fn pool_bytes(&self, octree: &OctreeBuild) -> (u64, u64, u64) {
        let tiles = octree.tile_capacity as u64;
        let size = self.bricks.size();
        let texels = size.width as u64 * size.height as u64 * size.depth_or_array_layers as u64;
        let per_node = 16 + 16 * self.params.faces as u64 + 32;
        (tiles * (32 + 32 + 8), texels * 8, tiles * 8 * per_node)
    }
}

/// `radiance.wgsl`'s `RadianceParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct RadianceParams {
    level: u32,
    light_count: u32,
    tile_capacity: u32,
    fragment_capacity: u32,
    cones: u32,
    tan_half: f32,
    offset: f32,
    start: f32,
}

/// The passes from the RSM into the bricks.
pub struct VoxelRadiance {
    /// Per node in fixed point: `[r, g, b]` reflected flux and the area it fell on.
    pub flux: wgpu::Buffer,
    /// Per node and face (at `node * faces + face`): `[radiance times opacity, opacity]`.
    pub values: wgpu::Buffer,
    /// `[flux units per W, radiance per flux unit]` as `plan` computed them.
    pub constants: wgpu::Buffer,
    /// Per node: `[albedo r, g, b sums (0 to 255 a fragment), fragments, normal x, y, z sums
    /// (-127 to 127 a fragment, two's complement), unused]`, for the bounces.
    pub surface: wgpu::Buffer,
    surface_pipeline: wgpu::ComputePipeline,
    surface_group: wgpu::BindGroup,
    bounce: wgpu::ComputePipeline,
    bounce_group: wgpu::BindGroup,
    fragment_groups: (u32, u32),
    args: wgpu::Buffer,
    plan: wgpu::ComputePipeline,
    inject: wgpu::ComputePipeline,
    leaves: wgpu::ComputePipeline,
    mip: wgpu::ComputePipeline,
    fill_bricks: wgpu::ComputePipeline,
    plan_groups: [wgpu::BindGroup; 2],
    level_groups: Vec<wgpu::BindGroup>,
    max_level: u32,
    rsm_size: (u32, u32, u32),
    /// The test that ends the bounces once converged, on the first level's light.
    converge: ConvergeGpu,
}

impl VoxelRadiance {
    /// The passes over `octree`'s pool (built from `voxelizer`'s fragments) into `svo`'s
    /// bricks, from `shadows`' RSM; bounces after the first gather with `cones`, as many as
    /// `bounces` says (the bounces into the leaves, the cones' own not counted).
    ///
    /// # Errors
    /// Shadow maps without their RSM, per-node values beyond the device's largest storage
    /// binding.
    pub fn new(
        device: &wgpu::Device,
        voxelizer: &Voxelizer,
        octree: &OctreeBuild,
        svo: &Svo,
        shadows: &ShadowMaps,
        cones: &TraceParams,
        bounces: BouncePlan,
    ) -> Result<Self, RuntimeError> {
        let rsm = shadows.rsm.as_ref().ok_or_else(|| {
            RuntimeError::Unsupported("voxel light injection needs the shadow maps' RSM".into())
        })?;
        let nodes = octree.tile_capacity as u64 * 8;
        let buffer = |label, size, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC;
        let values_bytes = nodes * 16 * svo.params.faces as u64;
        let limit = device.limits().max_storage_buffer_binding_size;
        if values_bytes > limit {
            return Err(RuntimeError::Unsupported(format!(
                "a sparse voxel octree of {} tiles at {}³ needs {} MiB of node values; the \
                 device binds at most {} MiB: lower the resolution",
                octree.tile_capacity,
                svo.params.resolution,
                values_bytes >> 20,
                limit >> 20
            )));
        }
        let flux = buffer("svo flux", nodes * 16, storage);
        let surface = buffer("svo surface", nodes * 32, storage);
        let values = buffer("svo values", values_bytes, storage);
        let constants = buffer("svo constants", 8, storage);
        let max_level = octree.max_level;
        let args = buffer(
            "svo dispatch",
            (max_level as u64 + 2) * 16,
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
        );
        let c = wgpu::ShaderStages::COMPUTE;
        let array = wgpu::TextureViewDimension::D2Array;
        // Binding 1 is gone: the levels are the octree library's (group 1), so the passes stay
        // within the 8 storage buffers per stage a default device allows.
        let entries = [
            layout::uniform(0, c),
            layout::storage(2, true, c),
            layout::storage(3, true, c),
            layout::storage(4, true, c),
            layout::texture(5, array, c),
            layout::texture(6, array, c),
            layout::texture(7, array, c),
            layout::storage(8, false, c),
            layout::storage(9, false, c),
            layout::storage_texture_of(10, BRICK_FORMAT, wgpu::TextureViewDimension::D3, c),
            layout::storage(11, true, c),
        ];
        let level_layout = layout::bind_group_layout(device, "svo radiance", &entries);
        // `plan` writes the constants the others read: its own groups, without them.
        let plan_layout = layout::bind_group_layout(device, "svo plan", &[entries[0], entries[3]]);
        let plan_out_layout = layout::bind_group_layout(
            device,
            "svo plan out",
            &[
                layout::storage(0, true, c),
                layout::storage(1, false, c),
                layout::storage(2, false, c),
            ],
        );
        let module = SHADER.create(device);
        let pipeline = |entry, layouts: &[&wgpu::BindGroupLayout]| {
            layout::compute_pipeline_entry(device, "svo radiance", &module, entry, layouts)
        };
        let plan = pipeline("plan", &[&plan_layout, &svo.nodes_layout, &plan_out_layout]);
        let inject = pipeline("inject", &[&level_layout, &svo.nodes_layout]);
        let leaves = pipeline("leaves", &[&level_layout, &svo.nodes_layout]);
        let mip = pipeline("mip", &[&level_layout, &svo.nodes_layout]);
        let fill_bricks = pipeline("fill_bricks", &[&level_layout, &svo.nodes_layout]);
        // The bounces' own groups: the fragments in, and the bricks sampled (not written).
        let surface_layout = layout::bind_group_layout(
            device,
            "svo surface",
            &[
                layout::uniform(0, c),
                layout::storage(12, true, c),
                layout::storage(13, true, c),
                layout::storage(14, false, c),
            ],
        );
        let bounce_layout = layout::bind_group_layout(
            device,
            "svo bounce",
            &[
                layout::uniform(0, c),
                layout::storage(3, true, c),
                layout::storage(8, false, c),
                layout::storage(9, false, c),
                layout::storage(14, false, c),
                layout::storage(15, true, c),
            ],
        );
        let surface_pipeline = pipeline("surface_of_leaves", &[&surface_layout, &svo.nodes_layout]);
        let bounce = pipeline("bounce", &[&bounce_layout, &svo.sample_layout]);
        let params = |level| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("svo radiance params"),
                contents: bytemuck::bytes_of(&RadianceParams {
                    level,
                    light_count: shadows.light_count,
                    tile_capacity: octree.tile_capacity,
                    fragment_capacity: voxelizer.capacity,
                    cones: cones.cones,
                    tan_half: cones.tan_half,
                    offset: cones.offset,
                    start: cones.start,
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        let plan_params = params(0);
        let surface_group = layout::bind_group_at(
            device,
            "svo surface",
            &surface_layout,
            &[
                (0, plan_params.as_entire_binding()),
                (12, voxelizer.count.as_entire_binding()),
                (13, voxelizer.fragments.as_entire_binding()),
                (14, surface.as_entire_binding()),
            ],
        );
        let bounce_group = layout::bind_group_at(
            device,
            "svo bounce",
            &bounce_layout,
            &[
                (0, plan_params.as_entire_binding()),
                (3, constants.as_entire_binding()),
                (8, flux.as_entire_binding()),
                (9, values.as_entire_binding()),
                (14, surface.as_entire_binding()),
                (15, octree.node_cells.as_entire_binding()),
            ],
        );
        let fragment_groups = split_groups(shaders::groups_1d(voxelizer.capacity));
        let plan_groups = [
            // Bindings 0 and 4 of the level passes' layout.
            layout::bind_group_at(
                device,
                "svo plan",
                &plan_layout,
                &[
                    (0, plan_params.as_entire_binding()),
                    (4, octree.state.as_entire_binding()),
                ],
            ),
            layout::bind_group(
                device,
                "svo plan out",
                &plan_out_layout,
                &[
                    shadows.lights.as_entire_binding(),
                    args.as_entire_binding(),
                    constants.as_entire_binding(),
                ],
            ),
        ];
        let rsm_views = rsm.views();
        let bricks_view = svo.bricks.create_view(&Default::default());
        let level_groups = (0..=max_level)
            .map(|level| {
                let params = params(level);
                let mut resources = vec![
                    (0, params.as_entire_binding()),
                    (2, octree.tile_cells.as_entire_binding()),
                    (3, constants.as_entire_binding()),
                    (4, octree.state.as_entire_binding()),
                ];
                resources.extend(
                    (5..)
                        .zip(&rsm_views)
                        .map(|(b, v)| (b, wgpu::BindingResource::TextureView(v))),
                );
                resources.extend([
                    (8, flux.as_entire_binding()),
                    (9, values.as_entire_binding()),
                    (10, wgpu::BindingResource::TextureView(&bricks_view)),
                    (11, shadows.lights.as_entire_binding()),
                ]);
                layout::bind_group_at(device, "svo radiance", &level_layout, &resources)
            })
            .collect();
        let rsm_size = (
            rsm.position.width(),
            rsm.position.height(),
            shadows.light_count,
        );
        // The light: the first level's values (tile 1, nodes 8 to 15, the root's children),
        // each the box filter of its leaves; the bounce's dispatch: the leaves'.
        let faces = svo.params.faces;
        let converge = ConvergeGpu::new(
            device,
            bounces,
            &ConvergeInputs {
                solution: [&values, &values],
                held: None,
                mean: (8 * faces, 8 * faces),
                additive: false,
                work_args: Some((&args, 4 * max_level)),
            },
        );
        Ok(Self {
            flux,
            values,
            constants,
            surface,
            surface_pipeline,
            surface_group,
            bounce,
            bounce_group,
            fragment_groups,
            args,
            plan,
            inject,
            leaves,
            mip,
            fill_bricks,
            plan_groups,
            level_groups,
            max_level,
            rsm_size,
            converge,
        })
    }

    /// How many bounces into the leaves the last run computed (read back; waits for the GPU).
    ///
    /// # Errors
    /// GPU errors of the read-back.
    pub fn convergence(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Convergence, RuntimeError> {
        self.converge.read(device, queue)
    }

    /// Records the passes, after the octree's build and the RSM's raster: the direct light
    /// into the bricks, then the plan's bounces into the leaves (§8.1), each dispatched with as
    /// many workgroups as the convergence test leaves it (none once converged; the MIP-mapping
    /// and the bricks after it then compute the same values again).
    pub fn run(&self, frame: &mut FrameEncoder, svo: &Svo) {
        frame.encoder.clear_buffer(&self.flux, 0, None);
        frame.encoder.clear_buffer(&self.values, 0, None);
        let max = self.max_level as usize;
        {
            let mut pass = frame.compute_pass("svo inject");
            pass.set_pipeline(&self.plan);
            pass.set_bind_group(0, &self.plan_groups[0], &[]);
            pass.set_bind_group(1, &svo.nodes_group, &[]);
            pass.set_bind_group(2, &self.plan_groups[1], &[]);
            pass.dispatch_workgroups(1, 1, 1);
            pass.set_pipeline(&self.inject);
            pass.set_bind_group(0, &self.level_groups[max], &[]);
            let (w, h, layers) = self.rsm_size;
            let (x, y) = shaders::groups_2d((w, h));
            pass.dispatch_workgroups(x, y, layers);
        }
        {
            let mut pass = frame.compute_pass("svo mip");
            pass.set_bind_group(1, &svo.nodes_group, &[]);
            pass.set_pipeline(&self.leaves);
            pass.set_bind_group(0, &self.level_groups[max], &[]);
            pass.dispatch_workgroups_indirect(&self.args, 16 * max as u64);
            self.mip(&mut pass);
            self.converge.start(&mut pass);
        }
        {
            let mut pass = frame.compute_pass("svo bricks");
            pass.set_bind_group(1, &svo.nodes_group, &[]);
            self.bricks(&mut pass);
        }
        let bounces = self.converge.plan().max;
        if bounces == 0 {
            return;
        }
        frame.encoder.clear_buffer(&self.surface, 0, None);
        let mut pass = frame.compute_pass("svo bounce");
        pass.set_pipeline(&self.surface_pipeline);
        pass.set_bind_group(0, &self.surface_group, &[]);
        pass.set_bind_group(1, &svo.nodes_group, &[]);
        pass.dispatch_workgroups(self.fragment_groups.0, self.fragment_groups.1, 1);
        for k in 1..=bounces {
            pass.set_pipeline(&self.bounce);
            pass.set_bind_group(0, &self.bounce_group, &[]);
            pass.set_bind_group(1, &svo.sample_group, &[]);
            pass.dispatch_workgroups_indirect(self.converge.bounce_args(), 0);
            pass.set_bind_group(1, &svo.nodes_group, &[]);
            self.mip(&mut pass);
            self.converge.check(&mut pass, k);
            pass.set_bind_group(1, &svo.nodes_group, &[]);
            self.bricks(&mut pass);
        }
    }

    /// MIP-mapping from the leaves' values up (svo's nodes group bound at 1).
    fn mip(&self, pass: &mut wgpu::ComputePass) {
        let max = self.max_level as usize;
        pass.set_pipeline(&self.mip);
        for level in (1..max).rev() {
            pass.set_bind_group(0, &self.level_groups[level], &[]);
            pass.dispatch_workgroups_indirect(&self.args, 16 * level as u64);
        }
    }

    /// Every tile's bricks from the nodes' values (svo's nodes group bound at 1).
    fn bricks(&self, pass: &mut wgpu::ComputePass) {
        let max = self.max_level as usize;
        pass.set_pipeline(&self.fill_bricks);
        pass.set_bind_group(0, &self.level_groups[max], &[]);
        pass.dispatch_workgroups_indirect(&self.args, 16 * (max as u64 + 1));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_layouts_match_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "RadianceParams",
            size_of::<RadianceParams>(),
            &[
                ("level", offset_of!(RadianceParams, level)),
                ("light_count", offset_of!(RadianceParams, light_count)),
                ("tile_capacity", offset_of!(RadianceParams, tile_capacity)),
                (
                    "fragment_capacity",
                    offset_of!(RadianceParams, fragment_capacity),
                ),
                ("cones", offset_of!(RadianceParams, cones)),
                ("tan_half", offset_of!(RadianceParams, tan_half)),
                ("offset", offset_of!(RadianceParams, offset)),
                ("start", offset_of!(RadianceParams, start)),
            ],
        );
        // SvoParams is the `cssm::svo` library's, parsed alone.
        let library: String = include_str!("svo.wgsl")
            .lines()
            .filter(|l| !l.starts_with("#define_import_path"))
            .map(|l| format!("{}\n", l.replace("#{SVO_GROUP}", "1")))
            .collect();
        let library = naga::front::wgsl::parse_str(&library).expect("svo.wgsl parses");
        crate::shaders::tests::check_struct(
            &library,
            "SvoParams",
            size_of::<SvoParams>(),
            &[
                ("origin", offset_of!(SvoParams, origin)),
                ("inv_voxel", offset_of!(SvoParams, inv_voxel)),
                ("max_level", offset_of!(SvoParams, max_level)),
                ("resolution", offset_of!(SvoParams, resolution)),
                ("bricks_per_side", offset_of!(SvoParams, bricks_per_side)),
                ("voxel", offset_of!(SvoParams, voxel)),
                ("faces", offset_of!(SvoParams, faces)),
                ("correct_opacity", offset_of!(SvoParams, correct_opacity)),
            ],
        );
    }

    #[test]
    fn the_pool_holds_every_tile() {
        assert_eq!(bricks_per_side(1), 1);
        assert_eq!(bricks_per_side(8), 2);
        assert_eq!(bricks_per_side(9), 3);
        let params = SvoParams {
            bricks_per_side: 3,
            ..bytemuck::Zeroable::zeroed()
        };
        assert_eq!(params.brick_origin(0), [0, 0, 0]);
        assert_eq!(params.brick_origin(4), [5, 5, 0]);
        assert_eq!(params.brick_origin(26), [10, 10, 10]);
    }
}
