// Two planes of gathered light reflected towards the eye at full resolution (common/resolve.rs,
// shared by rsm and ssil): the diffuse irradiance with the pixel's albedo over pi, the
// lobe-weighted irradiance (each sample's irradiance times the pixel's normalised Phong lobe
// towards the eye) with its Ks.

#import cssm::types::{Material, View}

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> materials: array<Material>;
@group(0) @binding(2) var gb_normal: texture_2d<f32>;
@group(0) @binding(3) var gb_albedo: texture_2d<f32>;
@group(0) @binding(4) var<storage, read> planes: array<vec4f>;
@group(0) @binding(5) var<storage, read_write> indirect: array<vec4f>;

const PI: f32 = 3.14159265358979;

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= view.size.x || id.y >= view.size.y {
        return;
    }
    let index = id.y * view.size.x + id.x;
    let pixels = view.size.x * view.size.y;
    let at = vec2i(id.xy);
    let albedo = textureLoad(gb_albedo, at, 0).rgb;
    let material = materials[u32(textureLoad(gb_normal, at, 0).w)];
    let radiance = albedo / PI * planes[index].rgb + material.ks * planes[pixels + index].rgb;
    indirect[index] = vec4f(radiance, 1.0);
}
