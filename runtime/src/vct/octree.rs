//! The sparse voxel octree's structure on the GPU (Crassin et al. 2011 §4.1, §4.2.1):
//! tiles of 2x2x2 nodes in a node pool, built top-down from the voxel-fragment list of the
//! shared voxeliser one level at a time, without a per-node mutex (Crassin and Green 2012): every
//! fragment flags the node holding it at the level, every flagged node gets a tile of children
//! from an atomic counter, and the next level is the tiles just allocated (its dispatch
//! computed on the GPU, so nothing is read back). Empty space has no nodes: the pool holds the
//! occupied nodes of every level and their siblings, against `resolution³` voxels of a dense
//! grid.
//!
//! The reference is the voxelisation itself: the occupied nodes of level `l` are the
//! fragments' voxels shifted down by `max_level - l` ([`occupied_cells`]); the test walks the
//! GPU's pool ([`walk`]) and compares every level (`tests/gpu/octree.rs`).

use std::collections::BTreeSet;

use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{layout, voxelize::VoxelFragment, voxelize::Voxelizer},
    frame::FrameEncoder,
    shaders,
};

/// `vct/octree.wgsl`, the sparse voxel octree's structure from the fragments (`flag`, `allocate`,
/// `next_level`).
pub const SHADER: crate::shaders::Shader = crate::shaders::shader!("octree", "vct/octree.wgsl");

/// A node's word: occupied but not subdivided (a leaf at the last level).
pub const FLAG: u32 = 0x8000_0000;

/// `octree.wgsl`'s `OctreeParams`, one per level.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct OctreeParams {
    level: u32,
    max_level: u32,
    tile_capacity: u32,
    fragment_capacity: u32,
}

/// The levels of a grid of `resolution` voxels per side (a power of two): the root is level 0,
/// the leaves level `log2(resolution)`.
pub fn max_level(resolution: u32) -> u32 {
    resolution.max(1).ilog2()
}

/// The structure passes and the node pool.
pub struct OctreeBuild {
    /// One `u32` per node, in tiles of 8 (node 0 the root): 0 empty, [`FLAG`] a leaf, else the
    /// tile of its children.
    pub nodes: wgpu::Buffer,
    /// `[tiles allocated, first node of the last level, end of it, 1 after an overflow]`.
    pub state: wgpu::Buffer,
    /// The cell of every occupied node at its level, `x | y << 10 | z << 20`.
    pub node_cells: wgpu::Buffer,
    /// Per tile, `[parent's cell, parent's level]` (tile 0, the root's, none).
    pub tile_cells: wgpu::Buffer,
    /// Per level, `[first node, end]`: the tiles a level's allocation made are contiguous.
    pub levels: wgpu::Buffer,
    /// Tiles the pool holds.
    pub tile_capacity: u32,
    /// Levels below the root.
    pub max_level: u32,
    dispatch: wgpu::Buffer,
    flag: wgpu::ComputePipeline,
    allocate: wgpu::ComputePipeline,
    next_level: wgpu::ComputePipeline,
    dispatch_group: wgpu::BindGroup,
    bind_groups: Vec<wgpu::BindGroup>,
    fragment_capacity: u32,
}

impl OctreeBuild {
    /// The passes over `voxelizer`'s fragments into a pool of `tile_capacity` tiles.
    ///
    /// # Errors
    /// A grid whose resolution is not a power of two, a pool of no tile or beyond the device's
    /// largest storage binding.
    pub fn new(
        device: &wgpu::Device,
        voxelizer: &Voxelizer,
        tile_capacity: u32,
    ) -> Result<Self, RuntimeError> {
        let resolution = voxelizer.grid.resolution;
        if !resolution.is_power_of_two() || resolution < 2 {
            return Err(RuntimeError::Unsupported(format!(
                "an octree needs a power-of-two voxel resolution of at least 2, not {resolution}"
            )));
        }
        let bytes = tile_capacity as u64 * 8 * 4;
        if tile_capacity < 2 || bytes > device.limits().max_storage_buffer_binding_size {
            return Err(RuntimeError::Unsupported(format!(
                "an octree node pool of {tile_capacity} tiles ({bytes} bytes)"
            )));
        }
        let max_level = max_level(resolution);
        let nodes = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("octree nodes"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let state = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("octree state"),
            size: 16,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let storage = |label, size| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_DST
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let node_cells = storage("octree node cells", bytes);
        let tile_cells = storage("octree tile cells", tile_capacity as u64 * 8);
        let levels = storage("octree levels", (max_level as u64 + 1) * 8);
        let dispatch = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("octree dispatch"),
            size: 12,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let entries = [
            layout::uniform(0, c),
            layout::storage(1, true, c),
            layout::storage(2, true, c),
            layout::storage(3, false, c),
            layout::storage(4, false, c),
            layout::storage(5, false, c),
            layout::storage(6, false, c),
        ];
        let bind_layout = layout::bind_group_layout(device, "octree", &entries);
        let dispatch_layout = layout::bind_group_layout(
            device,
            "octree dispatch",
            &[layout::storage(0, false, c), layout::storage(1, false, c)],
        );
        let module = SHADER.create(device);
        let pipeline = |entry, layouts: &[&wgpu::BindGroupLayout]| {
            layout::compute_pipeline_entry(device, "octree", &module, entry, layouts)
        };
        let flag = pipeline("flag", &[&bind_layout]);
        let allocate = pipeline("allocate", &[&bind_layout]);
        let next_level = pipeline("next_level", &[&bind_layout, &dispatch_layout]);
        let dispatch_group = layout::bind_group(
            device,
            "octree dispatch",
            &dispatch_layout,
            &[dispatch.as_entire_binding(), levels.as_entire_binding()],
        );
        // One uniform per level (levels 0 to max_level: the last flags the leaves).
        let bind_groups = (0..=max_level)
            .map(|level| {
                let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("octree params"),
                    contents: bytemuck::bytes_of(&OctreeParams {
                        level,
                        max_level,
                        tile_capacity,
                        fragment_capacity: voxelizer.capacity,
                    }),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
                layout::bind_group(
                    device,
                    "octree",
                    &bind_layout,
                    &[
                        params.as_entire_binding(),
                        voxelizer.count.as_entire_binding(),
                        voxelizer.fragments.as_entire_binding(),
                        nodes.as_entire_binding(),
                        state.as_entire_binding(),
                        node_cells.as_entire_binding(),
                        tile_cells.as_entire_binding(),
                    ],
                )
            })
            .collect();
        Ok(Self {
            nodes,
            state,
            node_cells,
            tile_cells,
            levels,
            tile_capacity,
            max_level,
            dispatch,
            flag,
            allocate,
            next_level,
            dispatch_group,
            bind_groups,
            fragment_capacity: voxelizer.capacity,
        })
    }

    /// Records the build after the voxeliser's pass: the pool cleared, then per level flag,
    /// allocate and the next level's range; the leaves flagged last.
    pub fn run(&self, frame: &mut FrameEncoder, queue: &wgpu::Queue) {
        frame.encoder.clear_buffer(&self.nodes, 0, None);
        // Tile 0 holds the root; level 0 is node 0 alone, one workgroup of allocation.
        queue.write_buffer(&self.state, 0, bytemuck::cast_slice(&[1u32, 0, 1, 0]));
        queue.write_buffer(&self.dispatch, 0, bytemuck::cast_slice(&[1u32, 1, 1]));
        // Level 0 is the root alone; next_level records the others.
        queue.write_buffer(&self.levels, 0, bytemuck::cast_slice(&[0u32, 1]));
        let (x, y) =
            crate::common::voxelize::split_groups(shaders::groups_1d(self.fragment_capacity));
        let mut pass = frame.compute_pass("octree build");
        for (level, group) in self.bind_groups.iter().enumerate() {
            pass.set_bind_group(0, group, &[]);
            pass.set_pipeline(&self.flag);
            pass.dispatch_workgroups(x, y, 1);
            if level as u32 == self.max_level {
                break;
            }
            pass.set_pipeline(&self.allocate);
            pass.dispatch_workgroups_indirect(&self.dispatch, 0);
            pass.set_pipeline(&self.next_level);
            pass.set_bind_group(1, &self.dispatch_group, &[]);
            pass.dispatch_workgroups(1, 1, 1);
        }
    }
}

/// The node holding the leaf cell `cell` at `level` in a node pool read back, walking down from
/// the root (`svo.wgsl::svo_node`); `None` where that part of space is empty.
pub fn node_index(nodes: &[u32], cell: [u32; 3], level: u32, max_level: u32) -> Option<usize> {
    let mut node = 0usize;
    for l in 0..level {
        let word = *nodes.get(node)?;
        if word == 0 {
            return None;
        }
        let shift = max_level - 1 - l;
        let octant = (0..3).map(|k| ((cell[k] >> shift) & 1) << k).sum::<u32>();
        node = (word & !FLAG) as usize * 8 + octant as usize;
    }
    (*nodes.get(node)? != 0).then_some(node)
}

/// The cells of the occupied nodes of each level, root first.
pub type LevelCells = Vec<BTreeSet<[u32; 3]>>;

/// The cells of the occupied nodes at every level, from the fragments: level `l` holds the
/// voxels shifted down by `max_level - l`.
pub fn occupied_cells(fragments: &[VoxelFragment], max_level: u32) -> LevelCells {
    (0..=max_level)
        .map(|level| {
            let shift = max_level - level;
            fragments
                .iter()
                .map(|f| f.cell().map(|c| c >> shift))
                .collect()
        })
        .collect()
}

/// The occupied nodes of a node pool read back, per level, walking down from the root; and the
/// tiles it reached. `Err` for a pointer outside the pool or a tile reached twice.
pub fn walk(nodes: &[u32], max_level: u32) -> Result<(LevelCells, usize), String> {
    let mut levels = vec![BTreeSet::new(); max_level as usize + 1];
    let mut seen = BTreeSet::new();
    let mut stack = vec![(0usize, 0u32, [0u32; 3])];
    while let Some((node, level, cell)) = stack.pop() {
        let word = *nodes
            .get(node)
            .ok_or(format!("node {node} outside the pool"))?;
        if word == 0 {
            continue;
        }
        levels[level as usize].insert(cell);
        if level == max_level {
            if word != FLAG {
                return Err(format!("leaf {node} holds {word:#x}"));
            }
            continue;
        }
        let tile = (word & !FLAG) as usize;
        if word & FLAG != 0 || tile == 0 || !seen.insert(tile) {
            return Err(format!(
                "node {node} at level {level}: bad child tile {word:#x}"
            ));
        }
        for octant in 0..8u32 {
            let child = [octant & 1, (octant >> 1) & 1, (octant >> 2) & 1];
            let cell = [0, 1, 2].map(|k| 2 * cell[k] + child[k]);
            stack.push((tile * 8 + octant as usize, level + 1, cell));
        }
    }
    Ok((levels, seen.len()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octree_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "OctreeParams",
            size_of::<OctreeParams>(),
            &[
                ("level", offset_of!(OctreeParams, level)),
                ("max_level", offset_of!(OctreeParams, max_level)),
                ("tile_capacity", offset_of!(OctreeParams, tile_capacity)),
                (
                    "fragment_capacity",
                    offset_of!(OctreeParams, fragment_capacity),
                ),
            ],
        );
    }

    #[test]
    fn walk_reads_a_hand_built_pool() {
        // Root -> tile 1; its octant 3 (x 1, y 1, z 0) -> tile 2 with leaf octant 5.
        let mut nodes = vec![0u32; 24];
        nodes[0] = 1;
        nodes[8 + 3] = 2;
        nodes[16 + 5] = FLAG;
        let (levels, tiles) = walk(&nodes, 2).unwrap();
        assert_eq!(tiles, 2);
        assert_eq!(levels[1], BTreeSet::from([[1, 1, 0]]));
        assert_eq!(levels[2], BTreeSet::from([[3, 2, 1]]));
        let fragment = VoxelFragment {
            coord: 3 | (2 << 10) | (1 << 20),
            ..Default::default()
        };
        assert_eq!(occupied_cells(&[fragment], 2), levels);
        assert_eq!(node_index(&nodes, [3, 2, 1], 2, 2), Some(16 + 5));
        assert_eq!(node_index(&nodes, [3, 2, 1], 1, 2), Some(8 + 3));
        assert_eq!(node_index(&nodes, [3, 2, 0], 2, 2), None);
        assert_eq!(node_index(&nodes, [0, 0, 0], 1, 2), None);
        nodes[8 + 3] = 1; // a cycle back to tile 1
        assert!(walk(&nodes, 2).is_err());
    }
}
