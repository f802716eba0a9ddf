// Point proxies into their voxel grid (Chen et al. 2014 §3.1): `hash` moves each proxy with
// its object and writes (key, proxy) with the key of its voxel by Eq. 1,
// H(v) = v.z D_x D_y + v.y D_x + v.x; after the pairs are sorted by key (common/sort.rs),
// `cell_ranges` writes each voxel's range [start, end) in the sorted pairs (cleared to 0 before).
// Twins: vf/proxies.rs::{hash_cpu, cells_cpu}.

#import cssm::proxy::{Proxy, GridParams, grid_key}

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
    pairs[i] = vec2u(grid_key(grid, world), i);
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
