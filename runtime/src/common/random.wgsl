#define_import_path cssm::random

// Hashes for per-pixel and per-frame sample patterns (ssil's rings, vf's shadow rays, vct's
// turned cones, the radiosity's jitter, rsm's pattern): the PCG hash of a u32 and a hash as a
// number in [0, 1). Twin: common/random.rs.

fn pcg_hash(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn hash_unit(v: u32) -> f32 {
    return f32(v >> 8u) / 16777216.0;
}
