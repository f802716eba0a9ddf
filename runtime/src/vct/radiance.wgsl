// Light into the sparse voxel octree (Crassin et al. 2011): the spot lights' reflected flux
// splatted into the leaves from the RSM raster (§8.2), the leaves' radiance, MIP-mapping up
// the octree (§4.2.3) and the tiles' bricks (§4.1). CPU twin: vct/cpu.rs (`inject`,
// `Pyramid::from_leaves`, `Pyramid::vertex`); test `tests/gpu/vct.rs`.
//
// A voxel's value is (radiance times opacity, opacity), per face of view (`svo.faces`: 1, or 6
// for anisotropic voxels, §9). An occupied leaf is opaque and holds the radiance its lit
// surface reflects, the same from every side: the flux of its texels over pi and over the
// surface area they cover (a texel's solid angle from the light spread over the surface), so
// a surface at a slant to the grid, which touches more voxels per area, keeps its radiance. A coarser node holds
// the box filter of its eight children (an empty child counts as zero): isotropic, their mean;
// anisotropic, per face, the children composited front to back along the face's axis in
// each of the four columns, then the columns' mean (§9), so a wall seen face on stays opaque
// at every level. A cone's sample is thus the same sparse or dense (the paper's 3³ Gaussian
// over the children's vertex-centred bricks weighs the parent's own cell more).

#import cssm::types::SpotLight
#import cssm::voxel::{split_groups, split_item}
#import cssm::svo::{svo, svo_levels, svo_nodes, svo_node, svo_brick_of, svo_brick_origin, svo_diffuse, SVO_FLAG, SVO_BRICK, SVO_NONE}
#import cssm::voxel::{VoxelFragment, fragment_cell}

const WORKGROUP: u32 = #{WORKGROUP_1D}u;
const PI: f32 = 3.14159265358979;
// Fixed point of the flux sums: the total flux of every light bounded by 2^30 units, so no
// leaf's sum overflows 32 bits (atomics are integer).
const FLUX_UNITS: f32 = 1073741824.0;
// Fixed point of the area sums: units per leaf voxel face, so a texel far smaller than a voxel
// still counts thousands of units and a leaf holds 256 faces of area before its sum overflows
// (a slanted texel counts at most 1 / MIN_COS times its size).
const AREA_UNITS: f32 = 16777216.0;
// The slant at which a texel's area stops growing (1 / 0.05 its area face on).
const MIN_COS: f32 = 0.05;

struct RadianceParams {
    // The level a `mip` pass fills.
    level: u32,
    light_count: u32,
    tile_capacity: u32,
    fragment_capacity: u32,
    // The diffuse cones of a `bounce` (vct/trace.rs `TraceParams`).
    cones: u32,
    tan_half: f32,
    offset: f32,
    start: f32,
}

@group(0) @binding(0) var<uniform> params: RadianceParams;
// Per tile: its parent's cell and level.
@group(0) @binding(2) var<storage, read> tile_cells: array<vec2u>;
// [flux units per W, radiance per flux unit], from `plan`.
@group(0) @binding(3) var<storage, read> constants: array<f32, 2>;
// The octree build's state: [0] the tiles allocated.
@group(0) @binding(4) var<storage, read> state: array<u32, 4>;
@group(0) @binding(5) var rsm_position: texture_2d_array<f32>;
@group(0) @binding(6) var rsm_normal: texture_2d_array<f32>;
@group(0) @binding(7) var rsm_flux: texture_2d_array<f32>;
// Per node in fixed point: reflected flux rgb, and the area of surface the flux fell on.
@group(0) @binding(8) var<storage, read_write> flux: array<atomic<u32>>;
// Per node and face: (radiance times opacity, opacity), at node * faces + face.
@group(0) @binding(9) var<storage, read_write> values: array<vec4f>;
@group(0) @binding(10) var bricks: texture_storage_3d<rgba16float, write>;
@group(0) @binding(11) var<storage, read> lights: array<SpotLight>;

// `surface` alone: the fragments into the leaves' albedo and normal.
@group(0) @binding(12) var<storage, read> fragment_count: array<u32>;
@group(0) @binding(13) var<storage, read> fragments: array<VoxelFragment>;
// Per node: albedo sums (rgb, 0 to 255 a fragment), the fragments, normal sums (xyz, -127 to
// 127 a fragment, two's complement), a spare word. `surface` writes, `bounce` reads.
@group(0) @binding(14) var<storage, read_write> surface: array<atomic<u32>>;
// `bounce`: every occupied node's cell (vct/octree.wgsl).
@group(0) @binding(15) var<storage, read> node_cells: array<u32>;

// `plan` alone: the indirect arguments of the level passes and the bricks, and the constants.
@group(2) @binding(0) var<storage, read> plan_lights: array<SpotLight>;
@group(2) @binding(1) var<storage, read_write> plan_args: array<vec4u>;
@group(2) @binding(2) var<storage, read_write> plan_constants: array<f32, 2>;

// Workgroups `groups` as indirect arguments of a 2D dispatch.
fn split(groups: u32) -> vec4u {
    return vec4u(split_groups(groups), 0u);
}

fn linear_group(group: vec3u, count: vec3u) -> u32 {
    return split_item(group, count, 0u, 1u);
}

// The flux the lights' cones can send at most: the intensity's largest component times the
// cone's solid angle (`cpu::flux_bound`); 1 when they send none (no lights, or black ones:
// nothing is injected, and the fixed point's scale stays finite, where 2^30 over a tiny bound
// would overflow to infinity, one step from a NaN).
fn flux_bound() -> f32 {
    var total = 0.0;
    for (var i = 0u; i < params.light_count; i++) {
        let l = plan_lights[i];
        let peak = max(l.intensity.x, max(l.intensity.y, l.intensity.z));
        total += peak * (2.0 * PI * (1.0 - l.cos_cutoff));
    }
    return select(1.0, total, total > 0.0);
}

@compute @workgroup_size(#{WORKGROUP_1D})
fn plan(@builtin(local_invocation_index) local: u32) {
    if local != 0u {
        return;
    }
    for (var level = 0u; level <= svo.max_level; level++) {
        let range = svo_levels[level];
        plan_args[level] = split((range.y - range.x + WORKGROUP - 1u) / WORKGROUP);
    }
    plan_args[svo.max_level + 1u] = split(min(state[0], params.tile_capacity));
    // Two bits to spare: an RSM's texels can sum to a little more than the cone.
    let scale = FLUX_UNITS / flux_bound();
    plan_constants[0] = scale;
    // Radiance per flux unit over a leaf voxel's face of area: flux over pi over area.
    plan_constants[1] = 1.0 / (scale * PI * svo.voxel * svo.voxel);
}

fn leaf_of(p: vec3f) -> u32 {
    let q = floor((p - svo.origin) * svo.inv_voxel);
    if any(q < vec3f(0.0)) || any(q >= vec3f(f32(svo.resolution))) {
        return 0xffffffffu;
    }
    return svo_node(vec3u(q), svo.max_level);
}

// 1. Every RSM texel's flux into the leaf holding its surface point, nudged a quarter voxel
// towards the light first, so a surface on a voxel boundary lights the voxel on the lit side.
@compute @workgroup_size(#{WORKGROUP_2D}, #{WORKGROUP_2D})
fn inject(@builtin(global_invocation_id) id: vec3u) {
    let size = textureDimensions(rsm_position);
    if id.x >= size.x || id.y >= size.y || id.z >= params.light_count {
        return;
    }
    let at = vec2i(id.xy);
    let layer = i32(id.z);
    let position = textureLoad(rsm_position, at, layer, 0);
    let f = textureLoad(rsm_flux, at, layer, 0).rgb;
    if position.w <= 0.0 || all(f <= vec3f(0.0)) {
        return;
    }
    let normal = textureLoad(rsm_normal, at, layer, 0).xyz;
    var leaf = leaf_of(position.xyz + normal * (0.25 * svo.voxel));
    if leaf == 0xffffffffu {
        leaf = leaf_of(position.xyz);
    }
    if leaf == 0xffffffffu {
        return;
    }
    let units = vec3u(f * constants[0]);
    atomicAdd(&flux[leaf * 4u], units.x);
    atomicAdd(&flux[leaf * 4u + 1u], units.y);
    atomicAdd(&flux[leaf * 4u + 2u], units.z);
    let area = texel_area(lights[id.z], position.xyz, normal) * svo.inv_voxel * svo.inv_voxel;
    atomicAdd(&flux[leaf * 4u + 3u], u32(area * AREA_UNITS + 0.5));
}

// The surface area an RSM texel covers: its solid angle from the light (`texel_solid_angle` on
// the axis, cos³ off it) times the squared distance over the cosine of incidence
// (`cpu::texel_area`).
fn texel_area(light: SpotLight, p: vec3f, normal: vec3f) -> f32 {
    let to_surface = p - light.position;
    let d2 = dot(to_surface, to_surface);
    let dir = to_surface * inverseSqrt(d2);
    let cos_axis = dot(dir, light.direction);
    let cos_in = max(-dot(normal, dir), MIN_COS);
    return light.texel_solid_angle * cos_axis * cos_axis * cos_axis * d2 / cos_in;
}

// 2. Every leaf: opaque, with its flux's radiance.
@compute @workgroup_size(#{WORKGROUP_1D})
fn leaves(
    @builtin(workgroup_id) group: vec3u,
    @builtin(num_workgroups) count: vec3u,
    @builtin(local_invocation_index) local: u32,
) {
    let node = invocation_leaf(group, count, local);
    if node == SVO_NONE {
        return;
    }
    let radiance = leaf_radiance(node);
    for (var face = 0u; face < svo.faces; face++) {
        values[node * svo.faces + face] = vec4f(radiance, 1.0);
    }
}

// The leaf of an invocation of a pass over the last level's nodes, SVO_NONE for an empty
// node or past the level.
fn invocation_leaf(group: vec3u, count: vec3u, local: u32) -> u32 {
    let range = svo_levels[svo.max_level];
    let node = range.x + linear_group(group, count) * WORKGROUP + local;
    if node >= range.y || svo_nodes[node] != SVO_FLAG {
        return SVO_NONE;
    }
    return node;
}

// A leaf's direct radiance from its sums: flux over pi over area (`cpu::leaf_radiance`).
fn leaf_radiance(node: u32) -> vec3f {
    let units = vec3f(
        f32(atomicLoad(&flux[node * 4u])),
        f32(atomicLoad(&flux[node * 4u + 1u])),
        f32(atomicLoad(&flux[node * 4u + 2u])),
    );
    let area = atomicLoad(&flux[node * 4u + 3u]);
    if area == 0u {
        return vec3f(0.0);
    }
    return units * (constants[1] * (AREA_UNITS / f32(area)));
}

// Every fragment's albedo and normal into its leaf, for the bounces (§8.1).
@compute @workgroup_size(#{WORKGROUP_1D})
fn surface_of_leaves(
    @builtin(workgroup_id) group: vec3u,
    @builtin(num_workgroups) count: vec3u,
    @builtin(local_invocation_index) local: u32,
) {
    let i = split_item(group, count, local, WORKGROUP);
    if i >= min(fragment_count[0], params.fragment_capacity) {
        return;
    }
    let f = fragments[i];
    let leaf = svo_node(fragment_cell(f), svo.max_level);
    if leaf == SVO_NONE {
        return;
    }
    let albedo = vec3u(round(unpack4x8unorm(f.albedo).rgb * 255.0));
    let normal = vec3i(round(unpack4x8snorm(f.normal).xyz * 127.0));
    atomicAdd(&surface[leaf * 8u], albedo.x);
    atomicAdd(&surface[leaf * 8u + 1u], albedo.y);
    atomicAdd(&surface[leaf * 8u + 2u], albedo.z);
    atomicAdd(&surface[leaf * 8u + 3u], 1u);
    atomicAdd(&surface[leaf * 8u + 4u], bitcast<u32>(normal.x));
    atomicAdd(&surface[leaf * 8u + 5u], bitcast<u32>(normal.y));
    atomicAdd(&surface[leaf * 8u + 6u], bitcast<u32>(normal.z));
}

// One more bounce (§8.1): every leaf's radiance is its direct light plus its albedo times the
// light its diffuse cones gather from the bricks as they are (the bounces so far), the cones'
// apex `offset` leaves off the voxel's centre along its fragments' mean normal (`cpu::bounce`).
@compute @workgroup_size(#{WORKGROUP_1D})
fn bounce(
    @builtin(workgroup_id) group: vec3u,
    @builtin(num_workgroups) count: vec3u,
    @builtin(local_invocation_index) local: u32,
) {
    let node = invocation_leaf(group, count, local);
    if node == SVO_NONE {
        return;
    }
    let fragments = atomicLoad(&surface[node * 8u + 3u]);
    let sums = vec3i(
        bitcast<i32>(atomicLoad(&surface[node * 8u + 4u])),
        bitcast<i32>(atomicLoad(&surface[node * 8u + 5u])),
        bitcast<i32>(atomicLoad(&surface[node * 8u + 6u])),
    );
    var radiance = leaf_radiance(node);
    // Fragments whose normals cancel (both sides of a thin wall) gather nothing.
    let normal = vec3f(sums);
    if fragments > 0u && dot(normal, normal) > f32(fragments * fragments) {
        let albedo = vec3f(
            f32(atomicLoad(&surface[node * 8u])),
            f32(atomicLoad(&surface[node * 8u + 1u])),
            f32(atomicLoad(&surface[node * 8u + 2u])),
        ) / (255.0 * f32(fragments));
        let n = normalize(normal);
        let packed = node_cells[node];
        let cell = vec3f(vec3u(packed & 1023u, (packed >> 10u) & 1023u, packed >> 20u));
        let origin = cell + 0.5 + n * params.offset;
        radiance += albedo * svo_diffuse(origin, n, params.cones, params.tan_half, params.start, 0.0);
    }
    for (var face = 0u; face < svo.faces; face++) {
        values[node * svo.faces + face] = vec4f(radiance, 1.0);
    }
}

// 3. Every subdivided node of `params.level`: the mean of its children (the empty ones zero).
@compute @workgroup_size(#{WORKGROUP_1D})
fn mip(
    @builtin(workgroup_id) group: vec3u,
    @builtin(num_workgroups) count: vec3u,
    @builtin(local_invocation_index) local: u32,
) {
    let range = svo_levels[params.level];
    let node = range.x + linear_group(group, count) * WORKGROUP + local;
    if node >= range.y {
        return;
    }
    let word = svo_nodes[node];
    if word == 0u || word == SVO_FLAG {
        return;
    }
    let first = (word & ~SVO_FLAG) * 8u;
    if svo.faces == 1u {
        var sum = vec4f(0.0);
        for (var o = 0u; o < 8u; o++) {
            sum += values[first + o];
        }
        values[node] = sum * 0.125;
        return;
    }
    for (var face = 0u; face < 6u; face++) {
        // The axis's bit; seen along +axis the child with the bit clear is in front.
        let bit = 1u << (face / 2u);
        let front_set = select(0u, bit, (face & 1u) == 1u);
        var sum = vec4f(0.0);
        for (var o = 0u; o < 8u; o++) {
            if (o & bit) != 0u {
                continue;
            }
            let front = values[(first + (o | front_set)) * 6u + face];
            let back = values[(first + (o | (bit ^ front_set))) * 6u + face];
            sum += front + (1.0 - front.a) * back;
        }
        values[node * 6u + face] = sum * 0.25;
    }
}

// The 4x4x4 cells around a tile's 2x2x2 (one more each side), at the tile's level.
var<workgroup> around: array<vec4f, 64>;

// The cells touching a brick texel's vertex along one axis: an odd texel is a cell's centre
// (one cell), an even one lies between two. Indices into `around`'s axis (0 to 3).
fn axis_cells(texel: u32) -> vec2u {
    if (texel & 1u) == 1u {
        return vec2u((texel + 1u) / 2u);
    }
    return vec2u(texel / 2u, texel / 2u + 1u);
}

// 4. Every tile's brick, one workgroup per tile: the level's values of the tile's cells and
// their neighbours (looked up from the root), then each texel the mean of the cells touching
// its vertex: the trilinear interpolation of the level's voxel-centred values at the vertex.
@compute @workgroup_size(#{WORKGROUP_1D})
fn fill_bricks(
    @builtin(workgroup_id) group: vec3u,
    @builtin(num_workgroups) count: vec3u,
    @builtin(local_invocation_index) local: u32,
) {
    let tile = linear_group(group, count);
    let tiles = min(state[0], params.tile_capacity);
    // Workgroup-uniform: every invocation of the group returns or none does.
    if tile == 0u || tile >= tiles {
        return;
    }
    let parent = tile_cells[tile];
    let level = parent.y + 1u;
    let packed = parent.x;
    let parent_cell = vec3i(
        i32(packed & 1023u),
        i32((packed >> 10u) & 1023u),
        i32(packed >> 20u),
    );
    let offset = vec3i(i32(local & 3u), i32((local >> 2u) & 3u), i32(local >> 4u)) - 1;
    let cell = 2 * parent_cell + offset;
    let side = i32(1u << level);
    var node = 0xffffffffu;
    if all(cell >= vec3i(0)) && all(cell < vec3i(side)) {
        node = svo_node(vec3u(cell) << vec3u(svo.max_level - level), level);
    }
    // A tile of leaves has one brick: a leaf is the same from every side.
    var faces = svo.faces;
    if level == svo.max_level {
        faces = 1u;
    }
    for (var face = 0u; face < faces; face++) {
        var value = vec4f(0.0);
        if node != 0xffffffffu {
            value = values[node * svo.faces + face];
        }
        around[local] = value;
        workgroupBarrier();
        let brick = svo_brick_of(tile, face, level);
        if brick != SVO_NONE {
            fill_brick(brick, local);
        }
        workgroupBarrier();
    }
}

// One brick from `around`, every invocation of the workgroup a share of its texels.
fn fill_brick(brick: u32, local: u32) {
    let origin = svo_brick_origin(brick);
    for (var t = local; t < SVO_BRICK * SVO_BRICK * SVO_BRICK; t += WORKGROUP) {
        let texel = vec3u(t % 5u, (t / 5u) % 5u, t / 25u);
        let cx = axis_cells(texel.x);
        let cy = axis_cells(texel.y);
        let cz = axis_cells(texel.z);
        var sum = vec4f(0.0);
        var n = 0.0;
        for (var k = cz.x; k <= cz.y; k++) {
            for (var j = cy.x; j <= cy.y; j++) {
                for (var i = cx.x; i <= cx.y; i++) {
                    sum += around[i + 4u * j + 16u * k];
                    n += 1.0;
                }
            }
        }
        textureStore(bricks, origin + texel, sum / n);
    }
}
