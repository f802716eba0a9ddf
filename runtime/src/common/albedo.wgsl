#define_import_path cssm::albedo

// Bilinear sample of an albedo texture layer with repeat wrapping, done by hand with
// textureLoad so that float textures need no filtering feature and the CPU reference
// (load::AlbedoTexture::sample) computes the same.
fn albedo_sample(textures: texture_2d_array<f32>, layer: u32, uv: vec2f) -> vec3f {
    let size = vec2i(textureDimensions(textures));
    let x = uv.x * f32(size.x) - 0.5;
    let y = (1.0 - uv.y) * f32(size.y) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let ix = i32(x0);
    let iy = i32(y0);
    let c00 = albedo_texel(textures, ix, iy, layer, size);
    let c10 = albedo_texel(textures, ix + 1, iy, layer, size);
    let c01 = albedo_texel(textures, ix, iy + 1, layer, size);
    let c11 = albedo_texel(textures, ix + 1, iy + 1, layer, size);
    return c00 * (1.0 - fx) * (1.0 - fy) + c10 * fx * (1.0 - fy) + c01 * (1.0 - fx) * fy
        + c11 * fx * fy;
}

fn albedo_texel(textures: texture_2d_array<f32>, x: i32, y: i32, layer: u32, size: vec2i) -> vec3f {
    let wx = ((x % size.x) + size.x) % size.x;
    let wy = ((y % size.y) + size.y) % size.y;
    return textureLoad(textures, vec2i(wx, wy), i32(layer), 0).rgb;
}

// The least cosine between the shading and the geometric normal (normal_map::MIN_SHADING_COS).
const MIN_SHADING_COS: f32 = 0.05;

// The shading normal tilted by a normal-map sample `s` (a bilinear albedo_sample of a layer of
// unit tangent-space normals) in the flat frame (t, b, n) of a surface, n its unit geometric
// normal turned towards the eye and t, b turned with it; kept MIN_SHADING_COS above the surface
// so no pixel shades from below it. The CSSM paper's Fig. 1 (right): high-frequency detail in
// the direct light and the final gather. Twin: normal_map::perturb (the same operations).
fn perturb_normal(s: vec3f, n: vec3f, t: vec3f, b: vec3f) -> vec3f {
    let p = t * s.x + b * s.y + n * s.z;
    let len = length(p);
    if !(len > 1e-12) {
        return n;
    }
    let q = p / len;
    let d = dot(q, n);
    if d >= MIN_SHADING_COS {
        return q;
    }
    let along = q - n * d;
    let along_len = length(along);
    if !(along_len > 1e-12) {
        return n;
    }
    return n * MIN_SHADING_COS + along / along_len * sqrt(1.0 - MIN_SHADING_COS * MIN_SHADING_COS);
}
