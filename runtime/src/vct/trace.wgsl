// Voxel cone tracing (Crassin et al. 2011 §5, §7), per pixel of the image reduced `factor` times
// per side (its representative pixel, as every reduced technique): `cones` diffuse cones over
// the hemisphere of the G-buffer's normal, cosine-distributed (a Fibonacci spiral, turned about
// the normal by a per-pixel angle when `turn` is set, so that neighbours look along other
// directions and the filters' blur averages them), whose mean is the irradiance over pi; and
// for a glossy material one cone along the mirror direction whose aperture follows the Phong
// exponent. Output, two planes of the filters' input (as rsm's and ssil's): the diffuse
// irradiance (plane 0) and the Phong-lobe-weighted irradiance without Ks (plane 1), reflected
// with the full-resolution albedo and Ks by the resolve after filtering. The ambient occlusion
// view writes its grey at full resolution into `occlusion` instead. CPU twin: vct/cpu.rs
// `shade_planes`, `occlusion_view`; `probe` traces given cones for the test against
// `cpu::trace_cone`.

#import cssm::types::{Material, View}
#import cssm::svo::{svo, svo_cone, svo_diffuse, svo_occlusion}
#import cssm::lowres::lowres_representative
#import cssm::random::{pcg_hash, hash_unit}

struct TraceParams {
    cones: u32,
    // tan of the diffuse cones' half angle.
    tan_half: f32,
    // Above 0: the ambient occlusion view (§6), its cones this far (leaves).
    occlusion_radius: f32,
    // Reduction per side of the traced image.
    factor: u32,
    // Where a cone's first sample lies and how far off the surface it starts, in leaves.
    start: f32,
    offset: f32,
    // The diffuse half angle, radians: the glossy cone's widest.
    half_angle: f32,
    // Nonzero: the spiral turned per pixel.
    turn: u32,
}

@group(0) @binding(0) var<uniform> params: TraceParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var<storage, read> materials: array<Material>;
@group(0) @binding(3) var gb_position: texture_2d<f32>;
@group(0) @binding(4) var gb_normal: texture_2d<f32>;
@group(0) @binding(5) var<storage, read_write> occlusion: array<vec4f>;
@group(0) @binding(6) var<storage, read_write> planes: array<vec4f>;


// The tan of the glossy cone's half angle: the angle at which the Phong lobe cos^ns falls to
// half, at most the diffuse cones' (`cpu::glossy_tan_half`).
fn glossy_tan_half(ns: f32) -> f32 {
    let angle = acos(pow(0.5, 1.0 / max(ns, 1.0)));
    return tan(clamp(angle, 0.00873, params.half_angle));
}

// The spiral's turn at full-resolution pixel `pixel` (`cpu::pixel_turn`).
fn pixel_turn(pixel: vec2u) -> f32 {
    if params.turn == 0u {
        return 0.0;
    }
    return hash_unit(pcg_hash(pixel.x + pixel.y * 65536u));
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    let low = (view.size + vec2u(params.factor - 1u)) / params.factor;
    if id.x >= low.x || id.y >= low.y {
        return;
    }
    let index = id.y * low.x + id.x;
    let low_pixels = low.x * low.y;
    let pixel = lowres_representative(id.xy, params.factor, view.size);
    let at = vec2i(pixel);
    let g = textureLoad(gb_position, at, 0);
    if g.w <= 0.0 {
        if params.occlusion_radius > 0.0 {
            occlusion[index] = vec4f(0.0, 0.0, 0.0, 1.0);
        } else {
            planes[index] = vec4f(0.0);
            planes[low_pixels + index] = vec4f(0.0);
        }
        return;
    }
    let gn = textureLoad(gb_normal, at, 0);
    let n = gn.xyz;
    let material = materials[u32(gn.w)];
    let origin = (g.xyz - svo.origin) * svo.inv_voxel + n * params.offset;
    if params.occlusion_radius > 0.0 {
        let occluded = svo_occlusion(origin, n, params.cones, params.tan_half, params.start,
            params.occlusion_radius);
        occlusion[index] = vec4f(vec3f(1.0 - occluded), 1.0);
        return;
    }
    // §7: the hemisphere's irradiance over pi as the mean of cosine-distributed cones (a
    // uniform sky of radiance L gives L); times pi, the irradiance the resolve reflects.
    let turn = pixel_turn(pixel);
    let diffuse = 3.14159265 * svo_diffuse(origin, n, params.cones, params.tan_half, params.start,
        turn);
    var glossy = vec3f(0.0);
    if any(material.ks > vec3f(0.0)) {
        let v = normalize(view.eye - g.xyz);
        let r = reflect(-v, n);
        let cos_r = dot(n, r);
        if cos_r > 0.0 {
            let lobe = svo_cone(origin, r, glossy_tan_half(material.ns), params.start).rgb;
            // The normalised Phong lobe integrates to (ns + 2) / (ns + 1) times the cosine.
            glossy = lobe * ((material.ns + 2.0) / (material.ns + 1.0) * cos_r);
        }
    }
    planes[index] = vec4f(diffuse, 0.0);
    planes[low_pixels + index] = vec4f(glossy, 0.0);
}

// A cone to trace: origin (leaf voxels) and start distance, direction and tan of the half
// angle.
struct Probe {
    origin: vec3f,
    start: f32,
    dir: vec3f,
    tan_half: f32,
}

@group(0) @binding(7) var<storage, read> probes: array<Probe>;
@group(0) @binding(8) var<storage, read_write> probe_out: array<vec4f>;

@compute @workgroup_size(#{WORKGROUP_1D})
fn probe(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= arrayLength(&probes) {
        return;
    }
    let c = probes[id.x];
    probe_out[id.x] = svo_cone(c.origin, c.dir, c.tan_half, c.start);
}
