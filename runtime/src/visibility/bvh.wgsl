// Exact segment visibility by BVH traversal in a compute shader: what a user without CSSMs
// would run (the H100 has no hardware ray queries). The BVH is obvhs' binary BVH; the triangle
// test is the watertight test of Woop, Benthin and Wald (JCGT 2013) as in the CPU reference
// `cssm_bake::raycast` (without its double-precision fallback on exact edge hits: WGSL has no
// f64 everywhere).

struct BvhNode {
    min: vec3f,
    // 0: inner node, children at first_index and first_index + 1; else a leaf of that many
    // triangles starting at first_index.
    prim_count: u32,
    max: vec3f,
    first_index: u32,
}

struct Segment {
    a: vec3f,
    _pad0: u32,
    b: vec3f,
    _pad1: u32,
}

@group(0) @binding(0) var<storage, read> segments: array<Segment>;
@group(0) @binding(1) var<storage, read_write> clear: array<u32>;
@group(1) @binding(0) var<storage, read> nodes: array<BvhNode>;
// Three vertices per triangle, in the BVH's primitive order.
@group(1) @binding(1) var<storage, read> tri_vertices: array<vec4f>;

const STACK: u32 = 64u;

fn axis(v: vec3f, k: u32) -> f32 {
    if k == 0u {
        return v.x;
    } else if k == 1u {
        return v.y;
    }
    return v.z;
}

struct WatertightRay {
    origin: vec3f,
    kx: u32,
    ky: u32,
    kz: u32,
    sx: f32,
    sy: f32,
    sz: f32,
}

fn watertight_ray(origin: vec3f, dir: vec3f) -> WatertightRay {
    let a = abs(dir);
    var kz = 2u;
    if a.x >= a.y && a.x >= a.z {
        kz = 0u;
    } else if a.y >= a.z {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kx + 1u) % 3u;
    let dz = axis(dir, kz);
    if dz < 0.0 {
        let t = kx;
        kx = ky;
        ky = t;
    }
    return WatertightRay(origin, kx, ky, kz, axis(dir, kx) / dz, axis(dir, ky) / dz, 1.0 / dz);
}

fn intersect(r: WatertightRay, i: u32) -> f32 {
    let a = tri_vertices[3u * i].xyz - r.origin;
    let b = tri_vertices[3u * i + 1u].xyz - r.origin;
    let c = tri_vertices[3u * i + 2u].xyz - r.origin;
    let az = axis(a, r.kz);
    let bz = axis(b, r.kz);
    let cz = axis(c, r.kz);
    let ax = axis(a, r.kx) - r.sx * az;
    let ay = axis(a, r.ky) - r.sy * az;
    let bx = axis(b, r.kx) - r.sx * bz;
    let by = axis(b, r.ky) - r.sy * bz;
    let cx = axis(c, r.kx) - r.sx * cz;
    let cy = axis(c, r.ky) - r.sy * cz;
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return -1.0;
    }
    let det = u + v + w;
    if det == 0.0 {
        return -1.0;
    }
    return (u * r.sz * az + v * r.sz * bz + w * r.sz * cz) / det;
}

fn hits_box(n: BvhNode, origin: vec3f, inv_dir: vec3f, tmax: f32) -> bool {
    let t0 = (n.min - origin) * inv_dir;
    let t1 = (n.max - origin) * inv_dir;
    let near = max(max(min(t0.x, t1.x), min(t0.y, t1.y)), max(min(t0.z, t1.z), 0.0));
    let far = min(min(max(t0.x, t1.x), max(t0.y, t1.y)), min(max(t0.z, t1.z), tmax));
    return near <= far;
}

// True when the open segment a..b (parameters 1e-5 to 1 - 1e-5, as SceneBvh::segment_clear)
// hits no triangle.
fn segment_clear(a: vec3f, b: vec3f) -> bool {
    let dir = b - a;
    let r = watertight_ray(a, dir);
    let inv_dir = 1.0 / dir;
    let tmin = 1e-5;
    let tmax = 1.0 - 1e-5;
    var stack: array<u32, STACK>;
    var top = 1u;
    stack[0] = 0u;
    while top > 0u {
        top -= 1u;
        let n = nodes[stack[top]];
        if !hits_box(n, a, inv_dir, tmax) {
            continue;
        }
        if n.prim_count == 0u {
            stack[top] = n.first_index;
            stack[top + 1u] = n.first_index + 1u;
            top += 2u;
        } else {
            for (var k = 0u; k < n.prim_count; k++) {
                let t = intersect(r, n.first_index + k);
                if t > tmin && t < tmax {
                    return false;
                }
            }
        }
    }
    return true;
}

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u, @builtin(num_workgroups) groups: vec3u) {
    let i = id.x + id.y * groups.x * 64u;
    if i >= arrayLength(&segments) {
        return;
    }
    clear[i] = select(0u, 1u, segment_clear(segments[i].a, segments[i].b));
}
