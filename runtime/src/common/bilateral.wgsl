#define_import_path cssm::bilateral

// The range weight of the edge-aware filters (common/filters.wgsl) and of every other joint
// bilateral step (the SSIL levels, ssil/gather.wgsl): a guide per pixel, and the depth and
// normal weight of a tap against a centre whose distance is the reference, so that the depth
// tolerance means the same near and far from the eye. Twin: filters/cpu.rs::range_weight.

// A pixel's guide: covered, distance from the eye, normal.
struct Guide {
    covered: bool,
    distance: f32,
    normal: vec3f,
}

// exp(-((d_t - d_c) / (depth_sigma d_c))^2) max(0, n_c.n_t)^normal_power; 0 for normals facing
// apart.
fn bilateral_weight(centre: Guide, tap: Guide, depth_sigma: f32, normal_power: f32) -> f32 {
    let r = (tap.distance - centre.distance) / (depth_sigma * max(centre.distance, 1e-6));
    let c = dot(centre.normal, tap.normal);
    if c <= 0.0 {
        return 0.0;
    }
    return exp(-r * r) * pow(c, normal_power);
}

// Joint bilateral up-sampling (Kopf et al. 2007) from the 2x2 low-res taps around a pixel
// (taps in the order (0,0), (1,0), (0,1), (1,1); `t` the pixel's fractional position between
// them): bilinear weights times bilateral_weight against the pixel's own guide, normalised;
// when every tap is rejected, weight 1 on the covered tap nearest in distance; all 0 when none
// is covered. Twin: filters/cpu.rs::upsample_weights.
fn upsample_weights(pixel: Guide, taps: array<Guide, 4>, t: vec2f, depth_sigma: f32, normal_power: f32) -> vec4f {
    var weights = vec4f(0.0);
    var total = 0.0;
    var nearest = 4u;
    var nearest_gap = 0.0;
    for (var i = 0u; i < 4u; i++) {
        let tap = taps[i];
        if !tap.covered {
            continue;
        }
        let gap = abs(tap.distance - pixel.distance);
        if nearest == 4u || gap < nearest_gap {
            nearest = i;
            nearest_gap = gap;
        }
        let wx = select(1.0 - t.x, t.x, (i & 1u) == 1u);
        let wy = select(1.0 - t.y, t.y, (i >> 1u) == 1u);
        weights[i] = wx * wy * bilateral_weight(pixel, tap, depth_sigma, normal_power);
        total += weights[i];
    }
    if total >= 1e-6 {
        return weights / total;
    }
    var fallback = vec4f(0.0);
    if nearest < 4u {
        fallback[nearest] = 1.0;
    }
    return fallback;
}
