#import cssm::types::View
#import cssm::atlas_filter::atlas_lookup

// Indirect light from the atlas per pixel: the radiosity iteration's indirect irradiance per
// texel (`atlas_values`, binding 15), looked up at the pixel's atlas coordinates and reflected
// with the pixel's albedo. Mode 0: the texel under the pixel (the "direct visualisation" of the
// radiosity solution, §4.4); mode 1: the bicubic B-spline of `bicubic.wgsl` (§5, Fig. 17). CPU
// twin: lightmap/mod.rs::lookup. Needs types.wgsl and the CSSM library at group 1.

struct LookupParams {
    mode: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: LookupParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(3) var gbuffer_position: texture_2d<f32>;
@group(0) @binding(4) var gbuffer_albedo: texture_2d<f32>;
@group(0) @binding(5) var gbuffer_atlas: texture_2d<f32>;
@group(0) @binding(6) var<storage, read_write> indirect: array<vec4f>;

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
        let e = atlas_lookup(textureLoad(gbuffer_atlas, xy, 0).xy, params.mode == 1u);
        value = vec4f(albedo / 3.14159265358979 * e, 0.0);
    }
    indirect[pixel] = value;
}
