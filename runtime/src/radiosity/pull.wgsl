#import cssm::types::Node

// Pull (§4.1.1): the radiance of an inner node is the area-weighted mean of its children's,
// one level of the tree per dispatch, deepest first. CPU twin: radiosity/cpu.rs::pull.
// Needs types.wgsl (Node).

struct PullLevel {
    start: u32,
    end: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<uniform> level: PullLevel;
@group(0) @binding(1) var<storage, read> nodes: array<Node>;
// Inner nodes ordered by depth, deepest first; a level is `pull_order[start..end]`.
@group(0) @binding(2) var<storage, read> pull_order: array<u32>;
@group(0) @binding(3) var<storage, read_write> radiance: array<vec4f>;

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    let i = level.start + id.x;
    if i >= level.end {
        return;
    }
    let node = pull_order[i];
    let left = node + 1u;
    let right = nodes[left].skip;
    let a_left = nodes[left].area;
    let a_right = nodes[right].area;
    let total = a_left + a_right;
    if total > 0.0 {
        radiance[node] = (radiance[left] * a_left + radiance[right] * a_right) / total;
    } else {
        radiance[node] = 0.5 * (radiance[left] + radiance[right]);
    }
}
