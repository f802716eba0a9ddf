#define_import_path cssm::types

// Structs shared with Rust; their twins are in gpu_types.rs (a test holds the layouts together).

struct Material {
    kd: vec3f,
    ns: f32,
    ks: vec3f,
    texture: i32,
    // Emitted radiance, front side only; emission_texture: its layer in the albedo array, or -1.
    emission: vec3f,
    emission_texture: i32,
    // Emission times its texture's mean: what an atlas texel emits.
    emission_mean: vec3f,
    // Layer of the tangent-space normal map in the albedo array, or -1 (gpu_types.rs).
    normal_texture: i32,
    // Kd times its albedo texture's mean: what an atlas texel reflects in the bounces.
    kd_mean: vec3f,
    padding: u32,
}

struct SpotLight {
    position: vec3f,
    cos_cutoff: f32,
    direction: vec3f,
    normal_offset: f32,
    intensity: vec3f,
    shadow_resolution: f32,
    view_proj: mat4x4f,
    texel_solid_angle: f32,
    padding_a: f32,
    padding_b: f32,
    padding_c: f32,
}

struct View {
    view_proj: mat4x4f,
    eye: vec3f,
    light_count: u32,
    size: vec2u,
    exposure: f32,
    padding: u32,
}

struct Texel {
    position: vec3f,
    area: f32,
    normal: vec3f,
    chart: u32,
    map: u32,
    material: u32,
    x: u32,
    y: u32,
    object: u32,
    pad_x: u32,
    pad_y: u32,
    pad_z: u32,
}

struct CssmParams {
    atlas_resolution: u32,
    cube_resolution: u32,
    map_count: u32,
    pixel_count: u32,
    near: f32,
    far: f32,
    depth_scale: f32,
    bias_near: f32,
    bias_relative: f32,
    flags: u32,
    triangle_count: u32,
    runs_per_binding: u32,
}

struct Node {
    center: vec3f,
    radius: f32,
    normal: vec3f,
    cone_cos: f32,
    area: f32,
    skip: u32,
    first: u32,
    count: u32,
    representative: u32,
    padding_a: u32,
    padding_b: u32,
    padding_c: u32,
    // Its spread (gpu_types::GpuNodeSpread, computed at load): the second moment of its texel
    // normals, sum area n n^T (xx, yy, zz, xy; xz, yz), and its texel facing the most away from
    // its representative; NODE_EMITTER and NODE_ALL_EMITTERS.
    moment_a: vec4f,
    moment_b: vec2f,
    other: u32,
    flags: u32,
}

// gpu_types::NODE_EMITTER: the node holds a texel whose material emits.
const NODE_EMITTER: u32 = 1u;
// gpu_types::NODE_ALL_EMITTERS: every texel of the node emits.
const NODE_ALL_EMITTERS: u32 = 2u;

struct TraversalParams {
    receiver_count: u32,
    node_count: u32,
    threshold: f32,
    exposure: f32,
    seed: u32,
    jitter: u32,
    gather: u32,
    frame: u32,
    near_radius: f32,
    near_margin: f32,
    near_plane: f32,
    emitters: u32,
}
