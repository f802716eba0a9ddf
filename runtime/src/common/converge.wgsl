// Converged bounces: after each bounce a method's light (the sum of `after[mean_index ..
// mean_index + mean_count]`: the radiosity's hierarchy root, the area-weighted mean of every
// texel, §4.1.1; the voxel octree's first level, every leaf's light box-filtered) is compared
// with the light before it, kept in `state`. With `additive`, that sum is the light the bounce
// added alone (ssil: the top of the pyramid of the light the bounce reflects), and the light
// so far is the sum of them all. Once a bounce adds at most `fraction` of the
// light, the later bounces' main dispatches read zero workgroups from `args`, and, for a method
// that iterates between two buffers, `hold` copies the solution into the other one, so that
// whichever buffer the method reads holds it. With `fraction` 0 every bounce runs
// (`--bounces N`). CPU twin: common/converge.rs (BouncePlan::ends, added_fraction).

struct ConvergeParams {
    fraction: f32,
    // 1: the start of an iteration (reset); 0: the check after bounce `bounce`.
    start: u32,
    // Where a bounce's main dispatch arguments are read from (`work_args`, in words).
    work_index: u32,
    // Workgroups of `hold`; 0 for a method without a pair of buffers.
    hold_groups: u32,
    mean_index: u32,
    mean_count: u32,
    // The elements `hold` copies.
    count: u32,
    bounce: u32,
    // 1: the sum is the bounce's own light, added to the light so far.
    additive: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

struct ConvergeState {
    // 1 once a bounce added at most `fraction` of the light.
    done: u32,
    // Bounces computed.
    bounces: u32,
    // The share of the light the last computed bounce added.
    added: f32,
    _pad: u32,
    // The light after the last bounce computed (rgb).
    light: vec4f,
}

@group(0) @binding(0) var<uniform> params: ConvergeParams;
// The method's solution after the bounce: the light is summed from it, `hold` copies it.
@group(0) @binding(1) var<storage, read> after: array<vec4f>;
@group(0) @binding(2) var<storage, read_write> state: ConvergeState;
// Indirect dispatch arguments: [0..3] the next bounce's main dispatch, [3..6] `hold`'s.
@group(0) @binding(3) var<storage, read_write> args: array<u32, 6>;
// The main dispatch's arguments as the method computes them.
@group(0) @binding(4) var<storage, read> work_args: array<u32>;
// `hold` alone: the other buffer of the pair.
@group(0) @binding(5) var<storage, read_write> before: array<vec4f>;

// Rec. 709 luminance, as the auto exposure's (common/tonemap.rs).
fn luminance(c: vec3f) -> f32 {
    return dot(c, vec3f(0.2126, 0.7152, 0.0722));
}

fn light() -> vec3f {
    var sum = vec3f(0.0);
    for (var i = 0u; i < params.mean_count; i++) {
        sum += after[params.mean_index + i].rgb;
    }
    return sum;
}

// One thread does the test (the workgroup size is the shared one, the others return).
@compute @workgroup_size(#{WORKGROUP_1D})
fn check(@builtin(global_invocation_id) id: vec3u) {
    if id.x != 0u {
        return;
    }
    let now = light();
    if params.start != 0u {
        state.done = 0u;
        state.bounces = 0u;
        state.added = 0.0;
        state.light = vec4f(now, 0.0);
        args[0] = work_args[params.work_index];
        args[1] = work_args[params.work_index + 1u];
        args[2] = work_args[params.work_index + 2u];
        args[3] = 0u;
        args[4] = 1u;
        args[5] = 1u;
        return;
    }
    args[3] = 0u;
    if state.done != 0u {
        return;
    }
    var light_after = now;
    var total = luminance(now);
    var added = abs(total - luminance(state.light.rgb));
    if params.additive != 0u {
        light_after = state.light.rgb + now;
        total = luminance(light_after);
        added = luminance(now);
    }
    state.bounces = params.bounce;
    state.added = select(0.0, added / total, total > 0.0);
    state.light = vec4f(light_after, 0.0);
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
