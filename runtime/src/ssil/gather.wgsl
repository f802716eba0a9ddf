#import cssm::types::{Material, View}
#import cssm::bilateral::{Guide, upsample_weights}
#import cssm::random::{pcg_hash, hash_unit}

// The SSIL gather (Soler et al. 2010 §3, §4), one level of the pyramid per dispatch, coarsest
// first. Each pixel x of level k draws `samples` screen-space samples in the ring between
// r / 2 and r level-k pixels around it (the full disc at the finest gathered level, so that
// the levels together cover the screen once, Fig. 3), and sums the irradiance each sends:
//     dE_i = L_i cos_r cos_s ds_i / (r_i^2 + cos_s ds_i / pi)        (Eq. 3 with Eq. 4)
// with ds_i the scene area of the sample (Eq. 2): its share of the ring, dP = ring / samples
// level-k pixels, is 4^k full-res pixels each (the paper's energy factor 2^2k), and a full-res
// pixel at view depth z covers pixel_area z^2 cos_alpha / cos_beta. The point-to-disc form
// factor (Eq. 4, a disc of area cos_s ds) keeps a sender beside its receiver bounded; with
// `sample_disc` 0 the disc is the sample's own level pixel and the sample counts dP times, so
// that a sample standing for a large share near its receiver is not bounded by one disc.
// Visibility: a sample counts only when the march from x to it through this level's solid
// voxels (ssil/voxels.wgsl) meets none, skipping `bias` pixels at either end (§4).
// Glossy receivers also gather a lobe-weighted irradiance from `samples` more samples whose
// angle is importance-sampled around the screen-space direction of the mirrored view ray
// (§4: f(theta) = alpha + exp(-s (theta_r - theta)^2 / (2 pi)), sampled as its uniform and
// Gaussian parts), each weighted by the inverse of its density.
// The coarser level's result, already holding every coarser level's, is joint-bilaterally
// up-sampled into this one and added (§4, "Continuous combination of all levels").
// `accumulate` adds a bounce's result at the finest level into the filters' input and, when
// another bounce follows, makes it that bounce's light (§4, "Multi-bounce computation").
// Twins: ssil/cpu.rs::{gather_pixel, accumulate}.

struct GatherParams {
    full_size: vec2u,
    size: vec2u,
    coarse_size: vec2u,
    // The level (0 is the G-buffer's resolution).
    level: u32,
    // Pyramid element of this level's and the coarser level's pixel (0, 0).
    offset: u32,
    coarse_offset: u32,
    has_coarse: u32,
    samples: u32,
    // 1 at the finest gathered level: the full disc.
    disc: u32,
    radius: f32,
    visibility: u32,
    bias: f32,
    // Grid column of this level's (0, 0).
    grid_offset: u32,
    depth_sigma: f32,
    normal_power: f32,
    bounce: u32,
    next_bounce: u32,
    // Elements of the pyramid: the stride between the planes of `acc`.
    pixels: u32,
    // alpha of the importance function.
    uniform_weight: f32,
    // 1: each sample's form factor is that of a disc of the area its share of the ring stands
    // for (§3, Eq. 4 as the paper applies it); 0: of a disc of its own pixel, times the pixels
    // of its share (the plain Monte-Carlo estimate of the sum over the level's pixels).
    sample_disc: u32,
    padding_a: u32,
}

struct FrameParams {
    seed: u32,
    z_near: f32,
    z_far: f32,
    // Area of a full-res pixel at view depth 1 on a plane facing the eye: 4 tan(fh/2)
    // tan(fv/2) / (W H).
    pixel_area: f32,
}

@group(0) @binding(0) var<uniform> params: GatherParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var<uniform> frame: FrameParams;
@group(0) @binding(3) var<storage, read> materials: array<Material>;
@group(0) @binding(4) var<storage, read> pyramid_position: array<vec4f>;
@group(0) @binding(5) var<storage, read> pyramid_normal: array<vec4f>;
@group(0) @binding(6) var<storage, read> sender: array<vec4f>;
@group(0) @binding(7) var<storage, read> grid: array<u32>;
// Two planes (diffuse, lobe-weighted), `pixels` apart.
@group(0) @binding(8) var<storage, read_write> acc: array<vec4f>;
// The convergence test's state (common/converge.wgsl): its first word 1 once a bounce added at
// most 1% of the light, after which the later bounces gather nothing.
@group(0) @binding(12) var<storage, read> converge_state: array<u32>;
// `accumulate`'s own.
@group(0) @binding(9) var<storage, read_write> total: array<vec4f>;
@group(0) @binding(10) var<storage, read_write> next_sender: array<vec4f>;
@group(0) @binding(11) var<storage, read> pyramid_albedo: array<vec4f>;

const PI: f32 = 3.14159265358979;
const SLICES: u32 = 128u;
// Most steps of a visibility march.
const MAX_MARCH: u32 = 256u;

// Level-k pixel coordinates of a clip-space point.
fn to_level(clip: vec4f) -> vec2f {
    let ndc = clip.xy / clip.w;
    let full = vec2f(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5) * vec2f(params.full_size);
    return full / f32(1u << params.level);
}

fn occluded(a: vec3f, b: vec3f) -> bool {
    let pa = to_level(view.view_proj * vec4f(a, 1.0));
    let pb = to_level(view.view_proj * vec4f(b, 1.0));
    let len = length(pb - pa);
    let steps = u32(clamp(ceil(len), 1.0, f32(MAX_MARCH)));
    for (var s = 1u; s < steps; s++) {
        let t = f32(s) / f32(steps);
        if t * len < params.bias || (1.0 - t) * len < params.bias {
            continue;
        }
        let c = view.view_proj * vec4f(mix(a, b, t), 1.0);
        if c.w <= 0.0 {
            continue;
        }
        let px = vec2i(floor(to_level(c)));
        if px.x < 0 || px.y < 0 || px.x >= i32(params.size.x) || px.y >= i32(params.size.y) {
            continue;
        }
        let tz = (c.w - frame.z_near) / (frame.z_far - frame.z_near);
        if tz < 0.0 || tz >= 1.0 {
            continue;
        }
        let slice = u32(tz * f32(SLICES));
        let column = params.grid_offset + u32(px.y) * params.size.x + u32(px.x);
        if ((grid[4u * column + slice / 32u] >> (slice % 32u)) & 1u) == 1u {
            return true;
        }
    }
    return false;
}

struct Sent {
    // rgb irradiance; w 1 when the sample counted.
    irradiance: vec4f,
    direction: vec3f,
}

// The irradiance at x (normal n) from the sample at level pixel q standing for dp level
// pixels.
fn sent(x: vec3f, n: vec3f, q: vec2i, dp: f32) -> Sent {
    var none = Sent(vec4f(0.0), vec3f(0.0));
    if q.x < 0 || q.y < 0 || q.x >= i32(params.size.x) || q.y >= i32(params.size.y) {
        return none;
    }
    let j = params.offset + u32(q.y) * params.size.x + u32(q.x);
    let s = pyramid_position[j];
    if s.w <= 0.0 {
        return none;
    }
    let ns = pyramid_normal[j].xyz;
    let d = s.xyz - x;
    let r2 = dot(d, d);
    if r2 <= 1e-12 {
        return none;
    }
    let w = d * inverseSqrt(r2);
    let cos_r = dot(n, w);
    let cos_s = -dot(ns, w);
    if cos_r <= 0.0 || cos_s <= 0.0 {
        return none;
    }
    let z = (view.view_proj * vec4f(s.xyz, 1.0)).w;
    let to_eye = view.eye - s.xyz;
    let dist = length(to_eye);
    let cos_alpha = z / dist;
    let cos_beta = max(dot(ns, to_eye) / dist, 0.01);
    // Full-res pixels of a disc and how many such discs the sample stands for.
    var full_pixels = f32(1u << (2u * params.level));
    var copies = dp;
    if params.sample_disc == 1u {
        full_pixels *= dp;
        copies = 1.0;
    }
    let ds = frame.pixel_area * z * z * cos_alpha / cos_beta * full_pixels;
    let f = copies * cos_r * cos_s * ds / (r2 + cos_s * ds / PI);
    if params.visibility == 1u && occluded(x, s.xyz) {
        return none;
    }
    return Sent(vec4f(sender[j].rgb * f, 1.0), w);
}

// Density of the glossy samples' angle theta (wrapped offset `delta` from theta_r): the
// uniform part with probability `p_uniform`, else a Gaussian of `sigma` wrapped once each way.
fn angle_density(delta: f32, p_uniform: f32, sigma: f32) -> f32 {
    var g = 0.0;
    for (var k = -1; k <= 1; k++) {
        let t = (delta + 2.0 * PI * f32(k)) / sigma;
        g += exp(-0.5 * t * t);
    }
    return p_uniform / (2.0 * PI) + (1.0 - p_uniform) * g / (sigma * sqrt(2.0 * PI));
}

fn wrap_angle(a: f32) -> f32 {
    return a - 2.0 * PI * floor((a + PI) / (2.0 * PI));
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn gather(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let i = params.offset + id.y * params.size.x + id.x;
    let x4 = pyramid_position[i];
    if x4.w <= 0.0 || (params.bounce > 0u && converge_state[0] != 0u) {
        acc[i] = vec4f(0.0);
        acc[params.pixels + i] = vec4f(0.0);
        return;
    }
    let x = x4.xyz;
    let n4 = pyramid_normal[i];
    let n = n4.xyz;
    let m = materials[u32(n4.w)];
    let key = pcg_hash(id.x ^ pcg_hash(id.y ^ pcg_hash(params.level ^ pcg_hash(frame.seed))));
    let rotation = hash_unit(key);
    let jitter = hash_unit(pcg_hash(key));
    let r1 = select(0.5 * params.radius, 0.0, params.disc == 1u);
    let r2 = params.radius;
    let ring = PI * (r2 * r2 - r1 * r1);
    let count = f32(params.samples);
    let centre = vec2f(id.xy) + 0.5;
    var diffuse = vec3f(0.0);
    for (var k = 0u; k < params.samples; k++) {
        let theta = 2.0 * PI * (f32(k) + rotation) / count;
        let u = fract(f32(k) * 0.618034 + jitter);
        let rho = sqrt(r1 * r1 + u * (r2 * r2 - r1 * r1));
        let q = vec2i(floor(centre + rho * vec2f(cos(theta), sin(theta))));
        if all(q == vec2i(id.xy)) {
            continue;
        }
        diffuse += sent(x, n, q, ring / count).irradiance.rgb;
    }
    var glossy = vec3f(0.0);
    if max(m.ks.x, max(m.ks.y, m.ks.z)) > 0.0 {
        let v = normalize(view.eye - x);
        let mirrored = reflect(-v, n);
        // The mirrored ray's direction on screen, from a point as far along it as the eye.
        let far = view.view_proj * vec4f(x + distance(view.eye, x) * mirrored, 1.0);
        var theta_r = 0.0;
        var p_uniform = 1.0;
        if far.w > 1e-6 {
            let dir = to_level(far) - centre;
            if length(dir) > 1e-3 {
                theta_r = atan2(dir.y, dir.x);
                let sigma_g = sqrt(PI / max(m.ns, 1e-3));
                let m_uniform = 2.0 * PI * params.uniform_weight;
                let m_gauss = sigma_g * sqrt(2.0 * PI);
                p_uniform = m_uniform / (m_uniform + m_gauss);
            }
        }
        let sigma = sqrt(PI / max(m.ns, 1e-3));
        let lobe_scale = (m.ns + 2.0) / (2.0 * PI);
        let jitter_b = hash_unit(pcg_hash(key ^ 0x9e3779b9u));
        for (var k = 0u; k < params.samples; k++) {
            let a = (f32(k) + rotation) / count;
            var theta: f32;
            if a < p_uniform {
                theta = theta_r + 2.0 * PI * a / p_uniform;
            } else {
                let u1 = 1.0 - (a - p_uniform) / (1.0 - p_uniform);
                let u2 = fract(f32(k) * 0.754878 + jitter_b);
                theta = theta_r + sigma * sqrt(-2.0 * log(max(u1, 1e-7))) * cos(2.0 * PI * u2);
            }
            let density = angle_density(wrap_angle(theta - theta_r), p_uniform, sigma);
            let u = fract(f32(k) * 0.618034 + jitter);
            let rho = sqrt(r1 * r1 + u * (r2 * r2 - r1 * r1));
            let q = vec2i(floor(centre + rho * vec2f(cos(theta), sin(theta))));
            if all(q == vec2i(id.xy)) {
                continue;
            }
            let dp = ring / (count * 2.0 * PI * density);
            let s = sent(x, n, q, dp);
            if s.irradiance.w > 0.0 {
                let lobe = lobe_scale * pow(max(dot(mirrored, s.direction), 0.0), m.ns);
                glossy += lobe * s.irradiance.rgb;
            }
        }
    }
    var up = array<vec4f, 2>(vec4f(0.0), vec4f(0.0));
    if params.has_coarse == 1u {
        let pixel = Guide(true, distance(view.eye, x), n);
        let qf = centre / 2.0 - 0.5;
        let base = floor(qf);
        var taps: array<Guide, 4>;
        var indices: array<u32, 4>;
        let last = vec2i(params.coarse_size) - 1;
        for (var t = 0u; t < 4u; t++) {
            let s = vec2u(clamp(vec2i(base) + vec2i(vec2u(t & 1u, t >> 1u)), vec2i(0), last));
            let c = params.coarse_offset + s.y * params.coarse_size.x + s.x;
            indices[t] = c;
            let p = pyramid_position[c];
            taps[t] = Guide(p.w > 0.0, distance(view.eye, p.xyz), pyramid_normal[c].xyz);
        }
        let weights = upsample_weights(pixel, taps, qf - base, params.depth_sigma, params.normal_power);
        for (var t = 0u; t < 4u; t++) {
            if weights[t] > 0.0 {
                up[0] += weights[t] * acc[indices[t]];
                up[1] += weights[t] * acc[params.pixels + indices[t]];
            }
        }
    }
    acc[i] = vec4f(diffuse + up[0].rgb, 0.0);
    acc[params.pixels + i] = vec4f(glossy + up[1].rgb, 0.0);
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn accumulate(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= params.size.x || id.y >= params.size.y {
        return;
    }
    let local = id.y * params.size.x + id.x;
    let plane = params.size.x * params.size.y;
    let i = params.offset + local;
    var diffuse = acc[i];
    var glossy = acc[params.pixels + i];
    if params.next_bounce == 1u {
        next_sender[i] = vec4f(pyramid_albedo[i].rgb / PI * diffuse.rgb, 0.0);
    }
    if params.bounce > 0u {
        diffuse += total[local];
        glossy += total[plane + local];
    }
    total[local] = diffuse;
    total[plane + local] = glossy;
}
