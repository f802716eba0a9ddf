//! Voxel cone tracing over a sparse voxel octree (Crassin et al. 2011), built in slices: the
//! octree's structure from the shared voxeliser's fragments ([`octree`]), the light in its
//! leaves, MIP-mapped up the levels into the brick pool ([`radiance`]), and the CPU twin of the
//! octree's values and reads ([`cpu`]), all of it held together in [`SparseVoxels`]. The cone
//! tracing follows, and then the method's entry in the table.

pub mod cpu;
pub mod octree;
pub mod radiance;

use std::collections::BTreeSet;

use glam::Vec3;

use crate::{
    RuntimeError,
    common::{
        readback::read_buffer,
        voxelize::{VoxelFragment, VoxelGrid, Voxelizer},
    },
    frame::{FrameContext, FrameEncoder},
};

use octree::OctreeBuild;
use radiance::{Svo, VoxelRadiance};

/// Room for geometry that moves after the pools are sized: half as much again.
fn with_margin(count: u64) -> u64 {
    count + count / 2 + 64
}

/// The scene's sparse voxel octree with its light: voxelisation, the octree's build, the light
/// injection, MIP-mapping and bricks, recorded together whenever a light or an object moves.
pub struct SparseVoxels {
    /// The voxelisation pass and its fragment list.
    pub voxelizer: Voxelizer,
    /// The octree's structure.
    pub octree: OctreeBuild,
    /// The brick pool and the octree's reads.
    pub svo: Svo,
    /// The passes from the RSM into the bricks.
    pub radiance: VoxelRadiance,
}

impl SparseVoxels {
    /// The octree of `ctx`'s scene (`bounds` its bounds) at `resolution` leaves per side. The
    /// pools are sized from a first voxelisation read back (its fragments, then the nodes they
    /// occupy at every level), with room for half as much again.
    ///
    /// # Errors
    /// A resolution the voxeliser or the octree refuse, pools beyond the device's limits, the
    /// shadow maps without their RSM, a failed read-back.
    pub fn new(
        ctx: &FrameContext,
        bounds: (Vec3, Vec3),
        resolution: u32,
    ) -> Result<Self, RuntimeError> {
        let device = &ctx.device;
        let grid = VoxelGrid::of_scene(bounds, resolution);
        let probe = Voxelizer::new(device, &ctx.scene, grid, 1)?;
        let count = Self::voxelize(ctx, &probe)?;
        let capacity = u32::try_from(with_margin(count as u64)).map_err(|_| {
            RuntimeError::Unsupported(format!("{count} voxel fragments at {resolution}³"))
        })?;
        let voxelizer = Voxelizer::new(device, &ctx.scene, grid, capacity)?;
        let count = Self::voxelize(ctx, &voxelizer)?;
        let size = count as u64 * std::mem::size_of::<VoxelFragment>() as u64;
        let bytes = read_buffer(device, &ctx.queue, &voxelizer.fragments, 0, size.max(16))?;
        let fragments: &[VoxelFragment] = bytemuck::cast_slice(&bytes[..size as usize]);
        // A tile for the root and one for every occupied node above the leaves.
        let max_level = octree::max_level(resolution);
        let mut tiles = 1u64;
        for level in 0..max_level {
            let shift = max_level - level;
            let cells: BTreeSet<[u32; 3]> = fragments
                .iter()
                .map(|f| f.cell().map(|c| c >> shift))
                .collect();
            tiles += cells.len() as u64;
        }
        let tile_capacity = u32::try_from(with_margin(tiles)).map_err(|_| {
            RuntimeError::Unsupported(format!("{tiles} octree tiles at {resolution}³"))
        })?;
        let octree = OctreeBuild::new(device, &voxelizer, tile_capacity)?;
        let svo = Svo::new(device, &octree, &grid)?;
        let radiance = VoxelRadiance::new(device, &octree, &svo, &ctx.shadows)?;
        Ok(Self {
            voxelizer,
            octree,
            svo,
            radiance,
        })
    }

    /// One voxelisation, its fragment count read back.
    fn voxelize(ctx: &FrameContext, voxelizer: &Voxelizer) -> Result<u32, RuntimeError> {
        let mut timer = crate::common::timestamps::PassTimer::new(&ctx.device, &ctx.queue);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        voxelizer.run(&mut FrameEncoder {
            encoder: &mut encoder,
            timer: &mut timer,
            index: 0,
        });
        ctx.queue.submit([encoder.finish()]);
        let count = read_buffer(&ctx.device, &ctx.queue, &voxelizer.count, 0, 4)?;
        Ok(u32::from_le_bytes([count[0], count[1], count[2], count[3]]))
    }

    /// Records every pass, after the shadow maps' raster (the RSM).
    pub fn run(&self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.voxelizer.run(frame);
        self.octree.run(frame, &ctx.queue);
        self.radiance.run(frame, &self.svo);
    }
}
