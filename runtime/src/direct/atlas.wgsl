#import cssm::types::Texel
#import cssm::light::{view, materials, spot_irradiance, bounce_albedo, PI}
#import cssm::posed::posed_texel

// Direct light into the atlas texels: the radiance each texel sends out (its bounce albedo
// over pi times its irradiance, plus what its material emits: §4.7, any direct light may be the radiosity's
// source), the source of the indirect bounces. Front side only: the texel's normal is the side
// its cube map looks into, the winding's, the side that emits. A texel of a moving object is lit
// where the object stands now (posed.wgsl, §3.3; the moving objects' group at MOVING_GROUP).
// Twin: direct/cpu.rs::render_atlas.
@group(0) @binding(5) var<storage, read> texels: array<Texel>;
@group(0) @binding(6) var<storage, read_write> texel_radiance: array<vec4f>;

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x;
    if i >= min(arrayLength(&texels), arrayLength(&texel_radiance)) {
        return;
    }
    let t = posed_texel(texels[i]);
    var e = vec3f(0.0);
    for (var k = 0u; k < view.light_count; k++) {
        e += spot_irradiance(k, t.position, t.normal).rgb;
    }
    let m = materials[t.material];
    texel_radiance[i] = vec4f(bounce_albedo(m) / PI * e + m.emission_mean, 1.0);
}
