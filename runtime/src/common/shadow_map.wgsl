// Depth-only raster of the scene from a spot light (§4.7: direct light from spot lights with
// shadow maps).

struct LightTransform {
    view_proj: mat4x4f,
}

@group(0) @binding(0) var<uniform> light: LightTransform;

@vertex
fn vs_main(@location(0) position: vec3f) -> @builtin(position) vec4f {
    return light.view_proj * vec4f(position, 1.0);
}
