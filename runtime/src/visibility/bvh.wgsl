// Exact segment visibility by BVH traversal in a compute shader: what a user without CSSMs
// would run (the H100 has no hardware ray queries), on the ray casting of `cssm::bvh`.

#import cssm::bvh::{STACK, nodes, watertight_ray, intersect, hits_box}

struct Segment {
    a: vec3f,
    _pad0: u32,
    b: vec3f,
    _pad1: u32,
}

@group(0) @binding(0) var<storage, read> segments: array<Segment>;
@group(0) @binding(1) var<storage, read_write> clear: array<u32>;

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
