#import cssm::types::View

// Composes a frame's radiance from its parts: the direct light per pixel (texture) and the
// indirect light per pixel (buffer, rgb), keeping the component asked for
// (component 0: direct, 1: indirect, 2: full). Needs types.wgsl (View).

struct ComposeParams {
    component: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: ComposeParams;
@group(0) @binding(1) var<uniform> view: View;
@group(0) @binding(2) var direct: texture_2d<f32>;
@group(0) @binding(3) var<storage, read> indirect: array<vec4f>;
@group(0) @binding(4) var radiance: texture_storage_2d<rgba32float, write>;

@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn main(@builtin(global_invocation_id) id: vec3u) {
    if id.x >= view.size.x || id.y >= view.size.y {
        return;
    }
    let d = textureLoad(direct, vec2i(id.xy), 0).rgb;
    let i = indirect[id.y * view.size.x + id.x].rgb;
    var out = d + i;
    if params.component == 0u {
        out = d;
    } else if params.component == 1u {
        out = i;
    }
    textureStore(radiance, vec2i(id.xy), vec4f(out, 1.0));
}
