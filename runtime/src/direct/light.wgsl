#define_import_path cssm::light

// Direct light from spot lights (§4.7), shared by the screen and the atlas passes. Needs
// types.wgsl, shadow_lookup.wgsl and the bindings `lights: array<SpotLight>`.
// Conventions (docs/architecture.md): constant radiant intensity inside the cone, zero outside;
// BRDF Kd/pi + Ks (Ns+2)/(2 pi) cos^Ns of the angle between the mirrored light direction and
// the view direction (normalised Phong).

#import cssm::types::{Material, SpotLight, View}
#import cssm::shadow_lookup::shadow_visibility

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> materials: array<Material>;
@group(0) @binding(2) var<storage, read> lights: array<SpotLight>;

const PI: f32 = 3.14159265358979;

// Irradiance at `p` (normal `n`) from light `i`, shadowed, and the unit direction to the light.
// What a texel reflects of the light it receives in the view-independent bounces (the atlas,
// §4.1): Kd times its texture's mean (kd_mean; the atlas samples no textures), plus Ks as a diffuse stand-in for the glossy lobe, whose normalised Phong
// reflects Ks of light arriving along the normal. The paper's bounces are diffuse only and lose
// the glossy part (a glossy floor's Ks never reaches the walls: reports/final-gather.md).
// Twin: direct/cpu.rs::bounce_albedo.
fn bounce_albedo(m: Material) -> vec3f {
    return min(m.kd_mean + m.ks, vec3f(1.0));
}

fn spot_irradiance(i: u32, p: vec3f, n: vec3f) -> vec4f {
    let light = lights[i];
    let to_light = light.position - p;
    let dist2 = dot(to_light, to_light);
    let l = to_light / sqrt(dist2);
    let cos_i = dot(n, l);
    if cos_i <= 0.0 || dot(-l, light.direction) < light.cos_cutoff {
        return vec4f(0.0);
    }
    let visible = shadow_visibility(light, i, p, n);
    return vec4f(light.intensity * (cos_i / dist2 * visible), 0.0);
}

fn direction_to_light(i: u32, p: vec3f) -> vec3f {
    return normalize(lights[i].position - p);
}

// Radiance leaving `p` towards the unit direction `v` under every light.
fn direct_radiance(light_count: u32, p: vec3f, n: vec3f, v: vec3f, albedo: vec3f, m: Material) -> vec3f {
    var total = vec3f(0.0);
    for (var i = 0u; i < light_count; i++) {
        let e = spot_irradiance(i, p, n).rgb;
        if all(e == vec3f(0.0)) {
            continue;
        }
        let l = direction_to_light(i, p);
        let r = reflect(-l, n);
        let lobe = m.ks * ((m.ns + 2.0) / (2.0 * PI) * pow(max(dot(r, v), 0.0), m.ns));
        total += (albedo / PI + lobe) * e;
    }
    return total;
}
