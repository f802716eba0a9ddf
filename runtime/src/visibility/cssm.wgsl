#define_import_path cssm::visibility

#import cssm::types::{CssmParams, Texel}

// The CSSM visibility query (Ritschel et al. 2008, §3.2.2) in WGSL: the same computation, step
// for step, as the CPU reference `cssm_formats::visibility::VisibilityQuery`. Read that module's
// docs for the why of every step; the comments here name the CPU function each part mirrors.
//
// Needs `types.wgsl` (CssmParams, Texel). The bind group index is substituted for CSSM_GROUP
// when the library is assembled (`cssm_runtime::visibility::library_wgsl`).

@group(#{CSSM_GROUP}) @binding(0) var<uniform> cssm: CssmParams;
@group(#{CSSM_GROUP}) @binding(1) var<storage, read> cssm_texels: array<Texel>;
// Texel index of every atlas cell, 0xffffffff where undefined.
@group(#{CSSM_GROUP}) @binding(2) var<storage, read> cssm_grid: array<u32>;
// Atlas coordinates of the three corners of every scene triangle: 6 floats per triangle.
@group(#{CSSM_GROUP}) @binding(3) var<storage, read> cssm_triangle_uvs: array<f32>;
// Random-access run data (formats::cssm::RunData): per (segment, pixel) offsets into `runs`,
// runs packed as start_in_segment << 16 | depth16.
@group(#{CSSM_GROUP}) @binding(4) var<storage, read> cssm_offsets: array<u32>;
@group(#{CSSM_GROUP}) @binding(5) var<storage, read> cssm_runs: array<u32>;
// A file whose runs exceed one storage binding has them spread over several, in order,
// `cssm.runs_per_binding` runs each (load::CssmGpu; CSSM_RUN_BINDINGS of them, at most 8).
#if CSSM_RUN_BINDINGS > 1
@group(#{CSSM_GROUP}) @binding(6) var<storage, read> cssm_runs_1: array<u32>;
#endif
#if CSSM_RUN_BINDINGS > 2
@group(#{CSSM_GROUP}) @binding(7) var<storage, read> cssm_runs_2: array<u32>;
#endif
#if CSSM_RUN_BINDINGS > 3
@group(#{CSSM_GROUP}) @binding(8) var<storage, read> cssm_runs_3: array<u32>;
#endif
#if CSSM_RUN_BINDINGS > 4
@group(#{CSSM_GROUP}) @binding(9) var<storage, read> cssm_runs_4: array<u32>;
#endif
#if CSSM_RUN_BINDINGS > 5
@group(#{CSSM_GROUP}) @binding(10) var<storage, read> cssm_runs_5: array<u32>;
#endif
#if CSSM_RUN_BINDINGS > 6
@group(#{CSSM_GROUP}) @binding(11) var<storage, read> cssm_runs_6: array<u32>;
#endif
#if CSSM_RUN_BINDINGS > 7
@group(#{CSSM_GROUP}) @binding(12) var<storage, read> cssm_runs_7: array<u32>;
#endif

const CSSM_NONE: u32 = 0xffffffffu;
const CSSM_DEPTH_MAX: u32 = 65535u;
const CSSM_FLAG_PCF: u32 = 1u;
const CSSM_FLAG_SENDER_FILTER: u32 = 2u;
const CSSM_FLAG_BOTH_ENDS: u32 = 4u;
// The file's cube maps sample staggered pixel grids (cube::PixelGrid::Staggered).
const CSSM_FLAG_STAGGERED_GRID: u32 = 8u;
const CSSM_FLAG_TURNED_FRAME: u32 = 16u;

// cube::CubeFrame::TURN: the turned cube frame's rotation, world to cube (columns: the images of
// the world's x, y and z axes).
const CSSM_TURN: mat3x3f = mat3x3f(
    vec3f(0.70710677, -0.70710677, 0.0),
    vec3f(0.57735026, 0.57735026, 0.57735026),
    vec3f(-0.4082483, -0.4082483, 0.8164966),
);

// CubeFrame::to_cube: a world vector in the file's cube frame.
fn cssm_to_cube(v: vec3f) -> vec3f {
    if (cssm.flags & CSSM_FLAG_TURNED_FRAME) == 0u {
        return v;
    }
    return CSSM_TURN * v;
}
// cube::PixelGrid::STAGGER.
const CSSM_STAGGER: f32 = 0.125;
// Stands for "nothing within the far plane": larger than any receiver depth.
const CSSM_FAR_AWAY: f32 = 3.0e38;

// Run `i` of the file's run array (RunData::runs), in whichever binding holds it. With one
// binding (every file that fits one, the common case) this is a plain load.
fn cssm_run(i: u32) -> u32 {
#if CSSM_RUN_BINDINGS > 1
    let binding = i / cssm.runs_per_binding;
    let j = i - binding * cssm.runs_per_binding;
    switch binding {
        case 1u: { return cssm_runs_1[j]; }
#if CSSM_RUN_BINDINGS > 2
        case 2u: { return cssm_runs_2[j]; }
#endif
#if CSSM_RUN_BINDINGS > 3
        case 3u: { return cssm_runs_3[j]; }
#endif
#if CSSM_RUN_BINDINGS > 4
        case 4u: { return cssm_runs_4[j]; }
#endif
#if CSSM_RUN_BINDINGS > 5
        case 5u: { return cssm_runs_5[j]; }
#endif
#if CSSM_RUN_BINDINGS > 6
        case 6u: { return cssm_runs_6[j]; }
#endif
#if CSSM_RUN_BINDINGS > 7
        case 7u: { return cssm_runs_7[j]; }
#endif
        default: { return cssm_runs[j]; }
    }
#else
    return cssm_runs[i];
#endif
}

// Work counters of the query (issue 48: GPU work you can count), per invocation: composed in only
// for the counting kernels (`CSSM_COUNTERS`), where the kernel writes them out after its query;
// `cssm_formats::visibility::QueryWork` counts the same on the CPU.
#if CSSM_COUNTERS > 0
struct CssmWork {
    // Pixel tests that read the run data (don't-care pixels read nothing).
    taps: u32,
    // Binary-search steps that loaded a run.
    search_steps: u32,
    // Texel records loaded (one per sender texel asked).
    texel_loads: u32,
    // Atlas grid cells and texels' charts read, finding the senders.
    sender_loads: u32,
}
var<private> cssm_work: CssmWork;
#endif

// One step of cssm_lookup_slot's binary search over runs [first, first + count): the last run
// starting at or before `local` is kept in `found` as it is met, so no load follows the search.
// A lane whose range is empty loads nothing (a short list's lanes idle while a long one's search).
fn cssm_search_step(first: ptr<function, u32>, count: ptr<function, u32>, found: ptr<function, u32>, local: u32) {
    if *count > 0u {
        let half = *count >> 1u;
        let i = *first + half;
        let run = cssm_run(i);
#if CSSM_COUNTERS > 0
        cssm_work.search_steps += 1u;
#endif
        if (run >> 16u) <= local {
            *first = i + 1u;
            *count -= half + 1u;
            *found = run;
        } else {
            *count = half;
        }
    }
}

// RunData::lookup for the runs of slot `slot` (segment * pixel_count + pixel): the depth code of
// the last run starting at or before the map's place `local` in its segment (§3.1). A validated
// file starts every slot's runs at 0, so a step always finds one and `found`'s initial value is
// never returned.
//
// The search takes CSSM_SEARCH_STEPS steps, enough for the file's longest run list
// (`shaders::search_steps`: a list of c runs needs the bit length of c). As a loop where the
// driver allows; unrolled on llvmpipe, which ends every loop of an invocation once all its loops
// together have run 65,535 iterations (LP_MAX_TGSI_LOOP_ITERATIONS): a final gather's long cut,
// with 16 lookups per sender, went past that and silently lost most of its senders.
fn cssm_lookup_slot(slot: u32, local: u32) -> u32 {
    var first = cssm_offsets[slot];
    var count = cssm_offsets[slot + 1u] - first;
    var found = CSSM_DEPTH_MAX;
#if CSSM_SEARCH_LOOP > 0
    for (var s = 0u; s < #{CSSM_SEARCH_STEPS}u; s++) {
        if count == 0u {
            break;
        }
        cssm_search_step(&first, &count, &found, local);
    }
#else
#if CSSM_SEARCH_STEPS > 0
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 1
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 2
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 3
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 4
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 5
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 6
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 7
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 8
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 9
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 10
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 11
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 12
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 13
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 14
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 15
    cssm_search_step(&first, &count, &found, local);
#endif
#if CSSM_SEARCH_STEPS > 16
    cssm_search_step(&first, &count, &found, local);
#endif
#endif
    return found & 0xffffu;
}

// DepthQuantizer::depth.
fn cssm_depth(code: u32) -> f32 {
    if code == CSSM_DEPTH_MAX {
        return CSSM_FAR_AWAY;
    }
    return cssm.near + f32(code) / cssm.depth_scale;
}

fn cssm_axis(v: vec3f, axis: u32) -> f32 {
    if axis == 0u {
        return v.x;
    } else if axis == 1u {
        return v.y;
    }
    return v.z;
}

// cube::face_direction for a face of major axis `major` and sign `s`.
fn cssm_face_direction(major: u32, s: f32, u: f32, v: f32) -> vec3f {
    if major == 0u {
        return vec3f(s, u, v);
    } else if major == 1u {
        return vec3f(v, s, u);
    }
    return vec3f(u, v, s);
}

// cube::PixelGrid::offset: the shift of texel `t`'s pixel grid, in pixels.
fn cssm_grid_offset(t: Texel) -> vec2f {
    if (cssm.flags & CSSM_FLAG_STAGGERED_GRID) == 0u {
        return vec2f(0.0);
    }
    return vec2f(
        select(-CSSM_STAGGER, CSSM_STAGGER, t.x % 2u == 1u),
        select(-CSSM_STAGGER, CSSM_STAGGER, t.y % 2u == 1u),
    );
}

// cube::pixel_direction_at's face coordinate of pixel column (or row) `i` of an n-pixel face
// whose grid is shifted by `offset` pixels.
fn cssm_pixel_coordinate(i: u32, offset: f32, nf: f32) -> f32 {
    return (f32(i) + 0.5 + offset) / nf * 2.0 - 1.0;
}

struct CssmProjection {
    face: u32,
    u: f32,
    v: f32,
    depth: f32,
}

// cube::project.
fn cssm_project(d: vec3f) -> CssmProjection {
    let a = abs(d);
    var major = 2u;
    if a.x >= a.y && a.x >= a.z {
        major = 0u;
    } else if a.y >= a.z {
        major = 1u;
    }
    let m = cssm_axis(d, major);
    let face = major * 2u + select(0u, 1u, m < 0.0);
    let depth = abs(m);
    return CssmProjection(
        face,
        cssm_axis(d, (major + 1u) % 3u) / depth,
        cssm_axis(d, (major + 2u) % 3u) / depth,
        depth,
    );
}

// cube::pixel_index's column (or row) on an n-pixel face of a face coordinate `c` in [-1, 1],
// on a grid shifted by `offset` pixels (cube::pixel_index_at).
fn cssm_pixel_cell(c: f32, offset: f32, n: u32) -> u32 {
    let shifted = c - offset * (2.0 / f32(n));
    return u32(clamp(i32((shifted + 1.0) * 0.5 * f32(n)), 0, i32(n) - 1));
}

// What every pixel test of one query of one texel's cube map shares, worked out once
// (VisibilityQuery::answer_oriented's closures' captures): a test then does only its own
// pixel's work, from its face coordinates, with no index arithmetic to undo.
struct CssmTaps {
    // The texel's normal and the receiver's, in the cube frame.
    normal: vec3f,
    n_cube: vec3f,
    // Cube centre, receiver position and normal, in the world.
    centre: vec3f,
    p_i: vec3f,
    n_i: vec3f,
    // dot(p_i - centre, n_i): the receiver plane's distance along its normal.
    plane: f32,
    // The receiver's normal is known (receiver-plane depth).
    oriented: bool,
    depth: f32,
    bias: f32,
    // The projection's face: its major axis and sign (cube::face_axes).
    major: u32,
    sign: f32,
    // cube::dont_care_reach of the face.
    reach: f32,
    // Run-data slot of the face's first pixel, and the map's place in its segment.
    slot: u32,
    local: u32,
}

// One pixel's test, the pixel at face coordinates (u, v) and index `in_face` within the face:
// (visible, nearness), as VisibilityQuery::answer_oriented's `test`. The pixel's centre
// direction serves the don't-care test (cube::pixel_is_dont_care_at) and the ray the bake cast
// (cube::cast_direction_at) alike.
fn cssm_tap(t: CssmTaps, u: f32, v: f32, in_face: u32) -> vec2f {
    let dir = cssm_face_direction(t.major, t.sign, u, v);
    let below = dot(dir, t.normal);
    if below + t.reach < 0.0 {
        return vec2f(0.0);
    }
#if CSSM_COUNTERS > 0
    cssm_work.taps += 1u;
#endif
    let stored = cssm_depth(cssm_lookup_slot(t.slot + in_face, t.local));
    // Depth of the receiver along the ray the bake cast for the pixel (receiver-plane depth).
    var receiver = t.depth;
    if t.oriented {
        var ray = dir;
        var scale = 1.0;
        if below < 0.0 {
            ray = dir - t.normal * below;
            scale = abs(cssm_axis(ray, t.major));
        }
        let denom = dot(ray, t.n_cube);
        if abs(denom) >= 1e-4 {
            let along = t.plane / denom * scale;
            // `along` is finite here unless the inputs were not (the CPU tests is_finite).
            if along > 0.0 && along < CSSM_FAR_AWAY {
                receiver = clamp(along, 0.5 * t.depth, 1.5 * t.depth);
            }
        }
    }
    if stored >= receiver - t.bias {
        return vec2f(1.0, 0.0);
    }
    return vec2f(0.0, clamp(1.0 - stored / receiver, 0.0, 1.0));
}

// VisibilityQuery::visibility_oriented: fraction of `p_i` (normal `n_i`, or vec3f(0)) visible
// from the cube map of `texel_index`.
fn cssm_visibility_texel(texel_index: u32, p_i: vec3f, n_i: vec3f) -> f32 {
    return cssm_answer_texel(texel_index, p_i, n_i).x;
}

// VisibilityQuery::answer_oriented: cssm_visibility_texel's fraction and EndAnswer::nearness.
fn cssm_answer_texel(texel_index: u32, p_i: vec3f, n_i: vec3f) -> vec2f {
    let n = cssm.cube_resolution;
    let t = cssm_texels[texel_index];
#if CSSM_COUNTERS > 0
    cssm_work.texel_loads += 1u;
#endif
    let near = cssm.near;
    // Behind the sender's tangent plane: light leaves a surface on its front side.
    if dot(p_i - t.position, t.normal) < -near {
        return vec2f(0.0);
    }
    let centre = t.position + t.normal * near;
    let offset = cssm_grid_offset(t);
    var d = p_i - centre;
    let below = dot(d, t.normal);
    if below < 0.0 {
        d -= t.normal * below;
    }
    if dot(d, d) < near * near * 1e-6 {
        return vec2f(1.0, 0.0);
    }
    // The cube map's own frame (VisibilityQuery::answer_oriented): the lookup direction, the
    // texel's normal and the receiver's go into it; dot products of world vectors stay.
    let normal = cssm_to_cube(t.normal);
    let q = cssm_project(cssm_to_cube(d));
    let major = q.face / 2u;
    let nf = f32(n);
    let taps = CssmTaps(
        normal,
        cssm_to_cube(n_i),
        centre,
        p_i,
        n_i,
        dot(p_i - centre, n_i),
        any(n_i != vec3f(0.0)),
        q.depth,
        cssm.bias_near * near + cssm.bias_relative * q.depth,
        major,
        select(-1.0, 1.0, q.face % 2u == 0u),
        (1.0 / nf) * (abs(cssm_axis(normal, (major + 1u) % 3u)) + abs(cssm_axis(normal, (major + 2u) % 3u))),
        (t.map >> 16u) * cssm.pixel_count + q.face * n * n,
        t.map & 0xffffu,
    );
    if (cssm.flags & CSSM_FLAG_PCF) == 0u {
        let col = cssm_pixel_cell(q.u, offset.x, n);
        let row = cssm_pixel_cell(q.v, offset.y, n);
        return cssm_tap(
            taps, cssm_pixel_coordinate(col, offset.x, nf), cssm_pixel_coordinate(row, offset.y, nf),
            row * n + col,
        );
    }
    // §3.2.2 PCF: bilinear weights over the 2x2 pixel centres around the projection; the two
    // columns' and two rows' face coordinates serve the four pixels.
    let fx = clamp((q.u + 1.0) * 0.5 * nf - 0.5 - offset.x, 0.0, nf - 1.0);
    let fy = clamp((q.v + 1.0) * 0.5 * nf - 0.5 - offset.y, 0.0, nf - 1.0);
    let x0 = u32(floor(fx));
    let y0 = u32(floor(fy));
    let x1 = min(x0 + 1u, n - 1u);
    let y1 = min(y0 + 1u, n - 1u);
    let wx = fx - f32(x0);
    let wy = fy - f32(y0);
    let u0 = cssm_pixel_coordinate(x0, offset.x, nf);
    let u1 = cssm_pixel_coordinate(x1, offset.x, nf);
    let v0 = cssm_pixel_coordinate(y0, offset.y, nf);
    let v1 = cssm_pixel_coordinate(y1, offset.y, nf);
    let t00 = cssm_tap(taps, u0, v0, y0 * n + x0);
    let t10 = cssm_tap(taps, u1, v0, y0 * n + x1);
    let t01 = cssm_tap(taps, u0, v1, y1 * n + x0);
    let t11 = cssm_tap(taps, u1, v1, y1 * n + x1);
    return (1.0 - wy) * ((1.0 - wx) * t00 + wx * t10) + wy * ((1.0 - wx) * t01 + wx * t11);
}

fn cssm_cell(x: i32, y: i32) -> u32 {
    let r = i32(cssm.atlas_resolution);
    if x < 0 || y < 0 || x >= r || y >= r {
        return CSSM_NONE;
    }
#if CSSM_COUNTERS > 0
    cssm_work.sender_loads += 1u;
#endif
    return cssm_grid[u32(y * r + x)];
}

// VisibilityQuery::atlas_point.
fn cssm_atlas_point(triangle: u32, bary: vec3f) -> vec2f {
    let b = triangle * 6u;
    let a0 = vec2f(cssm_triangle_uvs[b], cssm_triangle_uvs[b + 1u]);
    let a1 = vec2f(cssm_triangle_uvs[b + 2u], cssm_triangle_uvs[b + 3u]);
    let a2 = vec2f(cssm_triangle_uvs[b + 4u], cssm_triangle_uvs[b + 5u]);
    return a0 * bary.x + a1 * bary.y + a2 * bary.z;
}

// VisibilityQuery::texel_at: the cell under the point, else the nearest defined cell within two.
fn cssm_texel_at(p: vec2f) -> u32 {
    let cx = i32(floor(p.x));
    let cy = i32(floor(p.y));
    let direct = cssm_cell(cx, cy);
    if direct != CSSM_NONE {
        return direct;
    }
    var best = CSSM_NONE;
    var best_d = 0.0;
    for (var dy = -2; dy <= 2; dy++) {
        for (var dx = -2; dx <= 2; dx++) {
            let t = cssm_cell(cx + dx, cy + dy);
            if t == CSSM_NONE {
                continue;
            }
            let c = vec2f(f32(cx + dx) + 0.5, f32(cy + dy) + 0.5) - p;
            let d = dot(c, c);
            if best == CSSM_NONE || d < best_d {
                best = t;
                best_d = d;
            }
        }
    }
    return best;
}

// VisibilityQuery::visibility_from_surface: fraction of `p_i` (normal `n_i`, or vec3f(0))
// visible from the surface point (`triangle`, `bary`), blending the cube maps of the 2x2 atlas
// texels around it (sender filtering); -1 when no texel stands for that point.
fn cssm_visibility(triangle: u32, bary: vec3f, p_i: vec3f, n_i: vec3f) -> f32 {
    if triangle >= cssm.triangle_count {
        return -1.0;
    }
    return cssm_visibility_atlas(cssm_atlas_point(triangle, bary), p_i, n_i);
}

// VisibilityQuery::sender_texels_at: the texels whose cube maps answer for the surface point
// at atlas coordinates `p` (texels), and their normalised weights (sender filtering: the 2x2
// texels around it in its chart, bilinear; weight 0: no texel). All weights are 0 when no texel
// stands for the point.
struct CssmSenders {
    texels: vec4u,
    weights: vec4f,
}

// One tap of the sender filter: the texel of cell (x, y) when it has weight and lies in `chart`.
fn cssm_sender_tap(x: i32, y: i32, weight: f32, chart: u32) -> u32 {
    if weight <= 0.0 {
        return CSSM_NONE;
    }
    let t = cssm_cell(x, y);
    if t == CSSM_NONE {
        return CSSM_NONE;
    }
#if CSSM_COUNTERS > 0
    cssm_work.sender_loads += 1u;
#endif
    return select(CSSM_NONE, t, cssm_texels[t].chart == chart);
}

fn cssm_senders_at(p: vec2f) -> CssmSenders {
    let centre = cssm_texel_at(p);
    if centre == CSSM_NONE {
        return CssmSenders(vec4u(CSSM_NONE), vec4f(0.0));
    }
    let alone = CssmSenders(vec4u(centre, CSSM_NONE, CSSM_NONE, CSSM_NONE), vec4f(1.0, 0.0, 0.0, 0.0));
    if (cssm.flags & CSSM_FLAG_SENDER_FILTER) == 0u {
        return alone;
    }
#if CSSM_COUNTERS > 0
    cssm_work.sender_loads += 1u;
#endif
    let chart = cssm_texels[centre].chart;
    let fx = p.x - 0.5;
    let fy = p.y - 0.5;
    let x0 = i32(floor(fx));
    let y0 = i32(floor(fy));
    let wx = fx - floor(fx);
    let wy = fy - floor(fy);
    let w = vec4f((1.0 - wx) * (1.0 - wy), wx * (1.0 - wy), (1.0 - wx) * wy, wx * wy);
    let t = vec4u(
        cssm_sender_tap(x0, y0, w.x, chart),
        cssm_sender_tap(x0 + 1, y0, w.y, chart),
        cssm_sender_tap(x0, y0 + 1, w.z, chart),
        cssm_sender_tap(x0 + 1, y0 + 1, w.w, chart),
    );
    let used = select(vec4f(0.0), w, t != vec4u(CSSM_NONE));
    let total = used.x + used.y + used.z + used.w;
    if total <= 0.0 {
        return alone;
    }
    return CssmSenders(t, used / total);
}

// VisibilityQuery::visibility_from_senders: the weighted mean of the senders' answers, -1 when
// there are none. A receiver that asks many queries (a final-gather pixel) finds its senders once.
fn cssm_visibility_senders(s: CssmSenders, p_i: vec3f, n_i: vec3f) -> f32 {
    return cssm_answer_senders(s, p_i, n_i).x;
}

// VisibilityQuery::answer_from_senders: (visible, nearness) summed over the senders with their
// weights; x = -1 when there are none.
fn cssm_answer_senders(s: CssmSenders, p_i: vec3f, n_i: vec3f) -> vec2f {
    if all(s.weights == vec4f(0.0)) {
        return vec2f(-1.0, 0.0);
    }
    var sum = vec2f(0.0);
    if s.weights.x > 0.0 {
        sum += s.weights.x * cssm_answer_texel(s.texels.x, p_i, n_i);
    }
    if s.weights.y > 0.0 {
        sum += s.weights.y * cssm_answer_texel(s.texels.y, p_i, n_i);
    }
    if s.weights.z > 0.0 {
        sum += s.weights.z * cssm_answer_texel(s.texels.z, p_i, n_i);
    }
    if s.weights.w > 0.0 {
        sum += s.weights.w * cssm_answer_texel(s.texels.w, p_i, n_i);
    }
    return sum;
}

// visibility::NEARER_END_WEIGHT.
const CSSM_NEARER_END_WEIGHT: f32 = 2.0;

// visibility::combine_ends: the two ends' fractions, each weighted by exp(NEARER_END_WEIGHT *
// nearness) (the end nearer the occluder sees it larger).
fn cssm_combine_ends(forward: vec2f, backward: vec2f) -> f32 {
    let weight_forward = exp(CSSM_NEARER_END_WEIGHT * forward.y);
    let weight_backward = exp(CSSM_NEARER_END_WEIGHT * backward.y);
    return (weight_forward * forward.x + weight_backward * backward.x)
        / (weight_forward + weight_backward);
}

// The one texel `t` as a point's senders (a texel's centre has no neighbours to filter with).
fn cssm_senders_texel(t: u32) -> CssmSenders {
    return CssmSenders(vec4u(t, CSSM_NONE, CSSM_NONE, CSSM_NONE), vec4f(1.0, 0.0, 0.0, 0.0));
}

// VisibilityQuery::visibility_between: `a`'s answer for `p_b` and `b`'s for `p_a` combined by
// cssm_combine_ends (CSSM_FLAG_BOTH_ENDS), else `a`'s alone; one end's alone when the other has
// no texels, -1 when neither has.
fn cssm_visibility_between(a: CssmSenders, p_a: vec3f, n_a: vec3f, b: CssmSenders, p_b: vec3f, n_b: vec3f) -> f32 {
    let forward = cssm_answer_senders(a, p_b, n_b);
    if (cssm.flags & CSSM_FLAG_BOTH_ENDS) == 0u && forward.x >= 0.0 {
        return forward.x;
    }
    let backward = cssm_answer_senders(b, p_a, n_a);
    if forward.x < 0.0 {
        return backward.x;
    }
    if backward.x < 0.0 {
        return forward.x;
    }
    return cssm_combine_ends(forward, backward);
}

// VisibilityQuery::visibility_from_atlas: cssm_visibility for the surface point at atlas
// coordinates `p` (texels), as the G-buffer stores it.
fn cssm_visibility_atlas(p: vec2f, p_i: vec3f, n_i: vec3f) -> f32 {
    return cssm_visibility_senders(cssm_senders_at(p), p_i, n_i);
}

// The paper's binary query: is `p_i` visible from the surface point (`triangle`, `bary`)?
// (PCF: at least half visible.)
fn cssm_visible(triangle: u32, bary: vec3f, p_i: vec3f, n_i: vec3f) -> bool {
    return cssm_visibility(triangle, bary, p_i, n_i) >= 0.5;
}
