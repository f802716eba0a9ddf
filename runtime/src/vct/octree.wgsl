// The sparse voxel octree's structure, built top-down from the voxel-fragment list one level at a
// time (Crassin et al. 2011 §4.2.1, in the form of Crassin and Green 2012: flag, allocate, no
// per-node mutex). CPU reference: vct/octree.rs (`occupied_cells`, the fragments' cells at each
// level); test `tests/gpu/octree.rs`.
//
// The node pool holds tiles of 2x2x2 nodes (§4.1); node 0 is the root (the rest of tile 0 is
// unused). A node's word is 0 (empty), FLAG (occupied, not yet subdivided: a leaf at the last
// level) or the index of its children's tile. Beside the pool the build records what the
// radiance passes need (vct/radiance.wgsl): every occupied node's cell, every tile's parent cell
// and level, and every level's range of nodes.

#import cssm::voxel::{VoxelFragment, fragment_cell, split_groups, split_item}

const WORKGROUP: u32 = #{WORKGROUP_1D}u;

struct OctreeParams {
    level: u32,
    max_level: u32,
    tile_capacity: u32,
    fragment_capacity: u32,
}

@group(0) @binding(0) var<uniform> params: OctreeParams;
@group(0) @binding(1) var<storage, read> fragment_count: array<u32>;
@group(0) @binding(2) var<storage, read> fragments: array<VoxelFragment>;
@group(0) @binding(3) var<storage, read_write> nodes: array<atomic<u32>>;
// [0] tiles allocated, [1] first node of the level, [2] end of the level, [3] 1 after an overflow.
@group(0) @binding(4) var<storage, read_write> state: array<atomic<u32>, 4>;
// The cell of every occupied node at its level, x | y << 10 | z << 20.
@group(0) @binding(5) var<storage, read_write> node_cells: array<u32>;
// Per tile: its parent's cell and level (tile 0, the root's, has none).
@group(0) @binding(6) var<storage, read_write> tile_cells: array<vec2u>;
// Workgroups of the next allocation pass (an indirect dispatch): bound only with `next_level`,
// so that `allocate` reads it as its indirect arguments alone.
@group(1) @binding(0) var<storage, read_write> dispatch: array<u32, 3>;
// Per level: its first node and the end of its range.
@group(1) @binding(1) var<storage, read_write> levels: array<vec2u>;

const FLAG: u32 = 0x80000000u;

// The node of `cell` (leaf coordinates) at `params.level`, walking down from the root.
fn node_at_level(cell: vec3u) -> u32 {
    var node = 0u;
    for (var l = 0u; l < params.level; l++) {
        let tile = atomicLoad(&nodes[node]) & ~FLAG;
        if tile == 0u {
            return 0xffffffffu;
        }
        let shift = params.max_level - 1u - l;
        let octant = ((cell.x >> shift) & 1u) | (((cell.y >> shift) & 1u) << 1u)
            | (((cell.z >> shift) & 1u) << 2u);
        node = tile * 8u + octant;
    }
    return node;
}

// 1. Every fragment flags the node that holds it at this level.
@compute @workgroup_size(#{WORKGROUP_1D})
fn flag(
    @builtin(workgroup_id) group: vec3u,
    @builtin(num_workgroups) groups: vec3u,
    @builtin(local_invocation_index) local: u32,
) {
    let count = min(fragment_count[0], params.fragment_capacity);
    let i = split_item(group, groups, local, WORKGROUP);
    if i >= count {
        return;
    }
    let f = fragments[i];
    let cell = fragment_cell(f);
    let node = node_at_level(cell);
    if node != 0xffffffffu {
        atomicOr(&nodes[node], FLAG);
        // Every fragment of the node writes the same word.
        let c = cell >> vec3u(params.max_level - params.level);
        node_cells[node] = c.x | (c.y << 10u) | (c.z << 20u);
    }
}

// 2. Every flagged node of the level gets a tile of children.
@compute @workgroup_size(#{WORKGROUP_1D})
fn allocate(
    @builtin(workgroup_id) group: vec3u,
    @builtin(num_workgroups) groups: vec3u,
    @builtin(local_invocation_index) local: u32,
) {
    let node = atomicLoad(&state[1]) + split_item(group, groups, local, WORKGROUP);
    if node >= atomicLoad(&state[2]) {
        return;
    }
    if (atomicLoad(&nodes[node]) & FLAG) == 0u {
        return;
    }
    let tile = atomicAdd(&state[0], 1u);
    if tile >= params.tile_capacity {
        atomicStore(&state[3], 1u);
        atomicStore(&nodes[node], 0u);
        return;
    }
    atomicStore(&nodes[node], tile);
    tile_cells[tile] = vec2u(node_cells[node], params.level);
}

// 3. The next level is the tiles this allocation made: its range and its dispatch.
@compute @workgroup_size(#{WORKGROUP_1D})
fn next_level(@builtin(global_invocation_id) id: vec3u) {
    if id.x != 0u {
        return;
    }
    let tiles = min(atomicLoad(&state[0]), params.tile_capacity);
    let first = atomicLoad(&state[2]);
    let end = 8u * tiles;
    atomicStore(&state[1], first);
    atomicStore(&state[2], end);
    levels[params.level + 1u] = vec2u(first, end);
    let split = split_groups((end - first + WORKGROUP - 1u) / WORKGROUP);
    dispatch[0] = split.x;
    dispatch[1] = split.y;
    dispatch[2] = split.z;
}
