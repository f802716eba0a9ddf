#import cssm::light::{view, spot_irradiance}

// The light every pixel sends to the others in the first bounce (Soler et al. 2010 §3, L in
// Eq. 3): its diffuse direct radiance albedo / pi * E, plus the radiance it emits (the
// G-buffer's emission: an emitter seen from its front emits the same towards every direction
// of that side, so it sends what the eye sees; seen from its back it sends nothing). The
// gather's senders are diffuse (§5.3: "a diffuse approximation of this light"), so a glossy
// highlight towards the eye is not sent on to the walls. Twin: ssil/cpu.rs::sender_radiance.

@group(0) @binding(5) var gb_position: texture_2d<f32>;
@group(0) @binding(6) var gb_normal: texture_2d<f32>;
@group(0) @binding(7) var gb_albedo: texture_2d<f32>;
@group(0) @binding(8) var<storage, read_write> sender: array<vec4f>;
@group(0) @binding(9) var gb_emission: texture_2d<f32>;

const PI: f32 = 3.14159265358979;

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= view.size.x || id.y >= view.size.y {
        return;
    }
    let at = vec2i(id.xy);
    let position = textureLoad(gb_position, at, 0);
    var radiance = vec3f(0.0);
    if position.w > 0.0 {
        let n = textureLoad(gb_normal, at, 0).xyz;
        var e = vec3f(0.0);
        for (var i = 0u; i < view.light_count; i++) {
            e += spot_irradiance(i, position.xyz, n).rgb;
        }
        radiance = textureLoad(gb_albedo, at, 0).rgb / PI * e + textureLoad(gb_emission, at, 0).rgb;
    }
    sender[id.y * view.size.x + id.x] = vec4f(radiance, 0.0);
}
