// Raster of the scene from a spot light (§4.7: direct light from spot lights with shadow maps).
// Depth only (`vs_main`), or depth and the reflective shadow map (`vs_rsm`, `fs_rsm`; Bang 2011
// §3.1, §4.2, after Dachsbacher and Stamminger 2005): per texel the world position, the normal
// turned towards the light and the flux its surface reflects. One raster, so the shadow lookup
// and the RSM see the same surfaces.

#import cssm::types::{Material, SpotLight}
#import cssm::albedo::albedo_sample

struct LightTransform {
    view_proj: mat4x4f,
    // The light's index (its layer of the maps).
    layer: u32,
    padding_a: u32,
    padding_b: u32,
    padding_c: u32,
}

@group(0) @binding(0) var<uniform> light: LightTransform;
// Per object, its motion since loading (as in the G-buffer pass).
@group(0) @binding(1) var<storage, read> object_motion: array<mat4x4f>;

@vertex
fn vs_main(@location(0) position: vec3f, @location(6) object: u32) -> @builtin(position) vec4f {
    return light.view_proj * object_motion[object] * vec4f(position, 1.0);
}

@group(1) @binding(0) var<storage, read> materials: array<Material>;
@group(1) @binding(1) var albedo_textures: texture_2d_array<f32>;
@group(1) @binding(2) var<storage, read> lights: array<SpotLight>;

struct RsmVertexIn {
    @location(0) position: vec3f,
    @location(1) normal: vec3f,
    @location(2) uv: vec2f,
    @location(4) material: u32,
    @location(6) object: u32,
}

struct RsmVertex {
    @builtin(position) clip: vec4f,
    @location(0) position: vec3f,
    @location(1) @interpolate(flat) normal: vec3f,
    @location(2) uv: vec2f,
    @location(3) @interpolate(flat) material: u32,
}

@vertex
fn vs_rsm(v: RsmVertexIn) -> RsmVertex {
    let motion = object_motion[v.object];
    let position = (motion * vec4f(v.position, 1.0)).xyz;
    var out: RsmVertex;
    out.clip = light.view_proj * vec4f(position, 1.0);
    out.position = position;
    out.normal = normalize((motion * vec4f(v.normal, 0.0)).xyz);
    out.uv = v.uv;
    out.material = v.material;
    return out;
}

struct RsmOut {
    // xyz: world position; w: 1 where a surface covers the texel.
    @location(0) position: vec4f,
    // xyz: unit normal turned towards the light.
    @location(1) normal: vec4f,
    // rgb: reflected flux, W.
    @location(2) flux: vec4f,
}

@fragment
fn fs_rsm(f: RsmVertex) -> RsmOut {
    let l = lights[light.layer];
    let from_light = f.position - l.position;
    let dir = normalize(from_light);
    var n = f.normal;
    if dot(n, dir) > 0.0 {
        n = -n;
    }
    let m = materials[f.material];
    var albedo = m.kd;
    if m.texture >= 0 {
        albedo *= albedo_sample(albedo_textures, u32(m.texture), f.uv);
    }
    // The texel's solid angle times the intensity is the flux it receives, whatever the
    // surface's slope (the slope spreads it over a larger patch); the diffuse part leaves.
    let cos_axis = dot(dir, l.direction);
    var flux = vec3f(0.0);
    if cos_axis >= l.cos_cutoff {
        flux = albedo * l.intensity * (l.texel_solid_angle * cos_axis * cos_axis * cos_axis);
    }
    var out: RsmOut;
    out.position = vec4f(f.position, 1.0);
    out.normal = vec4f(n, 0.0);
    out.flux = vec4f(flux, 0.0);
    return out;
}
