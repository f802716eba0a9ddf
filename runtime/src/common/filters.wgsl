#import cssm::types::View
#import cssm::lowres::lowres_representative
#import cssm::bilateral::{Guide, bilateral_weight, upsample_weights}

// Edge-aware post-processing of indirect light computed at reduced resolution (§4.5, Bang
// 2011): a separable cross-bilateral blur at low resolution guided by the G-buffer at each
// low-res pixel's representative pixel (`blur_x`, then `blur_y`), and joint bilateral
// up-sampling to full resolution guided by the full-res G-buffer (`upsample`, Kopf et al.
// 2007). Signals are `layers` planes of vec4f, index (layer * height + y) * width + x.
// CPU twins: common/filters/cpu.rs::{blur, upsample}; test tests/gpu/filters.rs.

struct FilterParams {
    full_size: vec2u,
    low_size: vec2u,
    factor: u32,
    layers: u32,
    radius: u32,
    spatial_sigma: f32,
    depth_sigma: f32,
    normal_power: f32,
    // 1: the low-res guide is read from `low_position` and `low_normal` at `guide_offset` +
    // the low-res pixel's index (a pyramid level, common/pyramid.rs); 0: the G-buffer at the
    // low-res pixel's representative pixel.
    guide_buffers: u32,
    guide_offset: u32,
}

@group(0) @binding(0) var<uniform> params: FilterParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var gbuffer_position: texture_2d<f32>;
@group(0) @binding(3) var gbuffer_normal: texture_2d<f32>;
@group(0) @binding(4) var<storage, read> signal_in: array<vec4f>;
@group(0) @binding(5) var<storage, read_write> signal_out: array<vec4f>;
@group(0) @binding(6) var<storage, read> low_position: array<vec4f>;
@group(0) @binding(7) var<storage, read> low_normal: array<vec4f>;

// Most taps of a blur: radius 16 (FilterOptions::check).
const MAX_TAPS: u32 = 33u;

fn guide_at(pixel: vec2u) -> Guide {
    let p = textureLoad(gbuffer_position, vec2i(pixel), 0);
    let n = textureLoad(gbuffer_normal, vec2i(pixel), 0).xyz;
    return Guide(p.w > 0.0, distance(view.eye, p.xyz), n);
}

// The guide of low-res pixel `low`.
fn low_guide_at(low: vec2u) -> Guide {
    if params.guide_buffers == 0u {
        return guide_at(lowres_representative(low, params.factor, params.full_size));
    }
    let i = params.guide_offset + low.y * params.low_size.x + low.x;
    let p = low_position[i];
    return Guide(p.w > 0.0, distance(view.eye, p.xyz), low_normal[i].xyz);
}

fn range_weight(centre: Guide, tap: Guide) -> f32 {
    return bilateral_weight(centre, tap, params.depth_sigma, params.normal_power);
}

fn blur(id: vec2u, axis: vec2i) {
    let low = params.low_size;
    if id.x >= low.x || id.y >= low.y {
        return;
    }
    let plane = low.x * low.y;
    let centre_index = id.y * low.x + id.x;
    let centre = low_guide_at(id);
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
        let tap = low_guide_at(vec2u(t));
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

// Joint bilateral up-sampling (Kopf et al. 2007): the 2x2 low-res samples around the pixel
// weighted by cssm::bilateral::upsample_weights.
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
    let b = vec2i(base);
    var taps: array<Guide, 4>;
    var indices: array<u32, 4>;
    for (var i = 0u; i < 4u; i++) {
        let o = vec2i(vec2u(i & 1u, i >> 1u));
        let s = vec2u(clamp(b + o, vec2i(0), vec2i(low) - 1));
        indices[i] = s.y * low.x + s.x;
        taps[i] = low_guide_at(s);
    }
    let weights = upsample_weights(pixel, taps, q - base, params.depth_sigma, params.normal_power);
    for (var l = 0u; l < params.layers; l++) {
        var value = vec4f(0.0);
        for (var i = 0u; i < 4u; i++) {
            if weights[i] > 0.0 {
                value += weights[i] * signal_in[l * low_plane + indices[i]];
            }
        }
        signal_out[l * full_plane + pixel_index] = value;
    }
}
