#import cssm::light::{materials, lights, spot_irradiance}
#import cssm::albedo::albedo_sample
#import cssm::proxy::{Proxy, GridParams}

// The proxies as virtual point lights and each voxel's light in spherical harmonics (Chen et
// al. 2014 §3.1, Eq. 2, 3).
// `vpl`: each proxy moved with its object, lit by every spot light through its shadow map
// (cssm::light), on the side of its disc that sends more light (surfaces are two-sided; a VPL
// sends from one side): its flux is that side's exitance times the disc's area, the exitance
// albedo * E, plus pi times the emitted radiance on the front side (the winding's: emission is
// one-sided, and a Lambertian emitter of radiance Le has the exitance pi Le); its world position
// and that side's normal.
// `voxel_sh`: per voxel, over its range of the proxies sorted by voxel, the sum of each VPL's
// radiant intensity (flux / pi * max(0, n.w)) projected on the real spherical harmonics of
// order 0 and 1 (c00 = flux / (2 sqrt(pi)), c1m = flux / sqrt(3 pi) n_m for m = -1, 0, 1 on
// y, z, x), and the VPLs' centroid and count. A per-voxel sum over the sorted range instead of
// the paper's atomics: the same sums, deterministic, in floating point.
// Twins: vf/light.rs::{vpl_cpu, voxel_sh_cpu}.

@group(0) @binding(5) var<uniform> grid: GridParams;
@group(0) @binding(6) var<storage, read> proxies: array<Proxy>;
@group(0) @binding(7) var<storage, read> object_motion: array<mat4x4f>;
@group(0) @binding(8) var albedo_textures: texture_2d_array<f32>;
// xyz world position, w disc radius.
@group(0) @binding(9) var<storage, read_write> vpl_position: array<vec4f>;
// xyz the side it sends from, w its disc area.
@group(0) @binding(10) var<storage, read_write> vpl_normal: array<vec4f>;
// rgb flux leaving the disc.
@group(0) @binding(11) var<storage, read_write> vpl_flux: array<vec4f>;
@group(0) @binding(12) var<storage, read> sorted: array<vec2u>;
@group(0) @binding(13) var<storage, read> ranges: array<vec2u>;
// Per voxel: c00, c1-1, c10, c11 (rgb each), then the centroid (xyz) and the count (w).
@group(0) @binding(14) var<storage, read_write> voxel_sh: array<vec4f>;

const PI: f32 = 3.14159265358979;

@compute @workgroup_size(#{WORKGROUP_1D})
fn vpl(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x;
    if i >= grid.count {
        return;
    }
    let p = proxies[i];
    let motion = object_motion[p.object];
    let world = (motion * vec4f(p.position, 1.0)).xyz;
    let n = normalize((motion * vec4f(p.normal, 0.0)).xyz);
    var front = vec3f(0.0);
    var back = vec3f(0.0);
    for (var l = 0u; l < arrayLength(&lights); l++) {
        front += spot_irradiance(l, world, n).rgb;
        back += spot_irradiance(l, world, -n).rgb;
    }
    let m = materials[p.material];
    var albedo = m.kd;
    if m.texture >= 0 {
        albedo *= albedo_sample(albedo_textures, u32(m.texture), p.uv);
    }
    var emission = m.emission;
    if m.emission_texture >= 0 && any(emission > vec3f(0.0)) {
        emission *= albedo_sample(albedo_textures, u32(m.emission_texture), p.uv);
    }
    let front_exitance = albedo * front + PI * emission;
    let back_exitance = albedo * back;
    var side = n;
    var exitance = front_exitance;
    if dot(back_exitance, vec3f(1.0)) > dot(front_exitance, vec3f(1.0)) {
        side = -n;
        exitance = back_exitance;
    }
    let area = PI * p.radius * p.radius;
    vpl_position[i] = vec4f(world, p.radius);
    vpl_normal[i] = vec4f(side, area);
    vpl_flux[i] = vec4f(exitance * area, 0.0);
}

@compute @workgroup_size(#{WORKGROUP_1D})
fn voxel_sh_sum(@builtin(global_invocation_id) id: vec3u) {
    let cell = id.x;
    if cell >= grid.dims.x * grid.dims.y * grid.dims.z {
        return;
    }
    var c00 = vec3f(0.0);
    var c1 = array<vec3f, 3>(vec3f(0.0), vec3f(0.0), vec3f(0.0));
    var centroid = vec3f(0.0);
    let range = ranges[cell];
    let k0 = 0.5 / sqrt(PI);
    let k1 = 1.0 / sqrt(3.0 * PI);
    for (var j = range.x; j < range.y; j++) {
        let v = sorted[j].y;
        let flux = vpl_flux[v].rgb;
        let n = vpl_normal[v].xyz;
        c00 += k0 * flux;
        c1[0] += k1 * n.y * flux;
        c1[1] += k1 * n.z * flux;
        c1[2] += k1 * n.x * flux;
        centroid += vpl_position[v].xyz;
    }
    let count = f32(range.y - range.x);
    let base = 5u * cell;
    voxel_sh[base] = vec4f(c00, 0.0);
    voxel_sh[base + 1u] = vec4f(c1[0], 0.0);
    voxel_sh[base + 2u] = vec4f(c1[1], 0.0);
    voxel_sh[base + 3u] = vec4f(c1[2], 0.0);
    voxel_sh[base + 4u] = vec4f(centroid / max(count, 1.0), count);
}
