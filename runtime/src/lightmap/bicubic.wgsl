#define_import_path cssm::atlas_filter

#import cssm::visibility::{CSSM_NONE, cssm_cell, cssm_texel_at, cssm_texels}

// A per-texel quantity of the atlas looked up at a point of it: the texel under the point, or
// a bicubic B-spline over the 4x4 texels around it, restricted to the chart of the texel under
// it (the view-dependent lightmap's "high quality bicubic texture filter", §5, Fig. 17). Read by
// `lightmap/lookup.wgsl` (the radiosity's irradiance) and `lightcuts/final_gather.wgsl` (the far
// field). The importing module binds the per-texel values at group 0, binding 15, out of the way
// of its own bindings. CPU twin: lightmap/mod.rs::lookup. Needs the CSSM library at group 1.

@group(0) @binding(15) var<storage, read> atlas_values: array<vec4f>;

// Uniform cubic B-spline weights of the samples at -1, 0, 1, 2 for the fraction t.
fn bspline_weights(t: f32) -> vec4f {
    let t2 = t * t;
    let t3 = t2 * t;
    let s = 1.0 - t;
    return vec4f(s * s * s, 3.0 * t3 - 6.0 * t2 + 4.0, -3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0, t3) / 6.0;
}

// The value at atlas coordinates `p` (texels): `bicubic` false, its texel's; true, the chart's
// B-spline. Zero where no texel covers `p`.
fn atlas_lookup(p: vec2f, bicubic: bool) -> vec3f {
    let centre = cssm_texel_at(p);
    if centre == CSSM_NONE {
        return vec3f(0.0);
    }
    if !bicubic {
        return atlas_values[centre].rgb;
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
            sum += w * atlas_values[cell].rgb;
            total += w;
        }
    }
    if total <= 0.0 {
        return atlas_values[centre].rgb;
    }
    return sum / total;
}
