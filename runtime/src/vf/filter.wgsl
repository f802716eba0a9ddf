#import cssm::types::View
#import cssm::lowres::lowres_representative

// The visibility filter (Chen et al. 2014 §3.2, Eq. 4): each pixel of the marching resolution
// unions the visible-voxel lists of its (2m+1)x(2m+1) neighbours that lie on the same
// surface: |d_t - d_c| <= depth d_c (d the distance from the eye) and n_c.n_t >= normal, the
// pixel itself always. The union is built in a bit mask of the grid's voxels (one per pixel,
// in `mask`), then written out in increasing key order: per pixel `capacity` + 1 entries of
// `lists`, the count first. Twin: vf/filter.rs::filter_cpu.

struct FilterParams {
    low_size: vec2u,
    full_size: vec2u,
    factor: u32,
    rays: u32,
    // m: the window is (2m+1) x (2m+1); 0 keeps each pixel's own list.
    radius: u32,
    // u32 words of a voxel mask.
    words: u32,
    // Most voxels of a filtered list: min(voxels, (2m+1)^2 rays).
    capacity: u32,
    depth: f32,
    normal: f32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: FilterParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var gb_position: texture_2d<f32>;
@group(0) @binding(3) var gb_normal: texture_2d<f32>;
// Per marching pixel, `rays` voxel keys (NO_VOXEL for a ray that hit nothing).
@group(0) @binding(4) var<storage, read> visible: array<u32>;
@group(0) @binding(5) var<storage, read_write> mask: array<u32>;
@group(0) @binding(6) var<storage, read_write> lists: array<u32>;

const NO_VOXEL: u32 = 0xffffffffu;

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    let low = params.low_size;
    if id.x >= low.x || id.y >= low.y {
        return;
    }
    let pixel = id.y * low.x + id.x;
    let out = pixel * (params.capacity + 1u);
    let at = vec2i(lowres_representative(id.xy, params.factor, params.full_size));
    let p = textureLoad(gb_position, at, 0);
    if p.w <= 0.0 {
        lists[out] = 0u;
        return;
    }
    let d = distance(view.eye, p.xyz);
    let n = textureLoad(gb_normal, at, 0).xyz;
    let words = pixel * params.words;
    for (var w = 0u; w < params.words; w++) {
        mask[words + w] = 0u;
    }
    let m = i32(params.radius);
    for (var j = -m; j <= m; j++) {
        for (var i = -m; i <= m; i++) {
            let t = vec2i(id.xy) + vec2i(i, j);
            if any(t < vec2i(0)) || any(t >= vec2i(low)) {
                continue;
            }
            let tat = vec2i(lowres_representative(vec2u(t), params.factor, params.full_size));
            let tp = textureLoad(gb_position, tat, 0);
            if tp.w <= 0.0 {
                continue;
            }
            // Eq. 4's delta_d and delta_n.
            let same_depth = abs(distance(view.eye, tp.xyz) - d) <= params.depth * d;
            let same_normal = dot(textureLoad(gb_normal, tat, 0).xyz, n) >= params.normal;
            if !(same_depth && same_normal) && (i != 0 || j != 0) {
                continue;
            }
            let base = (u32(t.y) * low.x + u32(t.x)) * params.rays;
            for (var k = 0u; k < params.rays; k++) {
                let key = visible[base + k];
                if key != NO_VOXEL {
                    mask[words + key / 32u] |= 1u << (key % 32u);
                }
            }
        }
    }
    var count = 0u;
    for (var w = 0u; w < params.words; w++) {
        var bits = mask[words + w];
        while bits != 0u {
            let b = firstTrailingBit(bits);
            bits &= bits - 1u;
            if count < params.capacity {
                count += 1u;
                lists[out + count] = w * 32u + b;
            }
        }
    }
    lists[out] = count;
}
