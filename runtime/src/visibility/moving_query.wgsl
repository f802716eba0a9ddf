#import cssm::visibility::{cssm_atlas_point, cssm_senders_at}
#import cssm::moving::moving_visibility_between

// Answers a batch of visibility queries between posed surface points (tests and benchmarks):
// one thread per pair.

struct MovingEnd {
    bary: vec3f,
    triangle: u32,
    position: vec3f,
    object: u32,
    normal: vec3f,
    _pad: u32,
}

struct MovingPair {
    a: MovingEnd,
    b: MovingEnd,
}

@group(0) @binding(0) var<storage, read> pairs: array<MovingPair>;
@group(0) @binding(1) var<storage, read_write> answers: array<f32>;

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u, @builtin(num_workgroups) groups: vec3u) {
    let i = id.x + id.y * groups.x * 64u;
    if i >= arrayLength(&pairs) {
        return;
    }
    let q = pairs[i];
    answers[i] = moving_visibility_between(
        cssm_senders_at(cssm_atlas_point(q.a.triangle, q.a.bary)), q.a.position, q.a.normal, q.a.object,
        cssm_senders_at(cssm_atlas_point(q.b.triangle, q.b.bary)), q.b.position, q.b.normal, q.b.object,
    );
}
