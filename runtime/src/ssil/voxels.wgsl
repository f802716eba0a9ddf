#import cssm::types::View

// Visibility for the SSIL gather (Soler et al. 2010 §4, "Visibility computation"): a binary
// solid voxelisation of the view frustum after Eisemann and Décoret 2008, one column of 128
// one-bit voxels per pixel of the first gathered level, in view depth from `z_near` to
// `z_far`. Every fragment of every triangle toggles (XOR) the voxels of its column from its
// own depth to the far end, so after all triangles a voxel is set where an odd number of
// surfaces lies in front of it along its pixel's ray: inside a closed object (the method needs
// watertight geometry, §5.3). `and_down` builds each coarser level's columns as the AND of
// their 2x2 children (§4: conservative, only x and y are reduced).
// Twins: ssil/cpu.rs::{voxelize, and_down}.

struct VoxelParams {
    // View depth of slice 0's near side and of slice 127's far side.
    z_near: f32,
    z_far: f32,
    // Columns of the raster level.
    columns: vec2u,
}

struct AndParams {
    fine_size: vec2u,
    coarse_size: vec2u,
    // Column of the finer and coarser level's (0, 0) in the grid.
    fine_offset: u32,
    coarse_offset: u32,
    padding_a: u32,
    padding_b: u32,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<uniform> voxel: VoxelParams;
@group(0) @binding(2) var<storage, read> object_motion: array<mat4x4f>;
@group(0) @binding(3) var<storage, read_write> grid: array<atomic<u32>>;
@group(0) @binding(4) var<uniform> and_params: AndParams;

// Slices per column, four words of 32.
const SLICES: u32 = 128u;

struct VertexIn {
    @location(0) position: vec3f,
    @location(6) object: u32,
}

struct VertexOut {
    @builtin(position) clip: vec4f,
    @location(0) position: vec3f,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let position = (object_motion[v.object] * vec4f(v.position, 1.0)).xyz;
    var out: VertexOut;
    out.clip = view.view_proj * vec4f(position, 1.0);
    out.position = position;
    return out;
}

// The slice of view depth `z`, clamped to the grid.
fn slice_of(z: f32) -> u32 {
    let t = (z - voxel.z_near) / (voxel.z_far - voxel.z_near);
    return u32(clamp(floor(t * f32(SLICES)), 0.0, f32(SLICES - 1u)));
}

// The bits of word `word` at slices `first` and beyond.
fn mask_from(first: u32, word: u32) -> u32 {
    let start = 32u * word;
    if first <= start {
        return 0xffffffffu;
    }
    if first >= start + 32u {
        return 0u;
    }
    return ~((1u << (first - start)) - 1u);
}

@fragment
fn fs_main(in: VertexOut) {
    let column = vec2u(in.clip.xy);
    if column.x >= voxel.columns.x || column.y >= voxel.columns.y {
        return;
    }
    // View depth: the clip w of the world position (linear, unlike the depth buffer's z).
    let clip = view.view_proj * vec4f(in.position, 1.0);
    let first = slice_of(clip.w);
    let base = 4u * (column.y * voxel.columns.x + column.x);
    for (var w = 0u; w < 4u; w++) {
        let bits = mask_from(first, w);
        if bits != 0u {
            atomicXor(&grid[base + w], bits);
        }
    }
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn and_down(@builtin(global_invocation_id) id: vec3u) {
    let p = and_params;
    if id.x >= p.coarse_size.x || id.y >= p.coarse_size.y {
        return;
    }
    var words = vec4u(0xffffffffu);
    for (var c = 0u; c < 4u; c++) {
        let child = 2u * id.xy + vec2u(c & 1u, c >> 1u);
        if child.x >= p.fine_size.x || child.y >= p.fine_size.y {
            continue;
        }
        let base = 4u * (p.fine_offset + child.y * p.fine_size.x + child.x);
        for (var w = 0u; w < 4u; w++) {
            words[w] &= atomicLoad(&grid[base + w]);
        }
    }
    let out = 4u * (p.coarse_offset + id.y * p.coarse_size.x + id.x);
    for (var w = 0u; w < 4u; w++) {
        atomicStore(&grid[out + w], words[w]);
    }
}
