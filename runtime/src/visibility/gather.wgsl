#import cssm::visibility::cssm_visibility_texel

// Benchmark kernel in the access pattern of a final gather (§4.4): every receiver (a G-buffer
// pixel, here a surface point) queries `senders` consecutive sender texels of the depth-map
// sequence, as a receiver tile gathering from one cut of the hierarchy does, and sums the
// visible fractions. Neighbouring receivers share their senders, so the run data they read is
// shared too.

struct Receiver {
    position: vec3f,
    first_sender: u32,
    normal: vec3f,
    _pad: u32,
}

struct GatherParams {
    senders: u32,
    texel_count: u32,
    _pad0: u32,
    _pad1: u32,
}

@group(0) @binding(0) var<storage, read> receivers: array<Receiver>;
@group(0) @binding(1) var<storage, read_write> gathered: array<f32>;
@group(0) @binding(2) var<uniform> gather: GatherParams;

@compute @workgroup_size(#{WORKGROUP_1D})
fn main(@builtin(global_invocation_id) id: vec3u, @builtin(num_workgroups) groups: vec3u) {
    let i = id.x + id.y * groups.x * 64u;
    if i >= arrayLength(&receivers) {
        return;
    }
    let r = receivers[i];
    var sum = 0.0;
    for (var k = 0u; k < gather.senders; k++) {
        let texel = (r.first_sender + k) % gather.texel_count;
        sum += cssm_visibility_texel(texel, r.position, r.normal);
    }
    gathered[i] = sum;
}
