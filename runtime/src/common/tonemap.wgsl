// Tone mapping: exposure, the ACES filmic curve (Narkowicz 2015 fit) per channel, sRGB encoding.
// Its CPU twin is common::tonemap::tonemap.
@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var hdr: texture_2d<f32>;
@group(0) @binding(2) var ldr: texture_storage_2d<rgba8unorm, write>;

fn aces(x: vec3f) -> vec3f {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), vec3f(0.0), vec3f(1.0));
}

fn srgb_encode(c: vec3f) -> vec3f {
    return select(1.055 * pow(c, vec3f(1.0 / 2.4)) - 0.055, c * 12.92, c <= vec3f(0.0031308));
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= view.size.x || id.y >= view.size.y {
        return;
    }
    let radiance = textureLoad(hdr, vec2i(id.xy), 0).rgb;
    textureStore(ldr, vec2i(id.xy), vec4f(srgb_encode(aces(max(radiance, vec3f(0.0)) * view.exposure)), 1.0));
}
