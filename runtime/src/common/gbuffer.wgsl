#import cssm::types::{Material, View}
#import cssm::albedo::{albedo_sample, perturb_normal}

// G-buffer raster pass: world position, camera-facing shading normal, material, albedo, atlas
// coordinates and the emitted radiance towards the eye per pixel, sampled at pixel centres (the
// rays of the CPU references). The shading normal is the flat geometric one tilted by the
// material's normal map in the triangle's flat tangent frame (normal_map.rs; CPU twin
// direct/cpu.rs::shading_normal). Emission is one-sided: a surface emits from its front, the side
// its winding normal faces (direct/cpu.rs::emitted_radiance is the twin).
// Needs types.wgsl (View, Material) and albedo.wgsl.

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> materials: array<Material>;
@group(0) @binding(2) var albedo_textures: texture_2d_array<f32>;
// Per object, its motion since loading (rigid: rotation, uniform scale, translation).
@group(0) @binding(3) var<storage, read> object_motion: array<mat4x4f>;

struct VertexIn {
    @location(0) position: vec3f,
    @location(1) normal: vec3f,
    @location(2) uv: vec2f,
    @location(3) atlas_uv: vec2f,
    @location(4) material: u32,
    @location(5) triangle: u32,
    @location(6) object: u32,
    @location(7) tangent: vec4f,
}

struct VertexOut {
    @builtin(position) clip: vec4f,
    @location(0) position: vec3f,
    @location(1) @interpolate(flat) normal: vec3f,
    @location(2) uv: vec2f,
    @location(3) atlas_uv: vec2f,
    @location(4) @interpolate(flat) material: u32,
    @location(5) @interpolate(flat) triangle: u32,
    // xyz: unit tangent of the triangle's UVs (moved with it), w: handedness, 0 for none.
    @location(6) @interpolate(flat) tangent: vec4f,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let motion = object_motion[v.object];
    let position = (motion * vec4f(v.position, 1.0)).xyz;
    var out: VertexOut;
    out.clip = view.view_proj * vec4f(position, 1.0);
    out.position = position;
    out.normal = normalize((motion * vec4f(v.normal, 0.0)).xyz);
    out.uv = v.uv;
    out.atlas_uv = v.atlas_uv;
    out.material = v.material;
    out.triangle = v.triangle;
    out.tangent = vec4f(0.0);
    if v.tangent.w != 0.0 {
        out.tangent = vec4f(normalize((motion * vec4f(v.tangent.xyz, 0.0)).xyz), v.tangent.w);
    }
    return out;
}

struct GBufferOut {
    // xyz: world position; w: 1 where a surface covers the pixel.
    @location(0) position: vec4f,
    // xyz: unit shading normal turned towards the eye (normal-mapped); w: material index.
    @location(1) normal: vec4f,
    // rgb: Lambertian albedo (Kd times the texture); w: triangle index.
    @location(2) albedo: vec4f,
    // xy: atlas coordinates in texels (an Rg32Float target).
    @location(3) atlas: vec4f,
    // rgb: radiance emitted towards the eye (zero on a back side); a: 1 where the eye sees the
    // front side, 0 the back (an Rgba16Float target).
    @location(4) emission: vec4f,
}

@fragment
fn fs_main(f: VertexOut) -> GBufferOut {
    var n = f.normal;
    let front = dot(n, view.eye - f.position) >= 0.0;
    if !front {
        n = -n;
    }
    let m = materials[f.material];
    // The frame turns with the normal: seen from the back, the perturbed normal is the front's
    // negated. Emission's side stays the geometric one's (`front`).
    if m.normal_texture >= 0 && f.tangent.w != 0.0 {
        let side = select(-1.0, 1.0, front);
        let t = f.tangent.xyz * side;
        let b = cross(f.normal, f.tangent.xyz) * (f.tangent.w * side);
        let s = albedo_sample(albedo_textures, u32(m.normal_texture), f.uv);
        n = perturb_normal(s, n, t, b);
    }
    var albedo = m.kd;
    if m.texture >= 0 {
        albedo *= albedo_sample(albedo_textures, u32(m.texture), f.uv);
    }
    var emission = vec3f(0.0);
    if front {
        emission = m.emission;
        if m.emission_texture >= 0 && any(emission > vec3f(0.0)) {
            emission *= albedo_sample(albedo_textures, u32(m.emission_texture), f.uv);
        }
    }
    var out: GBufferOut;
    out.position = vec4f(f.position, 1.0);
    out.normal = vec4f(n, f32(f.material));
    out.albedo = vec4f(albedo, f32(f.triangle));
    out.atlas = vec4f(f.atlas_uv, 0.0, 0.0);
    out.emission = vec4f(emission, select(0.0, 1.0, front));
    return out;
}
