#import cssm::types::View

// Tone mapping: exposure, the ACES filmic curve (Narkowicz 2015 fit) per channel, sRGB encoding,
// drawn as one triangle over the caller's target. Its CPU twin is common::tonemap::tonemap.
@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var hdr: texture_2d<f32>;

// 1: the shader encodes sRGB (a UNORM target); 0: the target's format does (an *Srgb target).
override ENCODE_SRGB: f32 = 1.0;

fn aces(x: vec3f) -> vec3f {
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), vec3f(0.0), vec3f(1.0));
}

fn srgb_encode(c: vec3f) -> vec3f {
    return select(1.055 * pow(c, vec3f(1.0 / 2.4)) - 0.055, c * 12.92, c <= vec3f(0.0031308));
}

// A triangle covering the target: clip-space corners (-1,-1), (3,-1), (-1,3).
@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4f {
    let xy = vec2f(f32((i << 1u) & 2u), f32(i & 2u)) * 2.0 - 1.0;
    return vec4f(xy, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) frag: vec4f) -> @location(0) vec4f {
    let radiance = textureLoad(hdr, vec2i(frag.xy), 0).rgb;
    let mapped = aces(max(radiance, vec3f(0.0)) * view.exposure);
    return vec4f(select(mapped, srgb_encode(mapped), ENCODE_SRGB > 0.5), 1.0);
}
