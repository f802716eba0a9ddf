#import cssm::types::{NODE_EMITTER, Node, TraversalParams}
#import cssm::visibility::{cssm_senders_texel, cssm_texels}
#import cssm::moving::moving_visibility_between
#import cssm::posed::posed_texel
#import cssm::transfer::{TRANSFER_PI, faces, irradiance_bound, irradiance_from_cluster, irradiance_from_texel, near_split_weight, tone_mapped}

// The radiosity's cached links (issue 49, item 1): the cut of every receiver leaf, as the
// gather (gather.wgsl) walks it, stored once with its transfer. The transfer from a node is
// its radiance times a scalar, the form factor times the visibility (§4.3), so with the cuts
// kept every bounce is a sparse matrix-vector product (product.wgsl) and a moved light re-runs
// only the direct light and the products. One thread per receiver leaf walks the hierarchy
// as gather.wgsl does, its oracle reading `cut_radiance` (the node radiance the cuts are made
// for). `params.gather & 3` says what it does:
// - 0: counts its links into its count word;
// - 1: writes them into its slot (the counts' prefix sums with slack, radiosity/links.rs);
// - 2: re-cuts it if the product flagged it stale (the oracle would refine one of its links'
//   nodes, by more than STALE_MARGIN, under the light since), in place when the new cut fits
//   its slot, else counting an overflow and keeping the old cut (links.rs then builds
//   everything again).
// With LINKS_FAR in `params.gather`, the cuts are those of `lightcuts`' far field
// (gather.wgsl with `gather` 2: the nodes reaching within `params.near_radius` refined, each
// leaf's transfer weighted by `1 - near_split_weight`, with `params.emitters` the nodes
// holding an emitter refined and its leaves left out).
// A link is (node, bitcast transfer), with beside it its node's bound of unit radiance (0 for
// a leaf), which the product's staleness test multiplies by the node's radiance. Every node of
// the cut whose unoccluded transfer is above zero has one, lit or not, so that the cut holds
// for any light the oracle lets it.
// CPU twin: radiosity/cpu_links.rs::receiver_links. Needs types.wgsl, transfer.wgsl and the CSSM
// library at group 1.

@group(0) @binding(0) var<uniform> params: TraversalParams;
@group(0) @binding(1) var<storage, read> nodes: array<Node>;
// Per leaf in leaf order: (texel, node index).
@group(0) @binding(2) var<storage, read> leaves: array<vec2u>;
// Per texel: rgb diffuse albedo (the oracle's).
@group(0) @binding(3) var<storage, read> texel_albedo: array<vec4f>;
// Per node: the rgb radiance the oracle bounds.
@group(0) @binding(4) var<storage, read> cut_radiance: array<vec4f>;
// links.rs's link table: per leaf its slot's start and its count (LINK_STALE: flagged), then
// the slots' total, the receivers flagged this iteration and the overflows.
@group(0) @binding(5) var<storage, read_write> link_table: array<atomic<u32>>;
// The links, (node, bitcast<u32>(transfer)), each leaf's in walk order from its slot's start.
@group(0) @binding(6) var<storage, read_write> links: array<vec2u>;
// Per link, its node's bound of unit radiance (transfer::irradiance_bound; 0 for a leaf).
@group(0) @binding(7) var<storage, read_write> link_bounds: array<f32>;

// links.rs::LINK_STALE: the count word's flag of a receiver whose cut went stale.
const LINK_STALE: u32 = 0x80000000u;
// links.rs::LINKS_FAR: `params.gather`'s flag of the far field's cuts.
const LINKS_FAR: u32 = 4u;

// The cut of texel `receiver` (position p, normal n, albedo rho): its link count; with
// `write`, its links stored from `first` on while they fit before `end` (the count goes on).
fn walk_links(receiver: u32, p: vec3f, n: vec3f, rho: f32, write: bool, first: u32, end: u32) -> u32 {
    let far_only = (params.gather & LINKS_FAR) != 0u;
    var count = 0u;
    var s = 0u;
    loop {
        if s >= params.node_count {
            break;
        }
        let node = nodes[s];
        let radiance = cut_radiance[s].rgb;
        // The far field's emitters, left to the pixels: refined down to and skipped.
        if far_only && params.emitters != 0u && (node.flags & NODE_EMITTER) != 0u {
            s = select(node.skip, s + 1u, node.count > 1u);
            continue;
        }
        // Refine as the gather does (§4.3, Fig. 10), the far field's near nodes too.
        if node.count > 1u && (tone_mapped(irradiance_bound(p, n, node, radiance) * (rho / TRANSFER_PI), params.exposure) > params.threshold || (far_only && length(node.center - p) - node.radius < params.near_radius)) {
            s += 1u;
            continue;
        }
        let sender = node.representative;
        if sender != receiver {
            let y = posed_texel(cssm_texels[sender]);
            // The transfer of unit radiance: the gather's with its radiance factored out.
            var unoccluded: f32;
            if node.count == 1u {
                unoccluded = irradiance_from_texel(p, n, y.position, y.normal, node.area, vec3f(1.0)).x;
                if far_only {
                    unoccluded *= 1.0 - near_split_weight(distance(y.position, p), params.near_radius);
                }
            } else {
                unoccluded = irradiance_from_cluster(p, n, y.position, node, vec3f(1.0)).x;
            }
            if unoccluded > 0.0 {
                if write && first + count < end {
                    // gather.wgsl's visibility: the cluster's texel facing the receiver, both
                    // ends and the moving objects' maps.
                    var v_sender = sender;
                    var v_y = y;
                    if node.count > 1u && !faces(y, p) {
                        let other = posed_texel(cssm_texels[node.other]);
                        if faces(other, p) {
                            v_sender = node.other;
                            v_y = other;
                        }
                    }
                    let visibility = moving_visibility_between(cssm_senders_texel(receiver), p, n, cssm_texels[receiver].object, cssm_senders_texel(v_sender), v_y.position, v_y.normal, v_y.object);
                    links[first + count] = vec2u(s, bitcast<u32>(unoccluded * visibility));
                    var bound = 0.0;
                    if node.count > 1u {
                        bound = irradiance_bound(p, n, node, vec3f(1.0)).x;
                    }
                    link_bounds[first + count] = bound;
                }
                count += 1u;
            }
        }
        s = node.skip;
    }
    return count;
}

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    let leaf = id.x;
    if leaf >= params.receiver_count {
        return;
    }
    let count_word = 2u * leaf + 1u;
    let mode = params.gather & 3u;
    if mode == 2u && (atomicLoad(&link_table[count_word]) & LINK_STALE) == 0u {
        return;
    }
    let texel = leaves[leaf].x;
    let t = posed_texel(cssm_texels[texel]);
    let albedo = texel_albedo[texel].rgb;
    let rho = max(albedo.x, max(albedo.y, albedo.z));
    // The count first (no visibility: cheap), so that a cut past its slot leaves the old one.
    let count = walk_links(texel, t.position, t.normal, rho, false, 0u, 0u);
    if mode == 0u {
        atomicStore(&link_table[count_word], count);
        return;
    }
    // The next leaf's start; after the last leaf, the slots' total.
    let first = atomicLoad(&link_table[2u * leaf]);
    let end = atomicLoad(&link_table[2u * leaf + 2u]);
    if first + count > end {
        // Past its slot: the old cut is kept, flagged, and counted (re-cutting only;
        // the full build's slots fit their counts).
        atomicAdd(&link_table[2u * params.receiver_count + 2u], 1u);
        return;
    }
    walk_links(texel, t.position, t.normal, rho, true, first, end);
    atomicStore(&link_table[count_word], count);
}
