#import cssm::types::View
#import cssm::visibility::{CSSM_NONE, cssm_cell, cssm_texel_at, cssm_texels}

// Indirect light from the atlas per pixel: the radiosity iteration's indirect irradiance per
// texel, looked up at the pixel's atlas coordinates and reflected with the pixel's albedo.
// Mode 0: the texel under the pixel (the "direct visualisation" of the radiosity solution,
// §4.4); mode 1: a bicubic B-spline over the 4x4 texels around it, restricted to the chart
// of the texel under it (the view-dependent lightmap's "high quality bicubic texture filter",
// §5, Fig. 17). CPU twin: lightmap/mod.rs::lookup. Needs types.wgsl and the CSSM library at
// group 1.

struct LookupParams {
    mode: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: LookupParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var<storage, read> texel_irradiance: array<vec4f>;
@group(0) @binding(3) var gbuffer_position: texture_2d<f32>;
@group(0) @binding(4) var gbuffer_albedo: texture_2d<f32>;
@group(0) @binding(5) var gbuffer_atlas: texture_2d<f32>;
@group(0) @binding(6) var<storage, read_write> indirect: array<vec4f>;

// Uniform cubic B-spline weights of the samples at -1, 0, 1, 2 for the fraction t.
fn bspline_weights(t: f32) -> vec4f {
    let t2 = t * t;
    let t3 = t2 * t;
    let s = 1.0 - t;
    return vec4f(s * s * s, 3.0 * t3 - 6.0 * t2 + 4.0, -3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0, t3) / 6.0;
}

fn lookup(p: vec2f) -> vec3f {
    let centre = cssm_texel_at(p);
    if centre == CSSM_NONE {
        return vec3f(0.0);
    }
    if params.mode == 0u {
        return texel_irradiance[centre].rgb;
    }
    let chart = cssm_texels[centre].chart;
    let f = p - vec2f(0.5);
    let base = vec2i(floor(f));
    let t = f - floor(f);
    let wx = bspline_weights(t.x);
    let wy = bspline_weights(t.y);
    var sum = vec3f(0.0);
    var total = 0.0;
    for (var j = 0; j < 4; j++) {
        for (var i = 0; i < 4; i++) {
            let cell = cssm_cell(base.x - 1 + i, base.y - 1 + j);
            if cell == CSSM_NONE || cssm_texels[cell].chart != chart {
                continue;
            }
            let w = wx[i] * wy[j];
            sum += w * texel_irradiance[cell].rgb;
            total += w;
        }
    }
    if total <= 0.0 {
        return texel_irradiance[centre].rgb;
    }
    return sum / total;
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= view.size.x || id.y >= view.size.y {
        return;
    }
    let pixel = id.y * view.size.x + id.x;
    let xy = vec2i(id.xy);
    var value = vec4f(0.0);
    if textureLoad(gbuffer_position, xy, 0).w > 0.0 {
        let albedo = textureLoad(gbuffer_albedo, xy, 0).rgb;
        let e = lookup(textureLoad(gbuffer_atlas, xy, 0).xy);
        value = vec4f(albedo / 3.14159265358979 * e, 0.0);
    }
    indirect[pixel] = value;
}
