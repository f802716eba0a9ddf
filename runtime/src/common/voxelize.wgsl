// Conservative voxelisation of the scene into a voxel-fragment list (after Crassin and Green,
// "Octree-based sparse voxelization using the GPU hardware rasterizer", OpenGL Insights 2012,
// here in a compute pass): every voxel a triangle touches, by the separating-axis test of
// Akenine-Moller (2001), gets one fragment with the triangle's albedo at the voxel and its
// normal. CPU twin: common/voxelize.rs (`voxelize_cpu`, every voxel of the triangle's bounds).
//
// One invocation per triangle and tile of TILE x TILE columns along the triangle's dominant
// axis, so no invocation walks more than a tile (llvmpipe stops an invocation's loops after
// 65,535 iterations; a GPU balances the work better too).

#import cssm::types::Material
#import cssm::albedo::albedo_sample
#import cssm::voxel::VoxelFragment

struct VoxelParams {
    origin: vec3f,
    voxel: f32,
    resolution: u32,
    triangle_count: u32,
    capacity: u32,
    tiles_per_side: u32,
}

@group(0) @binding(0) var<uniform> params: VoxelParams;
// The scene's vertex buffer as words: 13 per vertex (position 3, normal 3, uv 2, atlas uv 2,
// material, triangle, object).
@group(0) @binding(1) var<storage, read> vertex_words: array<u32>;
@group(0) @binding(2) var<storage, read> object_motion: array<mat4x4f>;
@group(0) @binding(3) var<storage, read> materials: array<Material>;
@group(0) @binding(4) var albedo_textures: texture_2d_array<f32>;
@group(0) @binding(5) var<storage, read_write> fragment_count: atomic<u32>;
@group(0) @binding(6) var<storage, read_write> fragments: array<VoxelFragment>;

const WORDS_PER_VERTEX: u32 = 17u;
// Columns per tile side (`voxelize::TILE`).
const TILE: u32 = 16u;

fn word_f32(i: u32) -> f32 {
    return bitcast<f32>(vertex_words[i]);
}

fn vertex_position(v: u32) -> vec3f {
    let base = v * WORDS_PER_VERTEX;
    let object = vertex_words[base + 12u];
    let p = vec3f(word_f32(base), word_f32(base + 1u), word_f32(base + 2u));
    return (object_motion[object] * vec4f(p, 1.0)).xyz;
}

fn vertex_uv(v: u32) -> vec2f {
    let base = v * WORDS_PER_VERTEX;
    return vec2f(word_f32(base + 6u), word_f32(base + 7u));
}

fn component(v: vec3f, axis: u32) -> f32 {
    if axis == 0u {
        return v.x;
    }
    if axis == 1u {
        return v.y;
    }
    return v.z;
}

// Akenine-Moller's triangle-box overlap (`voxelize::triangle_box_overlap`): the triangle's
// corners relative to the box centre, the box's half size `h`; touching counts.
fn axis_separates(axis: vec3f, v0: vec3f, v1: vec3f, v2: vec3f, h: f32) -> bool {
    let p0 = dot(axis, v0);
    let p1 = dot(axis, v1);
    let p2 = dot(axis, v2);
    let r = h * (abs(axis.x) + abs(axis.y) + abs(axis.z));
    return min(p0, min(p1, p2)) > r || max(p0, max(p1, p2)) < -r;
}

fn triangle_box_overlap(v0: vec3f, v1: vec3f, v2: vec3f, h: f32) -> bool {
    let e0 = v1 - v0;
    let e1 = v2 - v1;
    let e2 = v0 - v2;
    let edges = array<vec3f, 3>(e0, e1, e2);
    for (var i = 0u; i < 3u; i++) {
        let e = edges[i];
        if axis_separates(vec3f(0.0, -e.z, e.y), v0, v1, v2, h)
            || axis_separates(vec3f(e.z, 0.0, -e.x), v0, v1, v2, h)
            || axis_separates(vec3f(-e.y, e.x, 0.0), v0, v1, v2, h) {
            return false;
        }
    }
    let lo = min(v0, min(v1, v2));
    let hi = max(v0, max(v1, v2));
    if any(lo > vec3f(h)) || any(hi < vec3f(-h)) {
        return false;
    }
    return !axis_separates(cross(e0, e1), v0, v1, v2, h);
}

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    let t = id.x;
    if t >= params.triangle_count {
        return;
    }
    let a = vertex_position(3u * t);
    let b = vertex_position(3u * t + 1u);
    let c = vertex_position(3u * t + 2u);
    let n = cross(b - a, c - a);
    if dot(n, n) == 0.0 {
        return;
    }
    let r = i32(params.resolution);
    let to_grid = 1.0 / params.voxel;
    let lo = clamp(vec3i(floor((min(a, min(b, c)) - params.origin) * to_grid)), vec3i(0), vec3i(r - 1));
    let hi = clamp(vec3i(floor((max(a, max(b, c)) - params.origin) * to_grid)), vec3i(0), vec3i(r - 1));
    // The dominant axis d and the two others u, v: columns along d over the (u, v) footprint.
    let an = abs(n);
    var d = 2u;
    if an.x >= an.y && an.x >= an.z {
        d = 0u;
    } else if an.y >= an.z {
        d = 1u;
    }
    let u = (d + 1u) % 3u;
    let v = (d + 2u) % 3u;
    let lo_u = component(vec3f(lo), u);
    let lo_v = component(vec3f(lo), v);
    let width = i32(component(vec3f(hi), u) - lo_u) + 1;
    let height = i32(component(vec3f(hi), v) - lo_v) + 1;
    let tiles_u = (width + i32(TILE) - 1) / i32(TILE);
    let tiles_v = (height + i32(TILE) - 1) / i32(TILE);
    let tile = i32(id.y);
    if tile >= tiles_u * tiles_v {
        return;
    }
    let tile_u = i32(lo_u) + (tile % tiles_u) * i32(TILE);
    let tile_v = i32(lo_v) + (tile / tiles_u) * i32(TILE);
    let h = 0.5 * params.voxel;
    let m = materials[vertex_words[3u * t * WORDS_PER_VERTEX + 10u]];
    let unit_n = normalize(n);
    let plane = dot(n, a);
    let nd = component(n, d);
    let nu = component(n, u);
    let nv = component(n, v);
    let d_lo = i32(component(vec3f(lo), d));
    let d_hi = i32(component(vec3f(hi), d));
    for (var cu = tile_u; cu < min(tile_u + i32(TILE), i32(lo_u) + width); cu++) {
        for (var cv = tile_v; cv < min(tile_v + i32(TILE), i32(lo_v) + height); cv++) {
            // The plane's extent along d over the column's square, one voxel wider each way.
            let wu0 = component(params.origin, u) + f32(cu) * params.voxel;
            let wv0 = component(params.origin, v) + f32(cv) * params.voxel;
            var z_min = 1e30;
            var z_max = -1e30;
            for (var k = 0u; k < 4u; k++) {
                let wu = wu0 + f32(k & 1u) * params.voxel;
                let wv = wv0 + f32(k >> 1u) * params.voxel;
                let z = (plane - nu * wu - nv * wv) / nd;
                z_min = min(z_min, z);
                z_max = max(z_max, z);
            }
            let od = component(params.origin, d);
            let first = max(d_lo, i32(floor((z_min - od) * to_grid)) - 1);
            let last = min(d_hi, i32(floor((z_max - od) * to_grid)) + 1);
            for (var cd = first; cd <= last; cd++) {
                var cell = vec3i(0);
                cell[d] = cd;
                cell[u] = cu;
                cell[v] = cv;
                let centre = params.origin + (vec3f(cell) + 0.5) * params.voxel;
                if !triangle_box_overlap(a - centre, b - centre, c - centre, h) {
                    continue;
                }
                // The triangle's albedo at the voxel centre projected onto its plane.
                let w = barycentric(centre, a, b, c);
                let uv = w.x * vertex_uv(3u * t) + w.y * vertex_uv(3u * t + 1u)
                    + w.z * vertex_uv(3u * t + 2u);
                var albedo = m.kd;
                if m.texture >= 0 {
                    albedo *= albedo_sample(albedo_textures, u32(m.texture), uv);
                }
                let slot = atomicAdd(&fragment_count, 1u);
                if slot < params.capacity {
                    let coord = u32(cell.x) | (u32(cell.y) << 10u) | (u32(cell.z) << 20u);
                    fragments[slot] = VoxelFragment(
                        coord,
                        pack4x8unorm(vec4f(albedo, 1.0)),
                        pack4x8snorm(vec4f(unit_n, 0.0)),
                        t,
                    );
                }
            }
        }
    }
}

// Barycentric coordinates of p's projection onto the triangle's plane, clamped to the triangle
// and renormalised (`voxelize::clamped_barycentric`).
fn barycentric(p: vec3f, a: vec3f, b: vec3f, c: vec3f) -> vec3f {
    let v0 = b - a;
    let v1 = c - a;
    let v2 = p - a;
    let d00 = dot(v0, v0);
    let d01 = dot(v0, v1);
    let d11 = dot(v1, v1);
    let d20 = dot(v2, v0);
    let d21 = dot(v2, v1);
    let denom = d00 * d11 - d01 * d01;
    if denom == 0.0 {
        return vec3f(1.0, 0.0, 0.0);
    }
    let y = (d11 * d20 - d01 * d21) / denom;
    let z = (d00 * d21 - d01 * d20) / denom;
    let w = max(vec3f(1.0 - y - z, y, z), vec3f(0.0));
    return w / (w.x + w.y + w.z);
}
