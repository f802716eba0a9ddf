#import cssm::visibility::{cssm_atlas_point, cssm_senders_at, cssm_senders_texel, cssm_texels, cssm_visibility_between}
#if CSSM_COUNTERS > 0
#import cssm::visibility::cssm_work
#endif

// Benchmark kernel in the access pattern of the final gather (§4.4), one query a thread: the
// pixels of a G-buffer in 8x8 tiles, one workgroup a tile and a sender, each thread the
// two-ended query between its pixel (its own sender-filter texels, found from its atlas point)
// and the sender texel, as `lightcuts/final_gather.wgsl` asks it of a node. CPU twin:
// `visibility::tiles::tiles_cpu`.

struct TilePixel {
    position: vec3f,
    // Scene triangle under the pixel; 0xffffffff where none (sky, or a partial tile's padding).
    triangle: u32,
    normal: vec3f,
    _pad0: u32,
    bary: vec3f,
    _pad1: u32,
}

struct TileParams {
    // Entries of `pixels`: 64 a tile.
    pixels: u32,
    // Senders: texel (first + k * stride) % texel_count for k = workgroup z.
    first: u32,
    stride: u32,
    texel_count: u32,
}

@group(0) @binding(0) var<storage, read> pixels: array<TilePixel>;
@group(0) @binding(1) var<storage, read_write> answers: array<f32>;
@group(0) @binding(2) var<uniform> tiles: TileParams;
#if CSSM_COUNTERS > 0
@group(0) @binding(3) var<storage, read_write> work: array<vec4u>;
#endif

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(
    @builtin(workgroup_id) group: vec3u,
    @builtin(num_workgroups) groups: vec3u,
    @builtin(local_invocation_index) lane: u32,
) {
    let tile = group.x + group.y * groups.x;
    let i = tile * 64u + lane;
    if i >= tiles.pixels {
        return;
    }
    let slot = group.z * tiles.pixels + i;
    let q = pixels[i];
    var answer = -1.0;
    if q.triangle != 0xffffffffu {
        let sender = (tiles.first + group.z * tiles.stride) % tiles.texel_count;
        let y = cssm_texels[sender];
        answer = cssm_visibility_between(
            cssm_senders_at(cssm_atlas_point(q.triangle, q.bary)), q.position, q.normal,
            cssm_senders_texel(sender), y.position, y.normal,
        );
    }
    answers[slot] = answer;
#if CSSM_COUNTERS > 0
    work[slot] = vec4u(cssm_work.taps, cssm_work.search_steps, cssm_work.texel_loads, cssm_work.sender_loads);
#endif
}
