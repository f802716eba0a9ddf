// Point proxies into their voxel grid (Chen et al. 2014 §3.1): `hash` moves each proxy with
// its object and writes (key, proxy) with the key of its voxel by Eq. 1,
// H(v) = v.z D_x D_y + v.y D_x + v.x; after the pairs are sorted by key (common/sort.rs),
// `cell_ranges` writes each voxel's range [start, end) in the sorted pairs (cleared to 0 before).
// Twins: vf/proxies.rs::{hash_cpu, cells_cpu}.

struct Proxy {
    position: vec3f,
    radius: f32,
    normal: vec3f,
    triangle: u32,
    object: u32,
    padding_a: u32,
    padding_b: u32,
    padding_c: u32,
}

struct GridParams {
    lo: vec3f,
    cell: f32,
    dims: vec3u,
    count: u32,
}

@group(0) @binding(0) var<uniform> grid: GridParams;
@group(0) @binding(1) var<storage, read> proxies: array<Proxy>;
@group(0) @binding(2) var<storage, read> object_motion: array<mat4x4f>;
// (key, proxy index) pairs: lampshade's KeyValue.
@group(0) @binding(3) var<storage, read_write> pairs: array<vec2u>;
@group(0) @binding(4) var<storage, read_write> sorted: array<vec2u>;
@group(0) @binding(5) var<storage, read_write> ranges: array<vec2u>;

@compute @workgroup_size(#{WORKGROUP_1D})
fn hash(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x;
    if i >= grid.count {
        return;
    }
    let p = proxies[i];
    let world = (object_motion[p.object] * vec4f(p.position, 1.0)).xyz;
    let v = min(vec3u(max(floor((world - grid.lo) / grid.cell), vec3f(0.0))), grid.dims - 1u);
    pairs[i] = vec2u(v.z * grid.dims.x * grid.dims.y + v.y * grid.dims.x + v.x, i);
}

@compute @workgroup_size(#{WORKGROUP_1D})
fn cell_ranges(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x;
    if i >= grid.count {
        return;
    }
    let key = sorted[i].x;
    if i == 0u || sorted[i - 1u].x != key {
        ranges[key].x = i;
    }
    if i + 1u == grid.count || sorted[i + 1u].x != key {
        ranges[key].y = i + 1u;
    }
}
