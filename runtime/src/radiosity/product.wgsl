#import cssm::types::TraversalParams

// A radiosity bounce over the cached links (links.wgsl; issue 49, item 1): the sparse
// matrix-vector product of every receiver leaf's links with the node radiance of the previous
// iteration, written as the gather (gather.wgsl with `gather` 1) writes its bounce: the
// texel's indirect irradiance and its leaf node's new radiance (direct + reflected indirect),
// for the pull (pull.wgsl) to rebuild the inner nodes. No visibility is queried: the links
// hold it. Beside the product, the oracle's test on every link's node under the radiance it
// multiplies: where it would refine one (§4.3: the tone-mapped bound above the threshold) by a
// margin (its bound above STALE_MARGIN times the threshold's, linear), the receiver's cut went
// stale, and it is flagged for links.wgsl to re-cut and counted. With LINKS_FAR in
// `params.gather` the links are `lightcuts`' far field's: the product writes the texel's
// far-field irradiance alone (radiosity/far_field.rs).
// One workgroup a receiver leaf: its lanes stride over the leaf's links together (a warp's
// load reads consecutive links: a few sectors, where a thread a leaf read a sector a lane),
// then sum their parts in workgroup memory; so a launch is WORKGROUP_1D threads a leaf, not
// one (the H200 holds 270,336 resident: a thread a leaf left them idle). A bounce after the
// iteration converged does nothing (common/converge.wgsl's `done`).
// CPU twin: radiosity/cpu_links.rs::link_product and cut_is_stale (summed in link order: the
// lanes' order rounds otherwise, within float precision).

@group(0) @binding(0) var<uniform> params: TraversalParams;
// Per leaf in leaf order: (texel, node index).
@group(0) @binding(1) var<storage, read> leaves: array<vec2u>;
// Per texel: rgb direct radiance leaving it.
@group(0) @binding(2) var<storage, read> texel_direct: array<vec4f>;
// Per texel: rgb diffuse albedo.
@group(0) @binding(3) var<storage, read> texel_albedo: array<vec4f>;
// Per node: rgb mean radiance of the previous iteration.
@group(0) @binding(4) var<storage, read> radiance_in: array<vec4f>;
// Per node: this iteration's radiance (leaves written here, inner nodes by the pull).
@group(0) @binding(5) var<storage, read_write> radiance_out: array<vec4f>;
// Per texel: rgb indirect irradiance gathered in this iteration.
@group(0) @binding(6) var<storage, read_write> texel_irradiance: array<vec4f>;
// links.rs::LinkTable (see links.wgsl).
@group(0) @binding(7) var<storage, read_write> link_table: array<atomic<u32>>;
// The links, (node, bitcast<u32>(transfer)).
@group(0) @binding(8) var<storage, read> links: array<vec2u>;
// Per link, its node's bound of unit radiance (0 for a leaf).
@group(0) @binding(9) var<storage, read> link_bounds: array<f32>;
// common/converge.wgsl's state: its first word 1 once the iteration converged (the far
// field's product binds a zero).
@group(0) @binding(10) var<storage, read> converged: array<u32>;

// links.rs::LINK_STALE.
const LINK_STALE: u32 = 0x80000000u;
// links.rs::STALE_MARGIN.
const STALE_MARGIN: f32 = 16.0;
// links.rs::LINKS_FAR.
const LINKS_FAR: u32 = 4u;

const LANES: u32 = #{WORKGROUP_1D}u;

// Each lane's part: rgb irradiance, and 1 in w where one of its links went stale.
var<workgroup> parts: array<vec4f, #{WORKGROUP_1D}>;

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(workgroup_id) group: vec3u, @builtin(num_workgroups) groups: vec3u, @builtin(local_invocation_index) lane: u32) {
    // Uniform across the workgroup, so its barriers stay in uniform control flow.
    let leaf = group.x + group.y * groups.x;
    if leaf >= params.receiver_count || converged[0] != 0u {
        return;
    }
    let ln = leaves[leaf];
    let texel = ln.x;
    let albedo = texel_albedo[texel].rgb;
    let rho = max(albedo.x, max(albedo.y, albedo.z));
    // transfer::tone_mapped(exposure * bound * rho / pi) > threshold, in linear units: a
    // node's bound of unit radiance times its radiance above `limit`.
    let limit = STALE_MARGIN * pow(params.threshold, 2.2) / max(params.exposure * rho / 3.14159265358979, 1e-30);
    let first = atomicLoad(&link_table[2u * leaf]);
    let word = atomicLoad(&link_table[2u * leaf + 1u]);
    let count = word & ~LINK_STALE;
    var e = vec3f(0.0);
    var stale = false;
    for (var i = first + lane; i < first + count; i += LANES) {
        let link = links[i];
        let l = radiance_in[link.x].rgb;
        e += l * bitcast<f32>(link.y);
        stale = stale || (rho > 0.0 && max(l.x, max(l.y, l.z)) * link_bounds[i] > limit);
    }
    parts[lane] = vec4f(e, select(0.0, 1.0, stale));
    workgroupBarrier();
    for (var half = LANES / 2u; half > 0u; half /= 2u) {
        if lane < half {
            let other = parts[lane + half];
            parts[lane] = vec4f(parts[lane].rgb + other.rgb, max(parts[lane].w, other.w));
        }
        workgroupBarrier();
    }
    if lane != 0u {
        return;
    }
    let sum = parts[0];
    if sum.w > 0.0 && (word & LINK_STALE) == 0u {
        atomicStore(&link_table[2u * leaf + 1u], word | LINK_STALE);
        atomicAdd(&link_table[2u * params.receiver_count + 1u], 1u);
    }
    texel_irradiance[texel] = vec4f(sum.rgb, 1.0);
    if (params.gather & LINKS_FAR) != 0u {
        return;
    }
    radiance_out[ln.y] = vec4f(texel_direct[texel].rgb + albedo / 3.14159265358979 * sum.rgb, 1.0);
}
