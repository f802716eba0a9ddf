// RSM sampling with micro-linear-buffer visibility (Bang 2011 §3.2, §3.3, Algorithms 5 and 6),
// one invocation per pixel of the reduced-resolution image. CPU twin: rsm/cpu.rs (`gather`),
// the same pattern, visibility and arithmetic.
//
// Output, two planes of the filter's input: rgb diffuse irradiance (plane 0) and rgb
// irradiance weighted by the receiver's normalised Phong lobe without Ks (plane 1), so the
// resolve pass reflects them with the full-resolution albedo and Ks after filtering.

#import cssm::types::{Material, SpotLight, View}
#import cssm::lowres::lowres_representative
#import cssm::random::hash_unit

struct SamplingParams {
    paths: u32,
    path_samples: u32,
    slots: u32,
    // 1: the micro linear buffer (§3.3); 0: every sample visible (the original RSM).
    visibility: u32,
    radius: f32,
    factor: u32,
    low_width: u32,
    low_height: u32,
}

@group(0) @binding(0) var<uniform> params: SamplingParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var<storage, read> lights: array<SpotLight>;
@group(0) @binding(3) var<storage, read> materials: array<Material>;
@group(0) @binding(4) var gb_position: texture_2d<f32>;
@group(0) @binding(5) var gb_normal: texture_2d<f32>;
@group(0) @binding(6) var rsm_position: texture_2d_array<f32>;
@group(0) @binding(7) var rsm_normal: texture_2d_array<f32>;
@group(0) @binding(8) var rsm_flux: texture_2d_array<f32>;
@group(0) @binding(9) var<storage, read_write> planes: array<vec4f>;

const PI: f32 = 3.14159265358979;
const TAU: f32 = 6.28318530717959;
// Most slots of the micro linear buffer (`rsm::MAX_SLOTS`).
const MAX_SLOTS: u32 = 16u;

// Chris Wellons' lowbias32 (`cpu::hash`).
fn hash(v: u32) -> u32 {
    var x = v;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return x;
}

// §3.3: the slot of an elevation angle in [-pi/2, pi/2] (`rsm::slot_of`).
fn slot_of(elevation: f32, slots: u32) -> u32 {
    let at = floor((elevation / PI + 0.5) * f32(slots));
    return u32(clamp(at, 0.0, f32(slots - 1u)));
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= params.low_width || id.y >= params.low_height {
        return;
    }
    let low_pixels = params.low_width * params.low_height;
    let out_index = id.y * params.low_width + id.x;
    let pixel = lowres_representative(id.xy, params.factor, view.size);
    let g = textureLoad(gb_position, vec2i(pixel), 0);
    var diffuse = vec3f(0.0);
    var glossy = vec3f(0.0);
    if g.w > 0.0 {
        let x = g.xyz;
        let gn = textureLoad(gb_normal, vec2i(pixel), 0);
        let n = gn.xyz;
        let ns = materials[u32(gn.w)].ns;
        let v = normalize(view.eye - x);
        // §3.2: one base pattern for every pixel, slightly rotated and scaled per pixel.
        let key = pixel.x + pixel.y * 65536u;
        let rotation = hash_unit(hash(key ^ 0x1b873593u));
        let scale = 0.9 + 0.2 * hash_unit(hash(key ^ 0x5bd1e995u));
        let sector = TAU / f32(params.paths);
        let radius = params.radius * scale;
        let samples = f32(params.path_samples);
        for (var li = 0u; li < view.light_count; li++) {
            let light = lights[li];
            // The receiver's projection into the RSM, the paths' origin: for a receiver the
            // map does not see (beside or behind the light), the nearest point of the map, or
            // its centre (our extension: the thesis' receivers all lie in the light's view).
            let clip = light.view_proj * vec4f(x, 1.0);
            var projection = vec2f(0.5);
            if clip.w > 0.0 {
                let ndc = clip.xy / clip.w;
                projection = clamp(vec2f(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5), vec2f(0.0), vec2f(1.0));
            }
            let side = light.shadow_resolution;
            for (var j = 0u; j < params.paths; j++) {
                // Algorithm 6: the micro linear buffer, reset for every path.
                var slots: array<f32, MAX_SLOTS>;
                for (var s = 0u; s < MAX_SLOTS; s++) {
                    slots[s] = 1.0;
                }
                var last_slot = MAX_SLOTS;
                var last_visible = 1.0;
                for (var k = 0u; k < params.path_samples; k++) {
                    // Algorithm 5, lines 4-8: jittered angle and radius along the path.
                    let jkey = j * 1024u + k;
                    let jitter_angle = hash_unit(hash(jkey)) - 0.5;
                    let jitter_radius = hash_unit(hash(jkey ^ 0x68e31da4u));
                    let theta = sector * (rotation + f32(j) + 0.5 + 0.5 * jitter_angle);
                    let u = (f32(k) + jitter_radius) / samples;
                    let rho = radius * u * u;
                    let at = projection + rho * vec2f(cos(theta), sin(theta));
                    if at.x < 0.0 || at.y < 0.0 || at.x >= 1.0 || at.y >= 1.0 {
                        continue;
                    }
                    let texel = vec2i(floor(at * side));
                    let p = textureLoad(rsm_position, texel, li, 0);
                    if p.w <= 0.0 {
                        continue;
                    }
                    let sender = p.xyz;
                    let d = sender - x;
                    let d2 = dot(d, d);
                    if d2 <= 0.0 {
                        continue;
                    }
                    var visible = 1.0;
                    if params.visibility != 0u {
                        // §3.3: the elevation in the light's view, the xy-plane horizontal.
                        let dz = dot(d, light.direction);
                        let lateral = length(d - dz * light.direction);
                        let slot = slot_of(atan2(-dz, lateral), params.slots);
                        if slot == last_slot {
                            visible = last_visible;
                        } else {
                            visible = slots[slot];
                            slots[slot] -= 1.0;
                        }
                        last_slot = slot;
                        last_visible = visible;
                        visible = clamp(visible, 0.0, 1.0);
                    }
                    // Eq. 3.2, with the sender's texel area in the denominator (a disc's form
                    // factor) so that senders next to the receiver stay bounded.
                    let n_p = textureLoad(rsm_normal, texel, li, 0).xyz;
                    let cos_product = max(dot(n_p, -d), 0.0) * max(dot(n, d), 0.0) / d2;
                    let to_sender = sender - light.position;
                    let light_d2 = dot(to_sender, to_sender);
                    let light_d = sqrt(light_d2);
                    let cos_axis = dot(to_sender, light.direction) / light_d;
                    let cos_light = max(abs(dot(n_p, -to_sender) / light_d), 0.05);
                    let area = light.texel_solid_angle * cos_axis * cos_axis * cos_axis
                        * light_d2 / cos_light;
                    let phi = textureLoad(rsm_flux, texel, li, 0).rgb;
                    let irradiance = phi / PI * cos_product / (d2 + area / PI);
                    let weight = 2.0 * sector * radius * radius * u * u * u / samples
                        * side * side;
                    let e = (visible * weight) * irradiance;
                    diffuse += e;
                    let l = d / sqrt(d2);
                    let mirrored = reflect(-l, n);
                    glossy += e * ((ns + 2.0) / TAU * pow(max(dot(mirrored, v), 0.0), ns));
                }
            }
        }
    }
    planes[out_index] = vec4f(diffuse, 0.0);
    planes[low_pixels + out_index] = vec4f(glossy, 0.0);
}
