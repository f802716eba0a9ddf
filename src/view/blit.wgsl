// `cssm view`: copies the renderer's offscreen image (Rgba8Unorm holding the tone mapping's
// sRGB-encoded bytes, the bytes `cssm render` writes) onto the window's surface, stretched to
// the window. One fullscreen triangle, no vertex buffer.

@group(0) @binding(0) var image: texture_2d<f32>;
@group(0) @binding(1) var image_sampler: sampler;

struct VertexOut {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

@vertex
fn vs_main(@builtin(vertex_index) index: u32) -> VertexOut {
    // (0,0), (2,0), (0,2): a triangle that covers the whole clip rectangle.
    let uv = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    var out: VertexOut;
    out.position = vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, 0.0, 1.0);
    out.uv = uv;
    return out;
}

// A surface of a plain (non-sRGB) format: the bytes go through as they are.
@fragment
fn fs_unorm(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(textureSample(image, image_sampler, in.uv).rgb, 1.0);
}

fn srgb_decode(c: vec3<f32>) -> vec3<f32> {
    return select(pow((c + 0.055) / 1.055, vec3<f32>(2.4)), c / 12.92, c <= vec3<f32>(0.04045));
}

// An sRGB surface encodes what it is given: decode first, so the screen shows the same bytes.
@fragment
fn fs_srgb(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(srgb_decode(textureSample(image, image_sampler, in.uv).rgb), 1.0);
}
