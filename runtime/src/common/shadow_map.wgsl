// Depth-only raster of the scene from a spot light (§4.7: direct light from spot lights with
// shadow maps).

struct LightTransform {
    view_proj: mat4x4f,
}

@group(0) @binding(0) var<uniform> light: LightTransform;
// Per object, its motion since loading (as in the G-buffer pass).
@group(0) @binding(1) var<storage, read> object_motion: array<mat4x4f>;

@vertex
fn vs_main(@location(0) position: vec3f, @location(6) object: u32) -> @builtin(position) vec4f {
    return light.view_proj * object_motion[object] * vec4f(position, 1.0);
}
