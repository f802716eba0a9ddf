//! The CPU twin of `common/random.wgsl`: the PCG hash (Jarzynski and Olano 2020) behind every
//! per-pixel and per-frame sample pattern of the GPU passes (ssil's rings, vf's shadow rays,
//! vct's turned cones, the radiosity's jitter), and a hash as a number in [0, 1) (also rsm's,
//! over its own lowbias32 hash).

/// `random.wgsl`: `pcg_hash`.
pub fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// `random.wgsl`: `hash_unit`, a hash as a number in [0, 1).
pub fn hash_unit(v: u32) -> f32 {
    (v >> 8) as f32 / 16_777_216.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hash_is_pcg() {
        assert_eq!(pcg_hash(0), 129_708_002);
        assert!(hash_unit(u32::MAX) < 1.0);
        assert_eq!(hash_unit(0), 0.0);
    }
}
