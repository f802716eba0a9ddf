#define_import_path cssm::shadow_lookup

// Spot-light shadow test with percentage-closer filtering: 3x3 hardware-filtered comparisons
// (each a bilinear blend of 2x2 texels), after a normal offset that keeps surfaces from
// shadowing themselves. Needs types.wgsl (SpotLight) and these two bindings in the includer:
//   shadow_maps: texture_depth_2d_array, shadow_sampler: sampler_comparison.

#import cssm::types::SpotLight

@group(0) @binding(3) var shadow_maps: texture_depth_2d_array;
@group(0) @binding(4) var shadow_sampler: sampler_comparison;

fn shadow_visibility(light: SpotLight, layer: u32, p: vec3f, n: vec3f) -> f32 {
    let lifted = p + n * (light.normal_offset * distance(light.position, p));
    let clip = light.view_proj * vec4f(lifted, 1.0);
    if clip.w <= 0.0 {
        return 0.0;
    }
    let ndc = clip.xyz / clip.w;
    let uv = vec2f(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    if any(uv < vec2f(0.0)) || any(uv > vec2f(1.0)) || ndc.z > 1.0 {
        return 0.0;
    }
    let step = 1.0 / light.shadow_resolution;
    var sum = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            let at = uv + vec2f(f32(dx), f32(dy)) * step;
            sum += textureSampleCompareLevel(shadow_maps, shadow_sampler, at, layer, ndc.z);
        }
    }
    return sum / 9.0;
}
