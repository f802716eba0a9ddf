// The bake's depth cube maps on the GPU (§3.2.1, issue 25): for every pixel of every texel's
// cube map in a batch, the ray `cssm_bake::cubemap::render` casts on the CPU, traversed through
// obvhs' binary BVH (the H200 has no hardware ray queries, and its rasteriser is the slow part
// of its frames: reports/runtime.md). Each invocation reduces its ray's hits as
// `cssm_raycast::HitReducer` does (the first hit, whether its surface faces the texel, the
// nearest facing hit beyond it), in any order; the CPU turns those into the pixel's depth
// interval with the same code as its own renderers. A pixel the kernel could not answer as the
// CPU would (its reducer overflowed, or it judged the pixel behind the tangent plane where
// rounding leaves doubt) is marked, and the CPU casts it itself.

#import cssm::bvh::{STACK, axis, nodes, watertight_ray, intersect, safe_inverse, box_entry}

struct DepthMapParams {
    // Cube-map face resolution N.
    n: u32,
    texel_count: u32,
    // 1: every hit counts as facing the texel (the paper's second layer, `SecondLayer::Any`).
    every_hit_faces: u32,
    _pad0: u32,
    // Hits nearer than this are not seen (`cubemap::min_hit`).
    min_hit: f32,
    // Hits closer together than this are one surface (`cubemap::separation`).
    separation: f32,
    _pad1: f32,
    _pad2: f32,
}

struct DepthMapTexel {
    // The cube's centre: the texel's position pushed off its surface by the near distance,
    // computed on the CPU so that every ray starts where the CPU's does.
    centre: vec3f,
    // The shift of the texel's pixel grid along the faces' u and v axes, in pixels
    // (`cssm_formats::cube::PixelGrid::offset`).
    grid_u: f32,
    normal: vec3f,
    grid_v: f32,
}

@group(0) @binding(0) var<uniform> params: DepthMapParams;
@group(0) @binding(1) var<storage, read> texels: array<DepthMapTexel>;
// Per pixel: the first hit's ray parameter with bit 31 set when its surface faces the texel,
// and the second (facing) hit's; `NONE` for no hit; `RECOMPUTE` in the first word for a pixel
// the CPU must cast.
@group(0) @binding(2) var<storage, read_write> hits: array<vec2u>;
// Every triangle's geometric normal (unnormalised, its winding's front), in the BVH's order.
@group(1) @binding(2) var<storage, read> tri_normals: array<vec4f>;

// No hit: a finite stand-in for infinity, far beyond any scene (shader compilers may assume
// that no value is infinite).
const NONE: f32 = 3.0e38;
const RECOMPUTE: u32 = 0xffffffffu;
// Hits beyond the first that `Reducer` keeps, as `cssm_raycast`'s CLUSTER.
const CLUSTER: u32 = 3u;
// A pixel is skipped as behind the tangent plane only this far beyond the CPU's own test, so
// rounding never skips one the CPU casts.
const BEHIND_MARGIN: f32 = 1e-4;

// `cssm_raycast::HitReducer`: the hits of one ray, met in any order.
struct Reducer {
    first: f32,
    second: f32,
    // Other hits within the separation of `first`.
    cluster: array<f32, CLUSTER>,
    // Bit i for cluster[i] facing the origin, bit CLUSTER for `first`.
    faces: u32,
    len: u32,
    overflowed: bool,
}

// `t` lies more than the separation beyond `first`: another surface.
fn beyond(t: f32, first: f32) -> bool {
    return t - first > params.separation;
}

fn push(r: ptr<function, Reducer>, t: f32, faces: bool) {
    if (*r).len == CLUSTER {
        (*r).overflowed = true;
        return;
    }
    (*r).cluster[(*r).len] = t;
    (*r).faces |= select(0u, 1u, faces) << (*r).len;
    (*r).len += 1u;
}

// A hit that was within the separation of the old first: beyond the new one it may become the
// second, else it stays in the cluster.
fn regroup(r: ptr<function, Reducer>, m: f32, m_faces: bool, t: f32) {
    if beyond(m, t) {
        if m_faces && m < (*r).second {
            (*r).second = m;
        }
    } else {
        push(r, m, m_faces);
    }
}

// `HitReducer::add` for a hit with `0 < t < second`.
fn add(r: ptr<function, Reducer>, t: f32, faces: bool) {
    if t < (*r).first {
        let old_first = (*r).first;
        let old_first_faces = ((*r).faces >> CLUSTER) & 1u;
        let old_cluster = (*r).cluster;
        let old_faces = (*r).faces;
        let old_len = (*r).len;
        (*r).first = t;
        (*r).faces = select(0u, 1u, faces) << CLUSTER;
        (*r).len = 0u;
        for (var i = 0u; i < old_len; i++) {
            regroup(r, old_cluster[i], ((old_faces >> i) & 1u) != 0u, t);
        }
        if old_first < NONE {
            regroup(r, old_first, old_first_faces != 0u, t);
        }
    } else if !beyond(t, (*r).first) {
        push(r, t, faces);
    } else if faces {
        (*r).second = t;
    }
}

fn cast_pixel(texel: DepthMapTexel, pixel: u32) -> vec2u {
    let n = params.n;
    // `cssm_formats::cube::pixel_direction_at`.
    let face = pixel / (n * n);
    let rest = pixel % (n * n);
    let row = rest / n;
    let col = rest % n;
    let u = (f32(col) + 0.5 + texel.grid_u) / f32(n) * 2.0 - 1.0;
    let v = (f32(row) + 0.5 + texel.grid_v) / f32(n) * 2.0 - 1.0;
    let major = face / 2u;
    let ua = (major + 1u) % 3u;
    let va = (major + 2u) % 3u;
    var dir = vec3f(0.0);
    dir[major] = select(-1.0, 1.0, face % 2u == 0u);
    dir[ua] = u;
    dir[va] = v;
    let normal = texel.normal;
    // `cube::pixel_is_dont_care`, with a margin.
    let below = dot(dir, normal);
    let half_step = 1.0 / f32(n);
    if below + half_step * (abs(axis(normal, ua)) + abs(axis(normal, va))) < -BEHIND_MARGIN {
        return vec2u(RECOMPUTE, 0u);
    }
    // `cube::cast_direction`: a straddling pixel whose centre lies below the plane is cast
    // along it.
    if below < 0.0 {
        dir = dir - normal * below;
    }
    let ray = watertight_ray(texel.centre, dir);
    let inv_dir = safe_inverse(dir);
    var r: Reducer;
    r.first = NONE;
    r.second = NONE;
    r.faces = 0u;
    r.len = 0u;
    r.overflowed = false;
    // Nodes whose box the ray enters, with where it enters: nearer children are popped first,
    // and a node entered beyond the current second hit is skipped.
    var stack: array<u32, STACK>;
    var entry: array<f32, STACK>;
    var top = 0u;
    let root = box_entry(nodes[0], texel.centre, inv_dir, params.min_hit, NONE);
    if root >= 0.0 {
        stack[0] = 0u;
        entry[0] = root;
        top = 1u;
    }
    while top > 0u {
        top -= 1u;
        if entry[top] > r.second {
            continue;
        }
        let node = nodes[stack[top]];
        if node.prim_count == 0u {
            let a = node.first_index;
            let ta = box_entry(nodes[a], texel.centre, inv_dir, params.min_hit, r.second);
            let tb = box_entry(nodes[a + 1u], texel.centre, inv_dir, params.min_hit, r.second);
            // Far child first, so the near one is popped next.
            let a_first = ta <= tb || tb < 0.0;
            let near_t = select(tb, ta, a_first);
            let far_t = select(ta, tb, a_first);
            let near_i = select(a + 1u, a, a_first);
            let far_i = select(a, a + 1u, a_first);
            if far_t >= 0.0 {
                stack[top] = far_i;
                entry[top] = far_t;
                top += 1u;
            }
            if near_t >= 0.0 {
                stack[top] = near_i;
                entry[top] = near_t;
                top += 1u;
            }
        } else {
            for (var k = 0u; k < node.prim_count; k++) {
                let tri = node.first_index + k;
                let t = intersect(ray, tri);
                if t > params.min_hit && t < r.second {
                    let faces = params.every_hit_faces != 0u || dot(tri_normals[tri].xyz, dir) < 0.0;
                    add(&r, t, faces);
                }
            }
        }
    }
    if r.overflowed {
        return vec2u(RECOMPUTE, 0u);
    }
    let first_faces = select(0u, 0x80000000u, r.faces != 0u);
    return vec2u(bitcast<u32>(r.first) | first_faces, bitcast<u32>(r.second));
}

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u, @builtin(num_workgroups) groups: vec3u) {
    let i = id.x + id.y * groups.x * #{WORKGROUP_1D}u;
    let pixels = 6u * params.n * params.n;
    if i >= pixels * params.texel_count {
        return;
    }
    hits[i] = cast_pixel(texels[i / pixels], i % pixels);
}
