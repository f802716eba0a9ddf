#define_import_path cssm::proxy

// A point proxy and the voxel grid over the scene (Chen et al. 2014 §3.1), shared by the vf
// passes. Rust twins: vf/proxies.rs::{Proxy, GridParams}.

struct Proxy {
    position: vec3f,
    radius: f32,
    normal: vec3f,
    triangle: u32,
    object: u32,
    material: u32,
    uv: vec2f,
}

struct GridParams {
    lo: vec3f,
    cell: f32,
    dims: vec3u,
    count: u32,
}

// The key of the voxel holding `p` by Eq. 1, H(v) = v.z D_x D_y + v.y D_x + v.x, outside points
// clamped to the border voxels (twin: GridParams::key).
fn grid_key(grid: GridParams, p: vec3f) -> u32 {
    let v = min(vec3u(max(floor((p - grid.lo) / grid.cell), vec3f(0.0))), grid.dims - 1u);
    return v.z * grid.dims.x * grid.dims.y + v.y * grid.dims.x + v.x;
}
