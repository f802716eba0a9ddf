#define_import_path cssm::bvh

// Ray casting against obvhs' binary BVH in a compute shader, shared by the exact segment
// visibility baseline (`bvh.wgsl`) and the bake's depth cube maps on the GPU
// (`depth_maps.wgsl`). The triangle test is the watertight test of Woop, Benthin and Wald
// (JCGT 2013), the very arithmetic of the CPU reference `cssm_raycast::WatertightRay`: neither
// takes the paper's double-precision fallback on exact edge hits (WGSL has no f64), so the two
// devices decide a ray through an edge alike where both round as IEEE f32.

struct BvhNode {
    min: vec3f,
    // 0: inner node, children at first_index and first_index + 1; else a leaf of that many
    // triangles starting at first_index.
    prim_count: u32,
    max: vec3f,
    first_index: u32,
}

@group(1) @binding(0) var<storage, read> nodes: array<BvhNode>;
// Three vertices per triangle, in the BVH's primitive order.
@group(1) @binding(1) var<storage, read> tri_vertices: array<vec4f>;

// Entries of a traversal stack: deeper than any BVH the kernels accept (`MAX_DEPTH`).
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

// The ray runs in the triangle's plane to within rounding: the triangle seen along it is a
// sliver at most 1 / 65536 as wide as its corners' largest offset from the ray. A miss (CPU twin:
// `cssm_raycast`'s `seen_edge_on`, the same powers of two and `max`).
fn seen_edge_on(ax: f32, ay: f32, bx: f32, by: f32, cx: f32, cy: f32, det: f32) -> bool {
    let reach = max(max(max(abs(ax), abs(ay)), max(abs(bx), abs(by))), max(abs(cx), abs(cy)));
    return abs(det) <= reach * reach * (1.0 / 65536.0);
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
    if det == 0.0 || seen_edge_on(ax, ay, bx, by, cx, cy, det) {
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


// `1 / d` with each zero component taken as a tiny positive one: a box test never multiplies
// zero by infinity (a ray cast along an axis-aligned wall has a zero component).
fn safe_inverse(d: vec3f) -> vec3f {
    return 1.0 / select(d, vec3f(1e-30), d == vec3f(0.0));
}

// Where the ray enters the node's box within `[tmin, tmax]`, or -1 when it misses it there.
fn box_entry(n: BvhNode, origin: vec3f, inv_dir: vec3f, tmin: f32, tmax: f32) -> f32 {
    let t0 = (n.min - origin) * inv_dir;
    let t1 = (n.max - origin) * inv_dir;
    let near = max(max(min(t0.x, t1.x), min(t0.y, t1.y)), max(min(t0.z, t1.z), tmin));
    let far = min(min(max(t0.x, t1.x), max(t0.y, t1.y)), min(max(t0.z, t1.z), tmax));
    return select(-1.0, near, near <= far);
}
