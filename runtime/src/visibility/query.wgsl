#import cssm::visibility::cssm_visibility
#if CSSM_COUNTERS > 0
#import cssm::visibility::cssm_work
#endif

// Answers a batch of visibility queries (tests and benchmarks): one thread per pair. Composed
// with CSSM_COUNTERS, it also writes what each query did (visibility::KernelWork).

struct QueryPair {
    sender_bary: vec3f,
    sender_triangle: u32,
    receiver: vec3f,
    _pad0: u32,
    receiver_normal: vec3f,
    _pad1: u32,
}

@group(0) @binding(0) var<storage, read> pairs: array<QueryPair>;
@group(0) @binding(1) var<storage, read_write> answers: array<f32>;
#if CSSM_COUNTERS > 0
@group(0) @binding(2) var<storage, read_write> work: array<vec4u>;
#endif

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u, @builtin(num_workgroups) groups: vec3u) {
    let i = id.x + id.y * groups.x * 64u;
    if i >= arrayLength(&pairs) {
        return;
    }
    let q = pairs[i];
    answers[i] = cssm_visibility(q.sender_triangle, q.sender_bary, q.receiver, q.receiver_normal);
#if CSSM_COUNTERS > 0
    work[i] = vec4u(cssm_work.taps, cssm_work.search_steps, cssm_work.texel_loads, cssm_work.sender_loads);
#endif
}
