#import cssm::light::{view, materials, direct_radiance}

// Direct light per pixel from the G-buffer into linear radiance: the spot lights' light
// reflected once, plus the radiance the surface emits towards the eye (the G-buffer's emission,
// zero where the eye sees a back side). Twin: direct/cpu.rs::render_screen.
@group(0) @binding(5) var gb_position: texture_2d<f32>;
@group(0) @binding(6) var gb_normal: texture_2d<f32>;
@group(0) @binding(7) var gb_albedo: texture_2d<f32>;
@group(0) @binding(8) var radiance_out: texture_storage_2d<rgba32float, write>;
@group(0) @binding(9) var gb_emission: texture_2d<f32>;

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= view.size.x || id.y >= view.size.y {
        return;
    }
    let at = vec2i(id.xy);
    let position = textureLoad(gb_position, at, 0);
    var radiance = vec3f(0.0);
    if position.w > 0.0 {
        let normal = textureLoad(gb_normal, at, 0);
        let albedo = textureLoad(gb_albedo, at, 0).rgb;
        let m = materials[u32(normal.w)];
        let v = normalize(view.eye - position.xyz);
        radiance = direct_radiance(view.light_count, position.xyz, normal.xyz, v, albedo, m);
        radiance += textureLoad(gb_emission, at, 0).rgb;
    }
    textureStore(radiance_out, at, vec4f(radiance, 1.0));
}
