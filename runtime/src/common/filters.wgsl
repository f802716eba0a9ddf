#import cssm::types::View
#import cssm::lowres::lowres_representative

// Edge-aware post-processing of indirect light computed at reduced resolution (§4.5, Bang
// 2011): a separable cross-bilateral blur at low resolution guided by the G-buffer at each
// low-res pixel's representative pixel (`blur_x`, then `blur_y`), and joint bilateral
// up-sampling to full resolution guided by the full-res G-buffer (`upsample`, Kopf et al.
// 2007). Signals are `layers` planes of vec4f, index (layer * height + y) * width + x.
// CPU twins: common/filters.rs::{blur, upsample}; test tests/gpu/filters.rs.

struct FilterParams {
    full_size: vec2u,
    low_size: vec2u,
    factor: u32,
    layers: u32,
    radius: u32,
    spatial_sigma: f32,
    depth_sigma: f32,
    normal_power: f32,
    padding_a: u32,
    padding_b: u32,
}

@group(0) @binding(0) var<uniform> params: FilterParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var gbuffer_position: texture_2d<f32>;
@group(0) @binding(3) var gbuffer_normal: texture_2d<f32>;
@group(0) @binding(4) var<storage, read> signal_in: array<vec4f>;
@group(0) @binding(5) var<storage, read_write> signal_out: array<vec4f>;

// Most taps of a blur: radius 16 (FilterOptions::check).
const MAX_TAPS: u32 = 33u;

// The guide at a full-res pixel: covered, distance from the eye, normal.
struct Guide {
    covered: bool,
    distance: f32,
    normal: vec3f,
}

fn guide_at(pixel: vec2u) -> Guide {
    let p = textureLoad(gbuffer_position, vec2i(pixel), 0);
    let n = textureLoad(gbuffer_normal, vec2i(pixel), 0).xyz;
    return Guide(p.w > 0.0, distance(view.eye, p.xyz), n);
}

// Depth and normal weight of `tap` against `centre`, whose distance is the reference
// (twin: filters.rs::range_weight). 0 for normals facing apart.
fn range_weight(centre: Guide, tap: Guide) -> f32 {
    let r = (tap.distance - centre.distance) / (params.depth_sigma * max(centre.distance, 1e-6));
    let c = dot(centre.normal, tap.normal);
    if c <= 0.0 {
        return 0.0;
    }
    return exp(-r * r) * pow(c, params.normal_power);
}

fn blur(id: vec2u, axis: vec2i) {
    let low = params.low_size;
    if id.x >= low.x || id.y >= low.y {
        return;
    }
    let plane = low.x * low.y;
    let centre_index = id.y * low.x + id.x;
    let centre = guide_at(lowres_representative(id, params.factor, params.full_size));
    if !centre.covered {
        for (var l = 0u; l < params.layers; l++) {
            signal_out[l * plane + centre_index] = vec4f(0.0);
        }
        return;
    }
    // The weights once for every layer; 0 for skipped taps.
    var weights: array<f32, MAX_TAPS>;
    var indices: array<u32, MAX_TAPS>;
    let radius = i32(params.radius);
    let s = params.spatial_sigma;
    for (var k = -radius; k <= radius; k++) {
        let slot = u32(k + radius);
        weights[slot] = 0.0;
        let t = vec2i(id) + k * axis;
        if t.x < 0 || t.y < 0 || t.x >= i32(low.x) || t.y >= i32(low.y) {
            continue;
        }
        let tap = guide_at(lowres_representative(vec2u(t), params.factor, params.full_size));
        if !tap.covered {
            continue;
        }
        let spatial = exp(-f32(k * k) / (2.0 * s * s));
        weights[slot] = spatial * range_weight(centre, tap);
        indices[slot] = u32(t.y) * low.x + u32(t.x);
    }
    let taps = 2u * params.radius + 1u;
    for (var l = 0u; l < params.layers; l++) {
        var sum = vec4f(0.0);
        var total = 0.0;
        for (var slot = 0u; slot < taps; slot++) {
            let w = weights[slot];
            if w > 0.0 {
                sum += w * signal_in[l * plane + indices[slot]];
                total += w;
            }
        }
        signal_out[l * plane + centre_index] = sum / total;
    }
}

// Horizontal pass: low-res input -> scratch.
@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn blur_x(@builtin(global_invocation_id) id: vec3u) {
    blur(id.xy, vec2i(1, 0));
}

// Vertical pass: scratch -> blurred.
@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn blur_y(@builtin(global_invocation_id) id: vec3u) {
    blur(id.xy, vec2i(0, 1));
}

// Joint bilateral up-sampling (Kopf et al. 2007): the 2x2 low-res samples around the pixel,
// bilinear weight times the depth and normal weight against the pixel's own guide; when all
// are rejected, the covered sample closest in distance.
@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn upsample(@builtin(global_invocation_id) id: vec3u) {
    let full = params.full_size;
    if id.x >= full.x || id.y >= full.y {
        return;
    }
    let low = params.low_size;
    let low_plane = low.x * low.y;
    let full_plane = full.x * full.y;
    let pixel_index = id.y * full.x + id.x;
    let pixel = guide_at(id.xy);
    if !pixel.covered {
        for (var l = 0u; l < params.layers; l++) {
            signal_out[l * full_plane + pixel_index] = vec4f(0.0);
        }
        return;
    }
    let q = (vec2f(id.xy) + 0.5) / f32(params.factor) - 0.5;
    let base = floor(q);
    let t = q - base;
    let b = vec2i(base);
    var weights: array<f32, 4>;
    var indices: array<u32, 4>;
    var total = 0.0;
    var nearest = 4u;
    var nearest_gap = 0.0;
    for (var i = 0u; i < 4u; i++) {
        let o = vec2u(i & 1u, i >> 1u);
        let s = vec2u(clamp(b + vec2i(o), vec2i(0), vec2i(low) - 1));
        indices[i] = s.y * low.x + s.x;
        weights[i] = 0.0;
        let tap = guide_at(lowres_representative(s, params.factor, full));
        if !tap.covered {
            continue;
        }
        let gap = abs(tap.distance - pixel.distance);
        if nearest == 4u || gap < nearest_gap {
            nearest = i;
            nearest_gap = gap;
        }
        let wx = select(1.0 - t.x, t.x, o.x == 1u);
        let wy = select(1.0 - t.y, t.y, o.y == 1u);
        weights[i] = wx * wy * range_weight(pixel, tap);
        total += weights[i];
    }
    for (var l = 0u; l < params.layers; l++) {
        var value = vec4f(0.0);
        if total >= 1e-6 {
            for (var i = 0u; i < 4u; i++) {
                if weights[i] > 0.0 {
                    value += weights[i] * signal_in[l * low_plane + indices[i]];
                }
            }
            value /= total;
        } else if nearest < 4u {
            value = signal_in[l * low_plane + indices[nearest]];
        }
        signal_out[l * full_plane + pixel_index] = value;
    }
}
