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
