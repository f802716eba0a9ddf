#import cssm::types::{Material, NODE_ALL_EMITTERS, NODE_EMITTER, Node, TraversalParams, View}
#import cssm::visibility::{CssmSenders, cssm_senders_at, cssm_senders_texel, cssm_texels}
#import cssm::moving::moving_visibility_between
#import cssm::posed::posed_texel
#import cssm::lowres::lowres_representative
#import cssm::atlas_filter::atlas_lookup
#import cssm::transfer::{phong_lobe, brdf_bound, faces, in_near_field, irradiance_bound, irradiance_from, irradiance_from_cluster, irradiance_from_footprint, irradiance_from_texel, jitter_in_disk, jitter_leaf, near_split_weight, tone_mapped}

// Final gathering per pixel (§4.4.1), in one of two forms (`grid.mode`):
// - 0, the walk: the stackless traversal of Fig. 10 from the G-buffer pixel instead of a
//   receiver leaf, the oracle bounding the normalised Phong BRDF so glossy surfaces refine
//   towards their highlight; each node of the cut is a VPL holding the direct light and the
//   diffuse bounces of the radiosity iteration. With jittering (§4.5) every sender is a random
//   point of a random texel of its node and frames are averaged progressively.
// - 1, texture space with a per-pixel near field: the irradiance is the atlas's far field
//   (`atlas_values`, gathered once per texel by the far-field pass, radiosity/gather.wgsl with
//   `gather` 2), looked up with the bicubic filter, plus the pixel's own near field: the leaves
//   within `params.near_radius`, weighted by `near_split_weight`, so that the two halves sum to
//   the whole transfer. Only what changes within a texel or two is gathered per pixel. With
//   `params.emitters` the emitters' light is the pixel's too (left out of the far field and
//   the near field): a walk over the nodes holding emitters, refining every node that mixes
//   them with other texels, so that a lamp's shadows are the pixel's, not the texels'. A
//   glossy pixel (Ks above 0) walks for its lobe alone, the oracle bounding its lobe only.
// Senders on moving objects send from where their objects stand now (posed.wgsl, §3.3).
// CPU twin: lightcuts/cpu.rs::gather_planes. Needs types.wgsl, transfer.wgsl, the CSSM library
// at group 1 and the moving objects' (moving.wgsl) at group 2.

@group(0) @binding(0) var<uniform> params: TraversalParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var<storage, read> nodes: array<Node>;
@group(0) @binding(3) var<storage, read> leaves: array<vec2u>;
@group(0) @binding(4) var<storage, read> radiance: array<vec4f>;
@group(0) @binding(5) var<storage, read> materials: array<Material>;
@group(0) @binding(6) var gbuffer_position: texture_2d<f32>;
@group(0) @binding(7) var gbuffer_normal: texture_2d<f32>;
@group(0) @binding(8) var gbuffer_albedo: texture_2d<f32>;
@group(0) @binding(9) var gbuffer_atlas: texture_2d<f32>;
// Two planes at the gather's resolution (progressive means over frames): the irradiance (w: the
// cut size), then the irradiance weighted by the pixel's normalised Phong lobe towards the eye;
// `common/resolve.wgsl` reflects them with the full-res albedo and Ks (after the edge-aware
// filters when the gather runs at a reduced resolution).
@group(0) @binding(10) var<storage, read_write> planes: array<vec4f>;
@group(0) @binding(11) var<uniform> grid: GatherGrid;
// The near lists in one buffer (lightcuts/near.rs, `NearLists::packed`; one buffer, not two,
// to keep within the runtime's 12 storage buffers a stage): per texel the index in this array
// where its list starts, and one past the last texel, then the lists' leaf nodes. Unread
// without lists (`params.near_margin` 0).
@group(0) @binding(12) var<storage, read> near_lists: array<u32>;

struct GatherGrid {
    // The gather's resolution: the G-buffer's reduced by `factor` per side.
    low_size: vec2u,
    factor: u32,
    // 0: the walk; 1: the atlas's far field and the pixel's near field.
    mode: u32,
}

// Where the pixel's end of every visibility query lies: its texels (the sender filter's four
// slots, found once for all its senders) and the object they lie on (a point without texels
// answers unshadowed).
struct PixelEnd {
    senders: CssmSenders,
    object: u32,
}

fn pixel_end(atlas: vec2f) -> PixelEnd {
    let senders = cssm_senders_at(atlas);
    var object = 0u;
    if senders.weights.x > 0.0 {
        object = cssm_texels[senders.texels.x].object;
    }
    return PixelEnd(senders, object);
}

// The light of leaf node `s` at the pixel at `p` weighted by `near_split_weight`, with its
// footprint's transfer (transfer.rs::irradiance_from_texel) and both ends' visibility; none
// from an emitter the pixel gathers apart (`params.emitters`).
fn near_leaf(s: u32, p: vec3f, n: vec3f, end: PixelEnd) -> vec3f {
    let node = nodes[s];
    if params.emitters != 0u && (node.flags & NODE_EMITTER) != 0u {
        return vec3f(0.0);
    }
    let l = radiance[s].rgb;
    let y = posed_texel(cssm_texels[node.representative]);
    let w = near_split_weight(distance(y.position, p), params.near_radius);
    if w <= 0.0 || !any(l > vec3f(0.0)) {
        return vec3f(0.0);
    }
    let unoccluded = w * irradiance_from_texel(p, n, y.position, y.normal, node.area, l);
    if !any(unoccluded > vec3f(0.0)) {
        return vec3f(0.0);
    }
    var visibility = moving_visibility_between(end.senders, p, n, end.object, cssm_senders_texel(node.representative), y.position, y.normal, y.object);
    if visibility < 0.0 {
        visibility = 1.0;
    }
    return unoccluded * visibility;
}

// The near field of the pixel at `p`: every leaf within `params.near_radius`. A pixel near its
// texel's centre and in its plane reads the texel's near list (lightcuts/near.rs: the leaves
// within reach, its own plane's left out); any other walks the hierarchy, descending only into
// nodes reaching within the radius.
fn near_field(p: vec3f, n: vec3f, end: PixelEnd) -> vec3f {
    var e = vec3f(0.0);
    if params.near_margin > 0.0 && end.senders.weights.x > 0.0 {
        let t = end.senders.texels.x;
        let texel = cssm_texels[t];
        let d = p - texel.position;
        if length(d) <= params.near_margin && abs(dot(d, texel.normal)) <= params.near_plane {
            for (var i = near_lists[t]; i < near_lists[t + 1u]; i++) {
                e += near_leaf(near_lists[i], p, n, end);
            }
            return e;
        }
    }
    let radius = params.near_radius;
    var s = 0u;
    loop {
        if s >= params.node_count {
            break;
        }
        let node = nodes[s];
        if length(node.center - p) - node.radius >= radius {
            s = node.skip;
            continue;
        }
        if node.count > 1u {
            s += 1u;
            continue;
        }
        e += near_leaf(s, p, n, end);
        s = node.skip;
    }
    return e;
}

struct Gathered {
    irradiance: vec3f,
    lobe_weighted: vec3f,
    cut: u32,
}

// The walk: the indirect light arriving at `p` (its irradiance, and its irradiance weighted by
// the Phong lobe towards `v`), and the cut size; the radiance towards `v` is
// albedo / pi * irradiance + ks * lobe_weighted. The oracle bounds the BRDF of `albedo` and
// the material's lobe (a zero `albedo`: the lobe's alone). With `emitters_only`, the
// emitters' light alone: nodes holding none skipped, nodes mixing them with other texels
// refined.
fn gather_pixel(receiver: u32, p: vec3f, n: vec3f, v: vec3f, albedo: vec3f, m: Material, end: PixelEnd, emitters_only: bool) -> Gathered {
    let senders = end.senders;
    let object = end.object;
    var irradiance = vec3f(0.0);
    var lobe_weighted = vec3f(0.0);
    var cut = 0u;
    var s = 0u;
    loop {
        if s >= params.node_count {
            break;
        }
        let node = nodes[s];
        if emitters_only && (node.flags & NODE_EMITTER) == 0u {
            s = node.skip;
            continue;
        }
        let l = radiance[s].rgb;
        var refine = false;
        if emitters_only && node.count > 1u && (node.flags & NODE_ALL_EMITTERS) == 0u {
            refine = true;
        } else if node.count > 1u {
            let bound = irradiance_bound(p, n, node, l) * brdf_bound(n, v, albedo, m.ks, m.ns, node.center - p, node.radius);
            refine = tone_mapped(bound, params.exposure) > params.threshold;
        }
        if refine {
            s += 1u;
        } else {
            cut += 1u;
            var sender = node.representative;
            if params.jitter != 0u && node.count > 1u {
                sender = leaves[jitter_leaf(params.seed, receiver, s, node)].x;
            }
            if any(l > vec3f(0.0)) {
                let y = posed_texel(cssm_texels[sender]);
                var y_position = y.position;
                var e: vec3f;
                if node.count == 1u && in_near_field(p, y.position, node.area) {
                    // The texel's footprint integrated exactly: what jittering would average to.
                    e = irradiance_from_footprint(p, n, y.position, y.normal, node.area, l);
                } else {
                    if params.jitter != 0u {
                        y_position = jitter_in_disk(params.seed, receiver, s, y.position, y.normal, y.area);
                    }
                    if node.count > 1u {
                        e = irradiance_from_cluster(p, n, y_position, node, l);
                    } else {
                        e = irradiance_from(p, n, y_position, node.normal, node.area, l);
                    }
                }
                if any(e > vec3f(0.0)) {
                    // Unjittered, a cluster seen from the other side than its representative's:
                    // the visibility of its texel facing the receiver
                    // (transfer.rs::visibility_sender).
                    var v_sender = sender;
                    var v_y = y;
                    var v_position = y_position;
                    if params.jitter == 0u && node.count > 1u && !faces(y, p) {
                        let other = posed_texel(cssm_texels[node.other]);
                        if faces(other, p) {
                            v_sender = node.other;
                            v_y = other;
                            v_position = other.position;
                        }
                    }
                    // The pixel's texels and the sender's (both ends, CSSM_FLAG_BOTH_ENDS), each
                    // object's own and the other moving objects' CSMs (§3.3).
                    var visibility = moving_visibility_between(senders, p, n, object, cssm_senders_texel(v_sender), v_position, v_y.normal, v_y.object);
                    // No texel stands for the point (far outside its chart): unshadowed.
                    if visibility < 0.0 {
                        visibility = 1.0;
                    }
                    let w = normalize(y_position - p);
                    irradiance += e * visibility;
                    lobe_weighted += phong_lobe(n, v, w, m.ns) * e * visibility;
                }
            }
            s = node.skip;
        }
    }
    return Gathered(irradiance, lobe_weighted, cut);
}

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= grid.low_size.x || id.y >= grid.low_size.y {
        return;
    }
    // The full-res pixel this gather pixel stands for (itself at factor 1).
    let at = lowres_representative(id.xy, grid.factor, view.size);
    let pixel = at.y * view.size.x + at.x;
    let xy = vec2i(at);
    let position = textureLoad(gbuffer_position, xy, 0);
    var value = Gathered(vec3f(0.0), vec3f(0.0), 0u);
    if position.w > 0.0 {
        let normal = textureLoad(gbuffer_normal, xy, 0);
        let albedo = textureLoad(gbuffer_albedo, xy, 0).rgb;
        let atlas = textureLoad(gbuffer_atlas, xy, 0).xy;
        let m = materials[u32(normal.w)];
        let v = normalize(view.eye - position.xyz);
        let end = pixel_end(atlas);
        if grid.mode == 0u {
            value = gather_pixel(pixel, position.xyz, normal.xyz, v, albedo, m, end, false);
        } else {
            if any(m.ks > vec3f(0.0)) {
                value = gather_pixel(pixel, position.xyz, normal.xyz, v, vec3f(0.0), m, end, false);
            }
            value.irradiance = atlas_lookup(atlas, true) + near_field(position.xyz, normal.xyz, end);
            if params.emitters != 0u {
                let emitted = gather_pixel(pixel, position.xyz, normal.xyz, v, albedo, m, end, true);
                value.irradiance += emitted.irradiance;
                value.cut += emitted.cut;
            }
        }
    }
    // Progressive mean over the frames of a still camera (§4.5).
    let index = id.y * grid.low_size.x + id.x;
    let plane = grid.low_size.x * grid.low_size.y;
    let k = f32(params.frame);
    let first = params.frame == 0u;
    let irradiance = vec4f(value.irradiance, f32(value.cut));
    let lobe_weighted = vec4f(value.lobe_weighted, 0.0);
    planes[index] = select((planes[index] * k + irradiance) / (k + 1.0), irradiance, first);
    planes[plane + index] = select((planes[plane + index] * k + lobe_weighted) / (k + 1.0), lobe_weighted, first);
}
