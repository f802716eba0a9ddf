#define_import_path cssm::svo

// Reading the sparse voxel octree (Crassin et al. 2011): the node lookup from the root (§4.1),
// the quadrilinear sample in the bricks (§5.1) and a cone's front-to-back accumulation (§5).
// CPU twin: vct/cpu.rs (`Pyramid::sample`, `Pyramid::sample_lod`, `trace_cone`), the same
// arithmetic over a dense pyramid of the same values; test `tests/gpu/vct.rs`.
//
// Positions are in leaf voxels from the grid's origin. A tile's brick holds its 2x2x2 nodes'
// values at the 5x5x5 corners, edge and face centres and centres of the nodes (vertex-centred,
// §4.1: 3x3x3 per node, the borders shared), so a trilinear sample of the brick is the
// trilinear interpolation of the level's voxel-centred values inside the tile's parent cell.
// A cell whose parent is empty has no brick and reads as empty.
//
// Anisotropic voxels (§9, `faces` 6): every tile above the leaves has six bricks, one per
// direction of view (+x, -x, +y, -y, +z, -z), and a sample along a direction weighs the three
// it faces by the direction's squared components; a tile of leaves, the same from every side,
// has one, after the others (`svo_brick_of`). Isotropic voxels (`faces` 1): one brick a tile.

struct SvoParams {
    // World position of the grid's corner.
    origin: vec3f,
    // Leaf voxels per world unit.
    inv_voxel: f32,
    max_level: u32,
    resolution: u32,
    // Bricks per row and per slice of rows in the brick pool.
    bricks_per_side: u32,
    // World size of a leaf voxel.
    voxel: f32,
    // Bricks per tile: 1 isotropic, 6 anisotropic.
    faces: u32,
    // 1: a sample's opacity corrected for a step shorter than its voxel (§5); 0: as it is.
    correct_opacity: u32,
    // Anisotropic: the bricks of the tiles above the leaves, six a tile; the leaves' follow.
    inner_bricks: u32,
    // Bricks the pool holds.
    brick_capacity: u32,
}

@group(#{SVO_GROUP}) @binding(0) var<uniform> svo: SvoParams;
// The node pool (vct/octree.wgsl): 0 empty, FLAG a leaf, else the tile of the children.
@group(#{SVO_GROUP}) @binding(1) var<storage, read> svo_nodes: array<u32>;
// The brick pool, 5x5x5 texels per tile, and its trilinear sampler.
@group(#{SVO_GROUP}) @binding(2) var svo_bricks: texture_3d<f32>;
@group(#{SVO_GROUP}) @binding(3) var svo_sampler: sampler;
// The octree's levels, [first node, end] (vct/octree.wgsl): the leaves' tiles are the last
// level's.
@group(#{SVO_GROUP}) @binding(4) var<storage, read> svo_levels: array<vec2u>;

const SVO_NONE: u32 = 0xffffffffu;
const SVO_FLAG: u32 = 0x80000000u;
// Texels per side of a tile's brick.
const SVO_BRICK: u32 = 5u;
// A cone advances by this fraction of its diameter per sample (§5.1).
const SVO_STEP: f32 = 0.5;
// Samples per cone at most (llvmpipe stops loops of more than 65,535 iterations).
const SVO_MAX_SAMPLES: u32 = 4096u;

// The octant of `cell`'s bit `shift` (x | y << 1 | z << 2).
fn svo_octant(cell: vec3u, shift: u32) -> u32 {
    let bit = (cell >> vec3u(shift)) & vec3u(1u);
    return bit.x | (bit.y << 1u) | (bit.z << 2u);
}

// The node holding the leaf cell `cell` at `level` (0 the root), or SVO_NONE where that part
// of space is empty.
fn svo_node(cell: vec3u, level: u32) -> u32 {
    var node = 0u;
    for (var l = 0u; l < level; l++) {
        let word = svo_nodes[node];
        if word == 0u {
            return SVO_NONE;
        }
        node = (word & ~SVO_FLAG) * 8u + svo_octant(cell, svo.max_level - 1u - l);
    }
    if svo_nodes[node] == 0u {
        return SVO_NONE;
    }
    return node;
}

// The brick of face `face` of tile `tile` whose nodes are at `level`, or SVO_NONE beyond the
// pool (`SvoParams::brick`).
fn svo_brick_of(tile: u32, face: u32, level: u32) -> u32 {
    var brick = tile;
    if svo.faces != 1u {
        let first_leaf_tile = svo_levels[svo.max_level].x / 8u;
        if level == svo.max_level {
            brick = svo.inner_bricks + (tile - first_leaf_tile);
        } else {
            brick = tile * 6u + face;
            if brick >= svo.inner_bricks {
                return SVO_NONE;
            }
        }
    }
    if brick >= svo.brick_capacity {
        return SVO_NONE;
    }
    return brick;
}

// The first texel of brick `brick` in the pool.
fn svo_brick_origin(brick: u32) -> vec3u {
    let b = svo.bricks_per_side;
    return SVO_BRICK * vec3u(brick % b, (brick / b) % b, brick / (b * b));
}

// Brick `brick` at `local` in [0, 1)³ of its tile's parent cell.
fn svo_brick(brick: u32, local: vec3f) -> vec4f {
    if brick == SVO_NONE {
        return vec4f(0.0);
    }
    let texel = vec3f(svo_brick_origin(brick)) + 0.5 + 4.0 * local;
    let dims = vec3f(textureDimensions(svo_bricks));
    return textureSampleLevel(svo_bricks, svo_sampler, texel / dims, 0.0);
}

// Level `level` (1 to max_level) at `p`, seen along the unit `dir`: premultiplied radiance and
// opacity.
fn svo_sample(p: vec3f, level: u32, dir: vec3f) -> vec4f {
    if any(p < vec3f(0.0)) || any(p >= vec3f(f32(svo.resolution))) {
        return vec4f(0.0);
    }
    let parent = svo_node(vec3u(p), level - 1u);
    if parent == SVO_NONE {
        return vec4f(0.0);
    }
    let tile = svo_nodes[parent] & ~SVO_FLAG;
    // The parent cell's side in leaves is a power of two: the division is exact.
    let size = f32(1u << (svo.max_level + 1u - level));
    let local = fract(p / size);
    if svo.faces == 1u || level == svo.max_level {
        return svo_brick(svo_brick_of(tile, 0u, level), local);
    }
    // The faces the direction looks at: +x (0) when it travels towards +x, else -x (1).
    let w = dir * dir;
    let x = svo_brick(svo_brick_of(tile, select(1u, 0u, dir.x >= 0.0), level), local);
    let y = svo_brick(svo_brick_of(tile, select(3u, 2u, dir.y >= 0.0), level), local);
    let z = svo_brick(svo_brick_of(tile, select(5u, 4u, dir.z >= 0.0), level), local);
    return w.x * x + w.y * y + w.z * z;
}

// The quadrilinear sample (§5.1): levels floor(level) and the next finer, interpolated by the
// fraction. `level` in [1, max_level].
fn svo_sample_lod(p: vec3f, level: f32, dir: vec3f) -> vec4f {
    let coarse = u32(floor(level));
    let f = level - floor(level);
    let a = svo_sample(p, coarse, dir);
    if f <= 0.0 || coarse >= svo.max_level {
        return a;
    }
    return mix(a, svo_sample(p, coarse + 1u, dir), f);
}

// A cone from `origin` along the unit `dir`, its radius `tan_half` times the distance, from
// distance `start` (leaf voxels) to the grid's diagonal or until opaque: front-to-back
// accumulation of the samples' radiance and opacity (§5), each sample's opacity corrected for
// a step shorter than its voxel when `correct_opacity`. Returns (radiance, opacity).
fn svo_cone(origin: vec3f, dir: vec3f, tan_half: f32, start: f32) -> vec4f {
    return svo_cone_to(origin, dir, tan_half, start, f32(svo.resolution) * 1.7320508);
}

// `svo_cone` up to distance `end`.
fn svo_cone_to(origin: vec3f, dir: vec3f, tan_half: f32, start: f32, end: f32) -> vec4f {
    let max_level = f32(svo.max_level);
    var radiance = vec3f(0.0);
    var alpha = 0.0;
    var t = start;
    for (var i = 0u; i < SVO_MAX_SAMPLES; i++) {
        if t >= end || alpha >= 0.99 {
            break;
        }
        let diameter = max(2.0 * t * tan_half, 1.0);
        let level = clamp(max_level - log2(diameter), 1.0, max_level);
        let s = svo_sample_lod(origin + t * dir, level, dir);
        let step = SVO_STEP * diameter;
        if s.a > 0.0 {
            var a = s.a;
            if svo.correct_opacity != 0u && s.a < 1.0 {
                // §5: the sample's opacity is its voxel's, `size` leaves deep; the step is
                // shorter.
                let size = exp2(max_level - level);
                a = 1.0 - pow(1.0 - s.a, step / size);
            }
            radiance += (1.0 - alpha) * a * (s.rgb / s.a);
            alpha += (1.0 - alpha) * a;
        }
        t += step;
    }
    return vec4f(radiance, alpha);
}

// pi (3 - sqrt 5).
const SVO_GOLDEN_ANGLE: f32 = 2.39996323;

// An orthonormal basis around the unit `n` (Duff et al. 2017), `cpu::basis`.
fn svo_basis(n: vec3f) -> mat3x3f {
    let s = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    let t = vec3f(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    let u = vec3f(b, s + n.y * n.y * a, -n.y);
    return mat3x3f(t, u, n);
}

// Cone `k` of `cones` in the normal's frame: equal areas of the unit disc projected up onto the
// hemisphere (cosine-distributed), along a Fibonacci spiral turned `turn` of a full turn about
// the normal (`cpu::cone_direction`).
fn svo_cone_direction(k: u32, cones: u32, turn: f32) -> vec3f {
    let u = (f32(k) + 0.5) / f32(cones);
    let r = sqrt(u);
    let phi = SVO_GOLDEN_ANGLE * f32(k) + 6.28318531 * turn;
    return vec3f(r * cos(phi), r * sin(phi), sqrt(1.0 - u));
}

// Ambient occlusion (§6): the mean opacity the diffuse cones gather within `radius` leaf voxels
// of `origin` (the paper weighs it by a falloff with distance; here a radius bounds it).
fn svo_occlusion(origin: vec3f, n: vec3f, cones: u32, tan_half: f32, start: f32, radius: f32) -> f32 {
    let frame = svo_basis(n);
    var sum = 0.0;
    for (var k = 0u; k < cones; k++) {
        let dir = frame * svo_cone_direction(k, cones, 0.0);
        sum += svo_cone_to(origin, dir, tan_half, start, start + radius).a;
    }
    return sum / f32(cones);
}

// The mean radiance of `cones` cosine-distributed diffuse cones around `n` from `origin`, their
// spiral turned `turn` of a full turn: the irradiance over pi (a uniform sky of radiance L
// gives L).
fn svo_diffuse(origin: vec3f, n: vec3f, cones: u32, tan_half: f32, start: f32, turn: f32) -> vec3f {
    let frame = svo_basis(n);
    var sum = vec3f(0.0);
    for (var k = 0u; k < cones; k++) {
        sum += svo_cone(origin, frame * svo_cone_direction(k, cones, turn), tan_half, start).rgb;
    }
    return sum / f32(cones);
}
