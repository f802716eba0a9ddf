#import cssm::types::View
#import cssm::lowres::lowres_representative
#import cssm::random::{pcg_hash, hash_unit}
#import cssm::proxy::GridParams

// Sparse shadow rays (Chen et al. 2014 §3.1, Fig. 2 (c), (d)): from each pixel of a
// low-resolution G-buffer (the shared filters' representative pixels), `rays` cosine-
// distributed directions around the normal march the voxel grid (Amanatides and Woo), and in
// each voxel they cross test its proxies' discs (its range of the sorted proxies); the first
// voxel whose disc a ray hits ends it and is the ray's entry in the pixel's visible-voxel list
// (NO_VOXEL for a ray that leaves the grid). Twin: vf/march.rs::march_cpu.

struct MarchParams {
    full_size: vec2u,
    low_size: vec2u,
    factor: u32,
    rays: u32,
    seed: u32,
    // Ray origins lifted off their surface by this much along the normal, and hits nearer
    // than it ignored.
    offset: f32,
    // The discs' radii as the rays test them, times the proxies' own (which give each disc
    // its share of the area, and leave gaps between discs).
    disc_scale: f32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: MarchParams;
@group(0) @binding(1) var<uniform> grid: GridParams;
@group(0) @binding(2) var gb_position: texture_2d<f32>;
@group(0) @binding(3) var gb_normal: texture_2d<f32>;
// xyz world position, w disc radius.
@group(0) @binding(4) var<storage, read> vpl_position: array<vec4f>;
// xyz disc normal.
@group(0) @binding(5) var<storage, read> vpl_normal: array<vec4f>;
@group(0) @binding(6) var<storage, read> sorted: array<vec2u>;
@group(0) @binding(7) var<storage, read> ranges: array<vec2u>;
// Per low-res pixel, `rays` voxel keys.
@group(0) @binding(8) var<storage, read_write> visible: array<u32>;

const NO_VOXEL: u32 = 0xffffffffu;
const PI: f32 = 3.14159265358979;

// An orthonormal basis around the unit `n` (Duff et al. 2017).
fn basis(n: vec3f) -> mat3x3f {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    return mat3x3f(vec3f(1.0 + s * n.x * n.x * a, s * b, -s * n.x), vec3f(b, s + n.y * n.y * a, -n.y), n);
}

// The ray parameter of the first disc of voxel `cell` the ray o + t d hits in (t0, t1], or -1.
fn hit_in(cell: u32, o: vec3f, d: vec3f, t0: f32, t1: f32) -> f32 {
    let range = ranges[cell];
    var best = -1.0;
    for (var j = range.x; j < range.y; j++) {
        let v = sorted[j].y;
        let c = vpl_position[v];
        let n = vpl_normal[v].xyz;
        let denom = dot(d, n);
        if abs(denom) < 1e-6 {
            continue;
        }
        let t = dot(c.xyz - o, n) / denom;
        if t <= t0 || t > t1 || (best >= 0.0 && t >= best) {
            continue;
        }
        let p = o + t * d;
        let r = params.disc_scale * c.w;
        if dot(p - c.xyz, p - c.xyz) <= r * r {
            best = t;
        }
    }
    return best;
}

// The key of the first voxel whose disc the ray hits, or NO_VOXEL.
fn march(o: vec3f, d: vec3f) -> u32 {
    let lo = grid.lo;
    let hi = lo + vec3f(grid.dims) * grid.cell;
    // Enter the grid's box.
    let inv = 1.0 / d;
    let ta = (lo - o) * inv;
    let tb = (hi - o) * inv;
    let t_enter = max(max(max(min(ta.x, tb.x), min(ta.y, tb.y)), min(ta.z, tb.z)), 0.0);
    let t_exit = min(min(max(ta.x, tb.x), max(ta.y, tb.y)), max(ta.z, tb.z));
    if t_enter > t_exit {
        return NO_VOXEL;
    }
    let start = o + t_enter * d;
    var v = vec3i(clamp(floor((start - lo) / grid.cell), vec3f(0.0), vec3f(grid.dims) - 1.0));
    let step = vec3i(sign(d));
    let next_edge = lo + (vec3f(v) + select(vec3f(0.0), vec3f(1.0), d > vec3f(0.0))) * grid.cell;
    var t_max = select(vec3f(1e30), (next_edge - o) * inv, d != vec3f(0.0));
    let t_delta = select(vec3f(1e30), abs(grid.cell * inv), d != vec3f(0.0));
    var t = t_enter;
    let dims = vec3i(grid.dims);
    let steps = dims.x + dims.y + dims.z;
    for (var s = 0; s < steps; s++) {
        let cell = u32(v.z * dims.x * dims.y + v.y * dims.x + v.x);
        let t_next = min(min(t_max.x, t_max.y), min(t_max.z, t_exit));
        if hit_in(cell, o, d, max(t, params.offset), t_next) >= 0.0 {
            return cell;
        }
        if t_next >= t_exit {
            break;
        }
        t = t_next;
        if t_max.x <= t_max.y && t_max.x <= t_max.z {
            v.x += step.x;
            t_max.x += t_delta.x;
        } else if t_max.y <= t_max.z {
            v.y += step.y;
            t_max.y += t_delta.y;
        } else {
            v.z += step.z;
            t_max.z += t_delta.z;
        }
        if any(v < vec3i(0)) || any(v >= dims) {
            break;
        }
    }
    return NO_VOXEL;
}

// One invocation per ray (issue 50: one per pixel ran its `rays` rays in a row, and at
// 1280x720 the H200 held only 14,400 such threads, a twentieth of its slots): workgroups of
// WORKGROUP_1D along a row of the low-res image's rays, ray `k` of pixel (x, y) at
// global x = x * rays + k. Every ray repeats the pixel's few loads and its hash; the rays
// and their order in `visible` are those of the per-pixel loop.
@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    let x = id.x / params.rays;
    let k = id.x % params.rays;
    if x >= params.low_size.x || id.y >= params.low_size.y {
        return;
    }
    let pixel = vec2u(x, id.y);
    let slot = (id.y * params.low_size.x + x) * params.rays + k;
    let at = vec2i(lowres_representative(pixel, params.factor, params.full_size));
    let p = textureLoad(gb_position, at, 0);
    if p.w <= 0.0 {
        visible[slot] = NO_VOXEL;
        return;
    }
    let n = textureLoad(gb_normal, at, 0).xyz;
    let frame = basis(n);
    let key = pcg_hash(pixel.x ^ pcg_hash(pixel.y ^ pcg_hash(params.seed)));
    let r1 = hash_unit(key);
    let r2 = hash_unit(pcg_hash(key));
    let o = p.xyz + params.offset * n;
    let u1 = (f32(k) + r1) / f32(params.rays);
    let u2 = fract(f32(k) * 0.618034 + r2);
    let r = sqrt(u1);
    let phi = 2.0 * PI * u2;
    let d = frame * vec3f(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - u1)));
    visible[slot] = march(o, d);
}
