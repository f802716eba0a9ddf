#define_import_path cssm::transfer

#import cssm::types::{Node, Texel}
#import cssm::random::pcg_hash

// Light transfer from a hierarchy node to a receiver point and the oracle's upper bound of it
// (§4.3, §4.4). Twin of radiosity/transfer.rs, function by function; read its docs for the
// model. Needs types.wgsl (Node) and the binding `nodes: array<Node>`.

const TRANSFER_PI: f32 = 3.14159265358979;
const UNBOUNDED: f32 = 3.0e38;

// transfer::cos_bound.
fn cos_bound(axis: vec3f, spread: f32, to_center: vec3f, radius: f32) -> f32 {
    let dist = length(to_center);
    if dist <= radius {
        return 1.0;
    }
    let theta = acos(clamp(dot(axis, to_center) / dist, -1.0, 1.0));
    let alpha = asin(min(radius / dist, 1.0));
    let phi = max(theta - alpha - spread, 0.0);
    if phi >= 0.5 * TRANSFER_PI {
        return 0.0;
    }
    return cos(phi);
}

// transfer::tone_mapped.
fn tone_mapped(radiance: vec3f, exposure: f32) -> f32 {
    return pow(max(exposure * max(radiance.x, max(radiance.y, radiance.z)), 0.0), 1.0 / 2.2);
}

// transfer::irradiance_bound.
fn irradiance_bound(p: vec3f, n: vec3f, node: Node, radiance: vec3f) -> vec3f {
    let to_center = node.center - p;
    let d_min = length(to_center) - node.radius;
    if d_min <= 0.0 {
        return vec3f(UNBOUNDED);
    }
    let cos_r = cos_bound(n, 0.0, to_center, node.radius);
    let len = length(node.normal);
    var cos_s = 1.0;
    if !(node.cone_cos <= -1.0 || len < 1e-6) {
        let spread = acos(clamp(node.cone_cos, -1.0, 1.0));
        cos_s = cos_bound(-node.normal / len, spread, to_center, node.radius);
    }
    return radiance * (node.area * cos_r * cos_s / (d_min * d_min));
}

// transfer::brdf_bound.
fn brdf_bound(n: vec3f, v: vec3f, albedo: vec3f, ks: vec3f, ns: f32, to_center: vec3f, radius: f32) -> vec3f {
    let mirror = reflect(-v, n);
    let c = cos_bound(mirror, 0.0, to_center, radius);
    return albedo / TRANSFER_PI + ks * ((ns + 2.0) / (2.0 * TRANSFER_PI) * pow(c, ns));
}

// transfer::brdf.
fn brdf(n: vec3f, v: vec3f, w: vec3f, albedo: vec3f, ks: vec3f, ns: f32) -> vec3f {
    return albedo / TRANSFER_PI + ks * phong_lobe(n, v, w, ns);
}

// transfer::phong_lobe: the normalised Phong lobe of `brdf` without Ks.
fn phong_lobe(n: vec3f, v: vec3f, w: vec3f, ns: f32) -> f32 {
    let r = reflect(-w, n);
    return (ns + 2.0) / (2.0 * TRANSFER_PI) * pow(max(dot(r, v), 0.0), ns);
}

// transfer::irradiance_from: xyz irradiance; the direction is recomputed by the caller.
fn irradiance_from(p: vec3f, n: vec3f, y: vec3f, sender_normal: vec3f, area: f32, radiance: vec3f) -> vec3f {
    let d = y - p;
    let dist2 = dot(d, d);
    if dist2 <= 0.0 {
        return vec3f(0.0);
    }
    let w = d / sqrt(dist2);
    let cos_r = max(dot(n, w), 0.0);
    let cos_s = max(-dot(sender_normal, w), 0.0);
    return radiance * (area * cos_r * cos_s / (dist2 + area / TRANSFER_PI));
}

// transfer::cluster_projected_area.
fn cluster_projected_area(node: Node, w: vec3f) -> f32 {
    let net = -node.area * dot(node.normal, w);
    let m = node.moment_a;
    let q = m.x * w.x * w.x + m.y * w.y * w.y + m.z * w.z * w.z
        + 2.0 * (m.w * w.x * w.y + node.moment_b.x * w.x * w.z + node.moment_b.y * w.y * w.z);
    return max(0.5 * (net + sqrt(max(node.area * q, 0.0))), 0.0);
}

// transfer::irradiance_from_cluster.
fn irradiance_from_cluster(p: vec3f, n: vec3f, y: vec3f, node: Node, radiance: vec3f) -> vec3f {
    let d = y - p;
    let dist2 = dot(d, d);
    if dist2 <= 0.0 {
        return vec3f(0.0);
    }
    let w = d / sqrt(dist2);
    let cos_r = max(dot(n, w), 0.0);
    return radiance * (cluster_projected_area(node, w) * cos_r / (dist2 + node.area / TRANSFER_PI));
}

// transfer::faces.
fn faces(t: Texel, p: vec3f) -> bool {
    return dot(p - t.position, t.normal) > 0.0;
}

// transfer::NEAR_FIELD_SIZES.
const NEAR_FIELD_SIZES: f32 = 3.0;

// transfer::in_near_field.
fn in_near_field(p: vec3f, y: vec3f, area: f32) -> bool {
    let d = y - p;
    return dot(d, d) < NEAR_FIELD_SIZES * NEAR_FIELD_SIZES * area;
}

// transfer::near_split_weight.
fn near_split_weight(dist: f32, radius: f32) -> f32 {
    if radius <= 0.0 {
        return 0.0;
    }
    return 1.0 - smoothstep(0.5 * radius, radius, dist);
}

// transfer::irradiance_from_footprint: Lambert's formula over the octagon of the texel's area,
// clipped to the receiver's hemisphere; xyz irradiance.
fn irradiance_from_footprint(p: vec3f, n: vec3f, y: vec3f, sender_normal: vec3f, area: f32, radiance: vec3f) -> vec3f {
    let d = y - p;
    let scale = sqrt(max(area, 0.0));
    // transfer::COPLANAR: a receiver in the texel's plane gets nothing, whatever the rounding.
    if dot(d, d) <= 0.0 || dot(sender_normal, -d) <= 1e-3 * scale {
        return vec3f(0.0);
    }
    // transfer::OCTAGON: unit area, counter-clockwise about the normal.
    let r = 0.59460355;
    let c = r * 0.70710678;
    var octagon = array<vec2f, 8>(vec2f(r, 0.0), vec2f(c, c), vec2f(0.0, r), vec2f(-c, c), vec2f(-r, 0.0), vec2f(-c, -c), vec2f(0.0, -r), vec2f(c, -c));
    let frame = tangent_frame(sender_normal);
    var clipped: array<vec3f, 9>;
    var count = 0u;
    for (var k = 0u; k < 8u; k++) {
        let ca = octagon[k];
        let cb = octagon[(k + 1u) % 8u];
        let a = d + (frame[0] * ca.x + frame[1] * ca.y) * scale;
        let b = d + (frame[0] * cb.x + frame[1] * cb.y) * scale;
        let da = dot(a, n);
        let db = dot(b, n);
        if da >= 0.0 {
            clipped[count] = a;
            count += 1u;
        }
        if (da >= 0.0) != (db >= 0.0) {
            clipped[count] = a + (b - a) * (da / (da - db));
            count += 1u;
        }
    }
    var sum = 0.0;
    for (var i = 0u; i < count; i++) {
        let a = clipped[i];
        let b = clipped[(i + 1u) % count];
        let cr = cross(a, b);
        let len = length(cr);
        if len > 0.0 {
            sum += atan2(len, dot(a, b)) * dot(n, cr) / len;
        }
    }
    return radiance * max(-0.5 * sum, 0.0);
}

// transfer::irradiance_from_texel.
fn irradiance_from_texel(p: vec3f, n: vec3f, y: vec3f, sender_normal: vec3f, area: f32, radiance: vec3f) -> vec3f {
    if in_near_field(p, y, area) {
        return irradiance_from_footprint(p, n, y, sender_normal, area, radiance);
    }
    return irradiance_from(p, n, y, sender_normal, area, radiance);
}

// transfer::jitter_hash.
fn jitter_hash(seed: u32, receiver: u32, node_index: u32) -> u32 {
    return pcg_hash(seed ^ pcg_hash(receiver ^ pcg_hash(node_index)));
}

// transfer::jitter_leaf.
fn jitter_leaf(seed: u32, receiver: u32, node_index: u32, node: Node) -> u32 {
    return node.first + jitter_hash(seed, receiver, node_index) % max(node.count, 1u);
}

// transfer::tangent_frame (Duff et al. 2017): columns 0 and 1 of the frame around `n`.
fn tangent_frame(n: vec3f) -> mat2x3f {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return mat2x3f(vec3f(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x), vec3f(b, sign + n.y * n.y * a, -n.y));
}

// transfer::jitter_in_disk: a random point of the disk of area `area` around `center` (§4.5).
fn jitter_in_disk(seed: u32, receiver: u32, node_index: u32, center: vec3f, normal: vec3f, area: f32) -> vec3f {
    let a = pcg_hash(jitter_hash(seed, receiver, node_index));
    let b = pcg_hash(a);
    let u = f32(a >> 8u) / 16777216.0;
    let v = f32(b >> 8u) / 16777216.0;
    let r = sqrt(area / TRANSFER_PI) * sqrt(u);
    let phi = 2.0 * TRANSFER_PI * v;
    let frame = tangent_frame(normal);
    return center + frame[0] * (r * cos(phi)) + frame[1] * (r * sin(phi));
}
