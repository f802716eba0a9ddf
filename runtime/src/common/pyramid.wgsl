#import cssm::types::View

// The G-buffer pyramid (Soler et al. 2010 §4, "Filtering of mipmap levels", Eq. 5) and the
// pyramid of a signal over it. Level 0 is the G-buffer; level j halves level j - 1 (rounding
// up), each coarse pixel standing for its 2x2 children. Levels 1 and up live in buffers of one
// vec4f per pixel, level j's pixel (x, y) at element offset_j + y * width_j + x.
//
// `vote`: depths and normals cannot be averaged across levels (an average normal belongs to no
// surface, and small objects would flicker in and out), so each coarse pixel takes position,
// normal and albedo from the one child with the largest score
//     s(p_i) = sum over the finer level's p_j with |p_i - p_j|_L1 <= 1 of
//              g1(|p_i - p_j|) g2(1 - n_j.n_i) g3(z_j - z_i)          (Eq. 5)
// which favours children inside large regions of one depth and normal. Uncovered children
// neither score nor count in a score.
// `mean`: a signal (the light the SSIL gather reads) is the mean of the children inside the
// level, uncovered ones counting as zero, so each level keeps the screen's total.
// Twins: common/pyramid.rs::{vote_cpu, mean_cpu}.

struct LevelParams {
    fine_size: vec2u,
    coarse_size: vec2u,
    // Element of the finer level's (0, 0), unused when it is level 0.
    fine_offset: u32,
    coarse_offset: u32,
    // 1 when the finer level is level 0 (the G-buffer or the base signal).
    from_base: u32,
    padding_a: u32,
}

@group(0) @binding(0) var<uniform> level: LevelParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var gb_position: texture_2d<f32>;
@group(0) @binding(3) var gb_normal: texture_2d<f32>;
@group(0) @binding(4) var gb_albedo: texture_2d<f32>;
@group(0) @binding(5) var<storage, read_write> position: array<vec4f>;
@group(0) @binding(6) var<storage, read_write> normal: array<vec4f>;
@group(0) @binding(7) var<storage, read_write> albedo: array<vec4f>;
// `mean`'s own bindings.
@group(0) @binding(8) var<storage, read> base: array<vec4f>;
@group(0) @binding(9) var<storage, read_write> signal: array<vec4f>;

// g1 of a neighbour at L1 distance 1 (g1(d) = exp(-d^2 / 2)).
const NEIGHBOUR_WEIGHT: f32 = 0.60653066;
// Standard deviation of g2 over 1 - n_j.n_i.
const NORMAL_SIGMA: f32 = 0.2;
// Standard deviation of g3 over z_j - z_i, relative to z_i (the distance from the eye).
const DEPTH_SIGMA: f32 = 0.05;

struct Sample {
    position: vec4f,
    normal: vec4f,
    albedo: vec4f,
}

fn fine_sample(p: vec2u) -> Sample {
    if level.from_base == 1u {
        let at = vec2i(p);
        return Sample(
            textureLoad(gb_position, at, 0),
            textureLoad(gb_normal, at, 0),
            textureLoad(gb_albedo, at, 0),
        );
    }
    let i = level.fine_offset + p.y * level.fine_size.x + p.x;
    return Sample(position[i], normal[i], albedo[i]);
}

// g2 g3 of `other` against `centre`.
fn affinity(centre: Sample, other: Sample) -> f32 {
    let dn = (1.0 - dot(centre.normal.xyz, other.normal.xyz)) / NORMAL_SIGMA;
    let zc = distance(view.eye, centre.position.xyz);
    let dz = (distance(view.eye, other.position.xyz) - zc) / (DEPTH_SIGMA * max(zc, 1e-6));
    return exp(-0.5 * (dn * dn + dz * dz));
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn vote(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= level.coarse_size.x || id.y >= level.coarse_size.y {
        return;
    }
    let fine = vec2i(level.fine_size);
    var best = Sample(vec4f(0.0), vec4f(0.0), vec4f(0.0));
    var best_score = -1.0;
    for (var c = 0u; c < 4u; c++) {
        let child = vec2i(2u * id.xy + vec2u(c & 1u, c >> 1u));
        if child.x >= fine.x || child.y >= fine.y {
            continue;
        }
        let candidate = fine_sample(vec2u(child));
        if candidate.position.w <= 0.0 {
            continue;
        }
        var score = 1.0;
        var steps = array<vec2i, 4>(vec2i(-1, 0), vec2i(1, 0), vec2i(0, -1), vec2i(0, 1));
        for (var k = 0u; k < 4u; k++) {
            let n = child + steps[k];
            if n.x < 0 || n.y < 0 || n.x >= fine.x || n.y >= fine.y {
                continue;
            }
            let other = fine_sample(vec2u(n));
            if other.position.w > 0.0 {
                score += NEIGHBOUR_WEIGHT * affinity(candidate, other);
            }
        }
        if score > best_score {
            best = candidate;
            best_score = score;
        }
    }
    let out = level.coarse_offset + id.y * level.coarse_size.x + id.x;
    position[out] = best.position;
    normal[out] = best.normal;
    albedo[out] = best.albedo;
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn mean(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= level.coarse_size.x || id.y >= level.coarse_size.y {
        return;
    }
    var sum = vec4f(0.0);
    var count = 0.0;
    for (var c = 0u; c < 4u; c++) {
        let child = 2u * id.xy + vec2u(c & 1u, c >> 1u);
        if child.x >= level.fine_size.x || child.y >= level.fine_size.y {
            continue;
        }
        let i = child.y * level.fine_size.x + child.x;
        if level.from_base == 1u {
            sum += base[i];
        } else {
            sum += signal[level.fine_offset + i];
        }
        count += 1.0;
    }
    signal[level.coarse_offset + id.y * level.coarse_size.x + id.x] = sum / count;
}
