#import cssm::types::{Material, View}
#import cssm::lowres::lowres_representative
#import cssm::bilateral::{Guide, upsample_weights}
#import cssm::proxy::GridParams

// Indirect energy gathering (Chen et al. 2014 §3.3, Eq. 5-7), one invocation per pixel of
// the gathering resolution (the G-buffer reduced `factor` times per side, at each pixel's
// representative). The pixel weighs the filtered lists of the four marching pixels around it
// (Eq. 5): w_l bilinear, w_G the joint bilateral weight of depth and normal, normalised over
// the four (cssm::bilateral::upsample_weights, the shared up-sampling's weights), so a voxel
// counts with the summed weight of the lists that hold it; the lists, in increasing key
// order, are merged. Each voxel's light (Eq. 6): within `range` of its centroid its VPLs one
// by one, beyond it the voxel's order-0/1 spherical harmonics from the centroid. Both are
// points whose irradiance is E = I cos_r / d^2, a VPL's intensity I = flux / pi cos_s with its
// disc's area over pi added to d^2 (a disc's form factor, bounded next to the receiver).
// Output, two planes of the shared filters' input: rgb diffuse irradiance (plane 0) and the
// irradiance weighted by the receiver's specular weight without Ks (plane 1): the normalised
// Phong lobe (Ns + 2) / (2 pi) cos^Ns, or with `sigma` > 0 Eq. 7's Gaussian of
// 1 - cos^Ns in place of cos^Ns. Twin: vf/gather.rs::gather_cpu.

struct GatherParams {
    full_size: vec2u,
    size: vec2u,
    march_size: vec2u,
    factor: u32,
    march_factor: u32,
    capacity: u32,
    // R of Eq. 6, world units.
    range: f32,
    depth_sigma: f32,
    normal_power: f32,
    // sigma_theta of Eq. 7; 0 for the Phong lobe.
    sigma: f32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: GatherParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var<uniform> grid: GridParams;
@group(0) @binding(3) var gb_position: texture_2d<f32>;
@group(0) @binding(4) var gb_normal: texture_2d<f32>;
@group(0) @binding(5) var<storage, read> materials: array<Material>;
@group(0) @binding(6) var<storage, read> lists: array<u32>;
@group(0) @binding(7) var<storage, read> vpl_position: array<vec4f>;
@group(0) @binding(8) var<storage, read> vpl_normal: array<vec4f>;
@group(0) @binding(9) var<storage, read> vpl_flux: array<vec4f>;
@group(0) @binding(10) var<storage, read> sorted: array<vec2u>;
@group(0) @binding(11) var<storage, read> ranges: array<vec2u>;
@group(0) @binding(12) var<storage, read> voxel_sh: array<vec4f>;
@group(0) @binding(13) var<storage, read_write> planes: array<vec4f>;

const PI: f32 = 3.14159265358979;
const NO_VOXEL: u32 = 0xffffffffu;

struct Receiver {
    x: vec3f,
    n: vec3f,
    v: vec3f,
    ns: f32,
}

// The receiver's specular weight for light arriving along `l` (without Ks).
fn specular(r: Receiver, l: vec3f) -> f32 {
    let c = pow(max(dot(reflect(-l, r.n), r.v), 0.0), r.ns);
    if params.sigma > 0.0 {
        let g = (1.0 - c) / params.sigma;
        return (r.ns + 2.0) / (2.0 * PI) * exp(-0.5 * g * g);
    }
    return (r.ns + 2.0) / (2.0 * PI) * c;
}

// Eq. 6: voxel `v`'s irradiance at the receiver, diffuse (xyz) and specular-weighted in
// the second vector.
fn voxel_light(r: Receiver, v: u32) -> array<vec3f, 2> {
    var diffuse = vec3f(0.0);
    var glossy = vec3f(0.0);
    let centroid = voxel_sh[5u * v + 4u];
    if distance(centroid.xyz, r.x) < params.range {
        let range = ranges[v];
        for (var j = range.x; j < range.y; j++) {
            let i = sorted[j].y;
            let p = vpl_position[i];
            let d = p.xyz - r.x;
            let d2 = dot(d, d);
            if d2 <= 0.0 {
                continue;
            }
            let l = d * inverseSqrt(d2);
            let sn = vpl_normal[i];
            let cosines = max(dot(sn.xyz, -l), 0.0) * max(dot(r.n, l), 0.0);
            if cosines <= 0.0 {
                continue;
            }
            let e = vpl_flux[i].rgb / PI * cosines / (d2 + sn.w / PI);
            diffuse += e;
            glossy += e * specular(r, l);
        }
    } else {
        let d = centroid.xyz - r.x;
        let d2 = dot(d, d);
        if d2 <= 0.0 {
            return array<vec3f, 2>(diffuse, glossy);
        }
        let l = d * inverseSqrt(d2);
        let cos_r = max(dot(r.n, l), 0.0);
        if cos_r > 0.0 {
            // The intensity towards the receiver, -l: Y00 c00 + Y1 (c1-1 w.y + c10 w.z + c11 w.x).
            let w = -l;
            let y0 = 0.5 / sqrt(PI);
            let y1 = sqrt(3.0 / (4.0 * PI));
            let base = 5u * v;
            let intensity = max(
                y0 * voxel_sh[base].rgb
                    + y1 * (w.y * voxel_sh[base + 1u].rgb + w.z * voxel_sh[base + 2u].rgb + w.x * voxel_sh[base + 3u].rgb),
                vec3f(0.0),
            );
            let e = intensity * cos_r / d2;
            diffuse = e;
            glossy = e * specular(r, l);
        }
    }
    return array<vec3f, 2>(diffuse, glossy);
}

fn guide_at(pixel: vec2u) -> Guide {
    let p = textureLoad(gb_position, vec2i(pixel), 0);
    let n = textureLoad(gb_normal, vec2i(pixel), 0).xyz;
    return Guide(p.w > 0.0, distance(view.eye, p.xyz), n);
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let index = id.y * params.size.x + id.x;
    let plane = params.size.x * params.size.y;
    let at = lowres_representative(id.xy, params.factor, params.full_size);
    let g = textureLoad(gb_position, vec2i(at), 0);
    var diffuse = vec3f(0.0);
    var glossy = vec3f(0.0);
    if g.w > 0.0 {
        let gn = textureLoad(gb_normal, vec2i(at), 0);
        let r = Receiver(g.xyz, gn.xyz, normalize(view.eye - g.xyz), materials[u32(gn.w)].ns);
        // Eq. 5: the four marching pixels around this one and their weights.
        let q = (vec2f(at) + 0.5) / f32(params.march_factor) - 0.5;
        let base = floor(q);
        let low = vec2i(params.march_size);
        var taps: array<Guide, 4>;
        var heads: array<u32, 4>;
        var ends: array<u32, 4>;
        for (var k = 0u; k < 4u; k++) {
            let s = vec2u(clamp(vec2i(base) + vec2i(vec2u(k & 1u, k >> 1u)), vec2i(0), low - 1));
            taps[k] = guide_at(lowres_representative(s, params.march_factor, params.full_size));
            let start = (s.y * params.march_size.x + s.x) * (params.capacity + 1u);
            heads[k] = start + 1u;
            ends[k] = start + 1u + lists[start];
        }
        let weights = upsample_weights(guide_at(at), taps, q - base, params.depth_sigma, params.normal_power);
        for (var k = 0u; k < 4u; k++) {
            if weights[k] <= 0.0 {
                ends[k] = heads[k];
            }
        }
        // The union of the four lists in key order, each voxel with its lists' weights.
        loop {
            var key = NO_VOXEL;
            for (var k = 0u; k < 4u; k++) {
                if heads[k] < ends[k] {
                    key = min(key, lists[heads[k]]);
                }
            }
            if key == NO_VOXEL {
                break;
            }
            var weight = 0.0;
            for (var k = 0u; k < 4u; k++) {
                if heads[k] < ends[k] && lists[heads[k]] == key {
                    weight += weights[k];
                    heads[k] += 1u;
                }
            }
            let light = voxel_light(r, key);
            diffuse += weight * light[0];
            glossy += weight * light[1];
        }
    }
    planes[index] = vec4f(diffuse, 0.0);
    planes[plane + index] = vec4f(glossy, 0.0);
}
