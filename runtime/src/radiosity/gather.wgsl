#import cssm::types::{NODE_EMITTER, Node, TraversalParams}
#import cssm::visibility::{cssm_senders_texel, cssm_texels}
#import cssm::moving::moving_visibility_between
#import cssm::posed::posed_texel
#import cssm::transfer::{TRANSFER_PI, faces, irradiance_bound, irradiance_from_cluster, irradiance_from_texel, near_split_weight, tone_mapped}

// GPU hierarchical radiosity with clustering (§4.1.1, §4.3): one thread per receiver leaf
// (texel) walks the hierarchy without a stack from the root, refining a sender while the oracle
// says so, else gathering from it with the clamped form factor (a single texel near the receiver: its
// footprint's exact form factor) and CSSM visibility, then
// skipping its subtree (Fig. 10). Writes the texel's indirect irradiance and its leaf node's
// new radiance (direct + reflected indirect); the pull pass (pull.wgsl) then rebuilds the
// inner nodes. Texels of moving objects transfer light where their objects stand now
// (posed.wgsl; the nodes' bounds refitted around them, radiosity::MovingTexels, §3.3).
// With `params.gather` 2 it gathers the far field only, for `lightcuts`' texture-space final
// gather (lightcuts/mod.rs): every node reaching within `params.near_radius` of the receiver is
// refined down to its leaves, each leaf sends `1 - near_split_weight` of its light, with
// `params.emitters` every emitter's light is left out (the nodes holding one refined, its
// leaves skipped), and the texel's irradiance is all it writes (the pixels gather the rest
// themselves).
// CPU twin: radiosity/cpu.rs::gather_texel.
// Needs types.wgsl, transfer.wgsl and the CSSM library at group 1.

@group(0) @binding(0) var<uniform> params: TraversalParams;
@group(0) @binding(1) var<storage, read> nodes: array<Node>;
// Per leaf in leaf order: (texel, node index).
@group(0) @binding(2) var<storage, read> leaves: array<vec2u>;
// Per texel: rgb direct radiance leaving it.
@group(0) @binding(3) var<storage, read> texel_direct: array<vec4f>;
// Per texel: rgb diffuse albedo.
@group(0) @binding(4) var<storage, read> texel_albedo: array<vec4f>;
// Per node: rgb mean radiance of the previous iteration.
@group(0) @binding(5) var<storage, read> radiance_in: array<vec4f>;
// Per node: this iteration's radiance (leaves written here, inner nodes by the pull).
@group(0) @binding(6) var<storage, read_write> radiance_out: array<vec4f>;
// Per texel: rgb indirect irradiance gathered in this iteration.
@group(0) @binding(7) var<storage, read_write> texel_irradiance: array<vec4f>;

// Irradiance at texel `receiver` (position p, normal n, albedo rho) from the whole scene.
fn gather_texel(receiver: u32, p: vec3f, n: vec3f, rho: f32) -> vec3f {
    let far_only = params.gather == 2u;
    var e = vec3f(0.0);
    var s = 0u;
    loop {
        if s >= params.node_count {
            break;
        }
        let node = nodes[s];
        let radiance = radiance_in[s].rgb;
        // The emitters' light, left to the pixels: refine down to it and skip it.
        if far_only && params.emitters != 0u && (node.flags & NODE_EMITTER) != 0u {
            s = select(node.skip, s + 1u, node.count > 1u);
            continue;
        }
        // Refine: descend into the left child (§4.3, Fig. 10); for the far field, also every
        // node reaching into the near field, whose leaves the split weighs one by one.
        if node.count > 1u && (tone_mapped(irradiance_bound(p, n, node, radiance) * (rho / TRANSFER_PI), params.exposure) > params.threshold || (far_only && length(node.center - p) - node.radius < params.near_radius)) {
            s += 1u;
            continue;
        }
        // Gather from the node, then skip its subtree.
        let sender = node.representative;
        if sender != receiver && any(radiance > vec3f(0.0)) {
            let y = posed_texel(cssm_texels[sender]);
            // A single texel's footprint is integrated in its near field (transfer.rs).
            var unoccluded: vec3f;
            if node.count == 1u {
                unoccluded = irradiance_from_texel(p, n, y.position, y.normal, node.area, radiance);
                if far_only {
                    unoccluded *= 1.0 - near_split_weight(distance(y.position, p), params.near_radius);
                }
            } else {
                unoccluded = irradiance_from_cluster(p, n, y.position, node, radiance);
            }
            if any(unoccluded > vec3f(0.0)) {
                // A cluster seen from the other side than its representative's: the visibility
                // of its texel facing the receiver (transfer.rs::visibility_sender).
                var v_sender = sender;
                var v_y = y;
                if node.count > 1u && !faces(y, p) {
                    let other = posed_texel(cssm_texels[node.other]);
                    if faces(other, p) {
                        v_sender = node.other;
                        v_y = other;
                    }
                }
                // Both ends' cube maps when the flags ask (CSSM_FLAG_BOTH_ENDS), each object's
                // own and the other moving objects' CSMs (§3.3).
                let visibility = moving_visibility_between(cssm_senders_texel(receiver), p, n, cssm_texels[receiver].object, cssm_senders_texel(v_sender), v_y.position, v_y.normal, v_y.object);
                e += unoccluded * visibility;
            }
        }
        s = node.skip;
    }
    return e;
}

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    let leaf = id.x;
    if leaf >= params.receiver_count {
        return;
    }
    let ln = leaves[leaf];
    let texel = ln.x;
    let t = posed_texel(cssm_texels[texel]);
    let albedo = texel_albedo[texel].rgb;
    var e = vec3f(0.0);
    if params.gather != 0u {
        e = gather_texel(texel, t.position, t.normal, max(albedo.x, max(albedo.y, albedo.z)));
    }
    texel_irradiance[texel] = vec4f(e, 1.0);
    if params.gather == 2u {
        return;
    }
    radiance_out[ln.y] = vec4f(texel_direct[texel].rgb + albedo / TRANSFER_PI * e, 1.0);
}
