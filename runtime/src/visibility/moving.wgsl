#define_import_path cssm::moving

#import cssm::visibility::{CSSM_FLAG_BOTH_ENDS, CssmSenders, cssm, cssm_answer_senders, cssm_combine_ends, cssm_visibility_between}

// Visibility among moving rigid objects (Ritschel et al. 2008, §3.3) in WGSL: the same
// computation, step for step, as the CPU reference `cssm_formats::moving::MovingQuery` and,
// for the coherent shadow maps, `cssm_formats::csm::CsmData::visibility`. Read those modules'
// docs for the why; the comments here name the CPU function each part mirrors.
//
// Bindings of `load::MovingGpu` at group MOVING_GROUP, beside the CSSM library's group.

// Where one object stands now (moving::Placement): two affine transforms as the rows of 3x4
// matrices (`row_k · (p, 1)`), and the normal matrix of the first.
struct ObjectPlacement {
    to_baked_x: vec4f,
    to_baked_y: vec4f,
    to_baked_z: vec4f,
    normal_x: vec4f,
    normal_y: vec4f,
    normal_z: vec4f,
    to_object_x: vec4f,
    to_object_y: vec4f,
    to_object_z: vec4f,
    // 0: the static part; 1 + i: rigid object i.
    group: u32,
    pad_x: u32,
    pad_y: u32,
    pad_z: u32,
}

// One object's coherent shadow map (csm::CsmData): its maps' runs lie at `runs_base` in
// `csm_runs`, their per-pixel offsets (relative to `runs_base`) at `offsets_base` in
// `csm_offsets`, the cells' map indices at `cells_base` in `csm_cells` (one segment: at most
// 65,536 maps).
struct Csm {
    center: vec3f,
    radius: f32,
    directions: u32,
    resolution: u32,
    object: u32,
    cells_base: u32,
    offsets_base: u32,
    runs_base: u32,
    pad_x: u32,
    pad_y: u32,
}

@group(#{MOVING_GROUP}) @binding(0) var<storage, read> moving_objects: array<ObjectPlacement>;
@group(#{MOVING_GROUP}) @binding(1) var<storage, read> moving_csms: array<Csm>;
@group(#{MOVING_GROUP}) @binding(2) var<storage, read> csm_cells: array<u32>;
@group(#{MOVING_GROUP}) @binding(3) var<storage, read> csm_offsets: array<u32>;
@group(#{MOVING_GROUP}) @binding(4) var<storage, read> csm_runs: array<u32>;

const CSM_DEPTH_MAX: u32 = 65535u;

fn moving_affine(r0: vec4f, r1: vec4f, r2: vec4f, p: vec3f) -> vec3f {
    let h = vec4f(p, 1.0);
    return vec3f(dot(r0, h), dot(r1, h), dot(r2, h));
}

// One step of csm_lookup's binary search over runs [first, first + count), keeping the last
// run found at or before `local` (cssm_search_step's, over the CSMs' bindings).
fn csm_search_step(first: ptr<function, u32>, count: ptr<function, u32>, found: ptr<function, u32>, local: u32) {
    if *count > 0u {
        let half = *count >> 1u;
        let i = *first + half;
        let run = csm_runs[i];
        if (run >> 16u) <= local {
            *first = i + 1u;
            *count -= half + 1u;
            *found = run;
        } else {
            *count = half;
        }
    }
}

// RunData::lookup over one CSM's single segment, as cssm_lookup_slot searches: the run found
// kept, no reload after the search (a validated CSM starts every pixel's runs at map 0). A loop
// that ends with its range where the driver allows (CSSM_SEARCH_LOOP); unrolled to 17 steps on
// llvmpipe, which ends all loops of an invocation once they have run 65,535 iterations together,
// which a gather's sender loop would reach. The CSSM's own copy reads other bindings (WGSL cannot
// pass storage arrays to functions).
fn csm_lookup(c: Csm, map: u32, pixel: u32) -> u32 {
    let slot = c.offsets_base + pixel;
    var first = c.runs_base + csm_offsets[slot];
    var count = c.runs_base + csm_offsets[slot + 1u] - first;
    var found = 0xffffu;
#if CSSM_SEARCH_LOOP > 0
    for (var s = 0u; s < 17u; s++) {
        if count == 0u {
            break;
        }
        csm_search_step(&first, &count, &found, map);
    }
#else
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
    csm_search_step(&first, &count, &found, map);
#endif
    return found & 0xffffu;
}

// csm::octahedral_direction.
fn csm_octahedral_direction(uv: vec2f) -> vec3f {
    var d = vec3f(uv.x, uv.y, 1.0 - abs(uv.x) - abs(uv.y));
    if d.z < 0.0 {
        let x = d.x;
        let y = d.y;
        d.x = (1.0 - abs(y)) * select(-1.0, 1.0, x >= 0.0);
        d.y = (1.0 - abs(x)) * select(-1.0, 1.0, y >= 0.0);
    }
    return normalize(d);
}

// csm::octahedral_uv.
fn csm_octahedral_uv(d: vec3f) -> vec2f {
    let p = d / (abs(d.x) + abs(d.y) + abs(d.z));
    if p.z >= 0.0 {
        return p.xy;
    }
    return vec2f(
        (1.0 - abs(p.y)) * select(-1.0, 1.0, p.x >= 0.0),
        (1.0 - abs(p.x)) * select(-1.0, 1.0, p.y >= 0.0),
    );
}

// csm::cell_direction.
fn csm_cell_direction(k: u32, cell: u32) -> vec3f {
    let x = cell % k;
    let y = cell / k;
    return csm_octahedral_direction(vec2f(
        (f32(x) + 0.5) / f32(k) * 2.0 - 1.0,
        (f32(y) + 0.5) / f32(k) * 2.0 - 1.0,
    ));
}

// csm::image_frame (Duff et al. 2017).
fn csm_image_frame(d: vec3f) -> mat2x3f {
    let sign = select(-1.0, 1.0, d.z >= 0.0);
    let a = -1.0 / (sign + d.z);
    let b = d.x * d.y * a;
    return mat2x3f(vec3f(1.0 + sign * d.x * d.x * a, sign * b, -sign * d.x), vec3f(b, sign + d.y * d.y * a, -d.y));
}

// CsmData::map_visibility: the map of cell `cell` as a shadow map of a light far along its -d,
// 2x2 percentage-closer filtering.
fn csm_map_visibility(c: Csm, cell: u32, light: vec3f, receiver: vec3f) -> f32 {
    let res = c.resolution;
    let d = csm_cell_direction(c.directions, cell);
    let frame = csm_image_frame(d);
    let origin = c.center - d * c.radius;
    let light_depth = dot(light - origin, d);
    let receiver_depth = dot(receiver - origin, d);
    let map = csm_cells[c.cells_base + cell];
    let r = receiver - origin;
    let fx = (dot(r, frame[0]) / c.radius + 1.0) * 0.5 * f32(res) - 0.5;
    let fy = (dot(r, frame[1]) / c.radius + 1.0) * 0.5 * f32(res) - 0.5;
    if !(fx > -1.0 && fy > -1.0 && fx < f32(res) && fy < f32(res)) {
        return 1.0;
    }
    let x0 = floor(fx);
    let y0 = floor(fy);
    let wx = fx - x0;
    let wy = fy - y0;
    let x = i32(x0);
    let y = i32(y0);
    let depths = vec2f(light_depth, receiver_depth);
#if CSSM_SEARCH_LOOP > 0
    // One copy of the tap (and of its search) where loops are allowed: the driver would otherwise
    // inline four searches per map, sixteen per CSM, for every CSM of the scene.
    var clear: vec4f;
    for (var k = 0; k < 4; k++) {
        clear[k] = csm_tap(c, map, x + (k & 1), y + (k >> 1u), depths);
    }
#else
    let clear = vec4f(
        csm_tap(c, map, x, y, depths),
        csm_tap(c, map, x + 1, y, depths),
        csm_tap(c, map, x, y + 1, depths),
        csm_tap(c, map, x + 1, y + 1, depths),
    );
#endif
    return (1.0 - wy) * ((1.0 - wx) * clear.x + wx * clear.y) + wy * ((1.0 - wx) * clear.z + wx * clear.w);
}

// One pixel of csm_map_visibility: 0 where the stored depth lies between the light's and the
// receiver's depth (`depths`), by more than half a code of bias; 1 off the map.
fn csm_tap(c: Csm, map: u32, x: i32, y: i32, depths: vec2f) -> f32 {
    let res = i32(c.resolution);
    if x < 0 || y < 0 || x >= res || y >= res {
        return 1.0;
    }
    let code = csm_lookup(c, map, u32(y * res + x));
    if code == CSM_DEPTH_MAX {
        return 1.0;
    }
    let z = f32(code) / (f32(CSM_DEPTH_MAX) / (2.0 * c.radius));
    let bias = c.radius / f32(CSM_DEPTH_MAX);
    if z > depths.x + bias && z < depths.y - bias {
        return 0.0;
    }
    return 1.0;
}

// CsmData::visibility: the four direction cells around `receiver - light`, bilinear over the
// octahedral map.
fn csm_visibility(c: Csm, light: vec3f, receiver: vec3f) -> f32 {
    let k = c.directions;
    let w = receiver - light;
    if dot(w, w) <= 0.0 {
        return 1.0;
    }
    let uv = csm_octahedral_uv(normalize(w));
    let top = f32(k - 1u);
    let fx = clamp((uv.x + 1.0) * 0.5 * f32(k) - 0.5, 0.0, top);
    let fy = clamp((uv.y + 1.0) * 0.5 * f32(k) - 0.5, 0.0, top);
    let x0 = u32(floor(fx));
    let y0 = u32(floor(fy));
    let x1 = min(x0 + 1u, k - 1u);
    let y1 = min(y0 + 1u, k - 1u);
    let wx = fx - f32(x0);
    let wy = fy - f32(y0);
#if CSSM_SEARCH_LOOP > 0
    // The four cells through one copy of csm_map_visibility, combined as below.
    let cells = vec4u(y0 * k + x0, y0 * k + x1, y1 * k + x0, y1 * k + x1);
    var seen: vec4f;
    for (var corner = 0u; corner < 4u; corner++) {
        seen[corner] = csm_map_visibility(c, cells[corner], light, receiver);
    }
    return (1.0 - wy) * ((1.0 - wx) * seen.x + wx * seen.y) + wy * ((1.0 - wx) * seen.z + wx * seen.w);
#else
    return (1.0 - wy) * ((1.0 - wx) * csm_map_visibility(c, y0 * k + x0, light, receiver)
            + wx * csm_map_visibility(c, y0 * k + x1, light, receiver))
        + wy * ((1.0 - wx) * csm_map_visibility(c, y1 * k + x0, light, receiver)
            + wx * csm_map_visibility(c, y1 * k + x1, light, receiver));
#endif
}

// MovingQuery::to_baked: a point and its normal in the frame `object` was baked in; the static
// part (group 0) never moves, its points pass unchanged.
fn moving_to_baked(object: u32, p: vec3f) -> vec3f {
    let o = moving_objects[object];
    if o.group == 0u {
        return p;
    }
    return moving_affine(o.to_baked_x, o.to_baked_y, o.to_baked_z, p);
}

fn moving_normal_to_baked(object: u32, n: vec3f) -> vec3f {
    let o = moving_objects[object];
    if o.group == 0u {
        return n;
    }
    let m = vec3f(dot(o.normal_x.xyz, n), dot(o.normal_y.xyz, n), dot(o.normal_z.xyz, n));
    let len = length(m);
    if len > 0.0 {
        return m / len;
    }
    return n;
}

// MovingQuery::visibility_between: the fraction of the segment between a surface point on
// `object_a` and one on `object_b` (world space now) that is clear, -1 when neither end has
// texels.
fn moving_visibility_between(
    a: CssmSenders, p_a: vec3f, n_a: vec3f, object_a: u32,
    b: CssmSenders, p_b: vec3f, n_b: vec3f, object_b: u32,
) -> f32 {
#if MOVING_CSMS == 0
    // No moving object (each has a CSM): every point lies on the static part, and the query is
    // the CSSM's alone; a static scene's modules carry only its code.
    return cssm_visibility_between(a, p_a, n_a, b, p_b, n_b);
#else
    let group_a = moving_objects[object_a].group;
    let group_b = moving_objects[object_b].group;
    // Each end's maps answer for the other end, in the end's own baked frame (one frame when
    // both lie on one object).
    let forward_answer = cssm_answer_senders(a, moving_to_baked(object_a, p_b), moving_normal_to_baked(object_a, n_b));
    let backward_answer = cssm_answer_senders(b, moving_to_baked(object_b, p_a), moving_normal_to_baked(object_b, n_a));
    let forward = forward_answer.x;
    let backward = backward_answer.x;
    var own: f32;
    if group_a == group_b {
        // cssm_visibility_between's combination: cssm_combine_ends (CSSM_FLAG_BOTH_ENDS), else
        // the sender's alone; one end's when the other has no texels.
        if forward < 0.0 {
            own = backward;
        } else if backward < 0.0 || (cssm.flags & CSSM_FLAG_BOTH_ENDS) == 0u {
            own = forward;
        } else {
            own = cssm_combine_ends(forward_answer, backward_answer);
        }
    } else if forward >= 0.0 && backward >= 0.0 {
        own = forward * backward;
    } else {
        own = max(forward, backward);
    }
    if own < 0.0 {
        return -1.0;
    }
    let groups = vec2u(group_a, group_b);
    let count = arrayLength(&moving_csms);
    var clear = own;
#if CSSM_SEARCH_LOOP > 0
    // The CSMs in a loop through one copy of the step (§3.3's product over the other objects):
    // code that does not grow with the objects, where the driver allows loops.
    for (var i = 0u; i < #{MOVING_CSMS}u; i++) {
        clear = moving_csm_step(i, count, groups, p_a, p_b, clear);
    }
#else
    // One step per CSM of the file (MOVING_CSMS, a composition constant) on llvmpipe, whose
    // loop limit a gather would reach; a static scene's modules carry none of this code.
#if MOVING_CSMS > 0
    clear = moving_csm_step(0u, count, groups, p_a, p_b, clear);
#endif
#if MOVING_CSMS > 1
    clear = moving_csm_step(1u, count, groups, p_a, p_b, clear);
#endif
#if MOVING_CSMS > 2
    clear = moving_csm_step(2u, count, groups, p_a, p_b, clear);
#endif
#if MOVING_CSMS > 3
    clear = moving_csm_step(3u, count, groups, p_a, p_b, clear);
#endif
#if MOVING_CSMS > 4
    clear = moving_csm_step(4u, count, groups, p_a, p_b, clear);
#endif
#if MOVING_CSMS > 5
    clear = moving_csm_step(5u, count, groups, p_a, p_b, clear);
#endif
#if MOVING_CSMS > 6
    clear = moving_csm_step(6u, count, groups, p_a, p_b, clear);
#endif
#if MOVING_CSMS > 7
    clear = moving_csm_step(7u, count, groups, p_a, p_b, clear);
#endif
#endif
    return clear;
#endif
}

// One rigid object of moving_visibility_between's second step (one copy per CSM):
// `clear` times CSM `i`'s answer, unless it is one of the ends' objects or past the last.
fn moving_csm_step(i: u32, count: u32, groups: vec2u, p_a: vec3f, p_b: vec3f, clear: f32) -> f32 {
    if i >= count || clear <= 0.0 {
        return clear;
    }
    let c = moving_csms[i];
    let o = moving_objects[c.object];
    // A scene without moving objects binds one placeholder of no directions.
    if c.directions == 0u || o.group == groups.x || o.group == groups.y {
        return clear;
    }
    return clear * csm_visibility(
        c,
        moving_affine(o.to_object_x, o.to_object_y, o.to_object_z, p_a),
        moving_affine(o.to_object_x, o.to_object_y, o.to_object_z, p_b),
    );
}
