#define_import_path cssm::posed

#import cssm::types::Texel

// A rigid object's atlas texels move with it (§3.3): texel `t`, baked where its object was
// loaded, lies now where the object's motion since loading puts it. The motion is
// `SceneGpu::motion` (`Renderer::set_object_transform` writes it; the raster passes draw the
// object with the same matrices), bound as binding 5 of the moving objects' group. Composed
// per scene: without moving objects (`MOVING_CSMS` 0) the texels stay where they were baked
// and the pass reads no motion. CPU twin: cssm_formats::moving::posed_texel.

#if MOVING_CSMS > 0
@group(#{MOVING_GROUP}) @binding(5) var<storage, read> texel_motion: array<mat4x4f>;

// moving::posed_texel: position and normal carried, area scaled by the square of the motion's
// uniform scale (|det|^(2/3)).
fn posed_texel(t: Texel) -> Texel {
    let m = texel_motion[t.object];
    var posed = t;
    posed.position = (m * vec4f(t.position, 1.0)).xyz;
    let n = (m * vec4f(t.normal, 0.0)).xyz;
    if dot(n, n) > 0.0 {
        posed.normal = normalize(n);
    }
    let linear = mat3x3f(m[0].xyz, m[1].xyz, m[2].xyz);
    posed.area = t.area * pow(abs(determinant(linear)), 2.0 / 3.0);
    return posed;
}
#else
fn posed_texel(t: Texel) -> Texel {
    return t;
}
#endif
