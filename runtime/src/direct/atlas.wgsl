// Direct light into the atlas texels: the diffuse radiance each texel sends out (Kd/pi times
// its irradiance), the source of the indirect bounces. Front side only: the texel's normal is
// the side its cube map looks into.
@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> materials: array<Material>;
@group(0) @binding(2) var<storage, read> lights: array<SpotLight>;
@group(0) @binding(3) var shadow_maps: texture_depth_2d_array;
@group(0) @binding(4) var shadow_sampler: sampler_comparison;
@group(0) @binding(5) var<storage, read> texels: array<Texel>;
@group(0) @binding(6) var<storage, read_write> texel_radiance: array<vec4f>;

@compute @workgroup_size(WORKGROUP_1D)
fn main(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x;
    if i >= min(arrayLength(&texels), arrayLength(&texel_radiance)) {
        return;
    }
    let t = texels[i];
    var e = vec3f(0.0);
    for (var k = 0u; k < view.light_count; k++) {
        e += spot_irradiance(k, t.position, t.normal).rgb;
    }
    texel_radiance[i] = vec4f(materials[t.material].kd / PI * e, 1.0);
}
