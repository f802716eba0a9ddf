// Converged bounces: after each bounce a method compares the mean radiance of its solution (the
// hierarchy's root, which the pull leaves holding the area-weighted mean of every texel, §4.1.1)
// with the bounce before's. Once a bounce adds at most `fraction` of the light, the later
// bounces' main dispatches read zero workgroups from `args`, and `hold` copies the solution
// into the other buffer of the method's ping-pong pair, so that whichever buffer the method
// reads holds it. With `fraction` 0 every bounce runs (`--bounces N`).
// CPU twin: common/converge.rs (BouncePlan::ends, added_fraction).

struct ConvergeParams {
    fraction: f32,
    // 1: the start of an iteration (reset); 0: the check after bounce `bounce`.
    start: u32,
    // Workgroups of a bounce's main dispatch and of `hold`.
    work_groups: u32,
    hold_groups: u32,
    // Index of the mean in the pair's buffers, and the elements `hold` copies.
    mean_index: u32,
    count: u32,
    bounce: u32,
    _pad: u32,
}

struct ConvergeState {
    // 1 once a bounce added at most `fraction` of the light.
    done: u32,
    // Bounces computed.
    bounces: u32,
    // The share of the light the last computed bounce added.
    added: f32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> params: ConvergeParams;
// The solution before the bounce (written by `hold`) and after it.
@group(0) @binding(1) var<storage, read_write> before: array<vec4f>;
@group(0) @binding(2) var<storage, read> after: array<vec4f>;
@group(0) @binding(3) var<storage, read_write> state: ConvergeState;
// Indirect dispatch arguments: [0..3] the next bounce's main dispatch, [3..6] `hold`'s.
@group(0) @binding(4) var<storage, read_write> args: array<u32, 6>;

// Rec. 709 luminance, as the auto exposure's (common/tonemap.rs).
fn luminance(c: vec3f) -> f32 {
    return dot(c, vec3f(0.2126, 0.7152, 0.0722));
}

// One thread does the test (the workgroup size is the shared one, the others return).
@compute @workgroup_size(#{WORKGROUP_1D})
fn check(@builtin(global_invocation_id) id: vec3u) {
    if id.x != 0u {
        return;
    }
    if params.start != 0u {
        state.done = 0u;
        state.bounces = 0u;
        state.added = 0.0;
        args[0] = params.work_groups;
        args[1] = 1u;
        args[2] = 1u;
        args[3] = 0u;
        args[4] = 1u;
        args[5] = 1u;
        return;
    }
    args[3] = 0u;
    if state.done != 0u {
        return;
    }
    let total = luminance(after[params.mean_index].rgb);
    let added = abs(luminance(after[params.mean_index].rgb) - luminance(before[params.mean_index].rgb));
    state.bounces = params.bounce;
    state.added = select(0.0, added / total, total > 0.0);
    if params.fraction > 0.0 && added <= params.fraction * total {
        state.done = 1u;
        args[0] = 0u;
        args[3] = params.hold_groups;
    }
}

@compute @workgroup_size(#{WORKGROUP_1D})
fn hold(@builtin(global_invocation_id) id: vec3u) {
    if id.x < params.count {
        before[id.x] = after[id.x];
    }
}
