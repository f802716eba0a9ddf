#import cssm::types::{Material, View}

// Temporal filtering (Soler et al. 2010 §4, Eq. 6): F_i = a W(F_{i-1}) + (1 - a) I_i on both
// planes of the up-sampled indirect light. W reprojects: the pixel's world point is projected
// with the previous frame's camera, and the history there is used only when the previous
// frame's G-buffer holds the same surface (position within 2% of the distance to the eye,
// normals within 25 degrees). `a` is adapted to the glossiness (§5.3): the diffuse plane
// blends with `blend`; the lobe-weighted plane with `blend` times
// max(0, 1 - angle / lobe), the angle between the directions from the point to the previous
// and the current eye against the Phong lobe's half-power angle, so that a glossy reflection
// follows a moving camera without ghosting and converges while the camera rests.
// Twin: ssil/cpu.rs::temporal_pixel.

struct TemporalParams {
    previous_view_proj: mat4x4f,
    previous_eye: vec3f,
    blend: f32,
    // 1 when the history holds a previous frame of this size.
    history: u32,
    padding_a: u32,
    padding_b: u32,
    padding_c: u32,
}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<uniform> temporal: TemporalParams;
@group(0) @binding(2) var<storage, read> materials: array<Material>;
@group(0) @binding(3) var gb_position: texture_2d<f32>;
@group(0) @binding(4) var gb_normal: texture_2d<f32>;
@group(0) @binding(5) var history_position: texture_2d<f32>;
@group(0) @binding(6) var history_normal: texture_2d<f32>;
@group(0) @binding(7) var<storage, read> current: array<vec4f>;
@group(0) @binding(8) var<storage, read> history: array<vec4f>;
@group(0) @binding(9) var<storage, read_write> blended: array<vec4f>;

const PI: f32 = 3.14159265358979;

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    let size = view.size;
    if id.x >= size.x || id.y >= size.y {
        return;
    }
    let plane = size.x * size.y;
    let i = id.y * size.x + id.x;
    var diffuse = current[i];
    var glossy = current[plane + i];
    let p = textureLoad(gb_position, vec2i(id.xy), 0);
    if temporal.history == 1u && p.w > 0.0 {
        let clip = temporal.previous_view_proj * vec4f(p.xyz, 1.0);
        if clip.w > 0.0 {
            let ndc = clip.xy / clip.w;
            let at = vec2i(floor(vec2f(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5) * vec2f(size)));
            if at.x >= 0 && at.y >= 0 && at.x < i32(size.x) && at.y < i32(size.y) {
                let hp = textureLoad(history_position, at, 0);
                let n4 = textureLoad(gb_normal, vec2i(id.xy), 0);
                let hn = textureLoad(history_normal, at, 0).xyz;
                let tolerance = 0.02 * distance(view.eye, p.xyz);
                if hp.w > 0.0 && distance(hp.xyz, p.xyz) <= tolerance && dot(hn, n4.xyz) >= 0.9 {
                    let h = u32(at.y) * size.x + u32(at.x);
                    let a = temporal.blend;
                    diffuse = mix(diffuse, history[h], a);
                    let m = materials[u32(n4.w)];
                    let now = normalize(view.eye - p.xyz);
                    let before = normalize(temporal.previous_eye - p.xyz);
                    let angle = acos(clamp(dot(now, before), -1.0, 1.0));
                    let lobe = acos(pow(0.5, 1.0 / max(m.ns, 1e-3)));
                    let a_glossy = a * max(0.0, 1.0 - angle / max(lobe, 1e-4));
                    glossy = mix(glossy, history[plane + h], a_glossy);
                }
            }
        }
    }
    blended[i] = diffuse;
    blended[plane + i] = glossy;
}
