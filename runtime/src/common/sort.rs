//! The one GPU sort of the runtime: a stable LSD radix sort of `u32` key-value pairs by key
//! (lampshade's `KeyValueSorter`, recorded into the frame's encoder), shared by every pass that
//! orders items by a key (the point proxies of `vf` by their voxel, Chen et al. 2014 §3.1).
//!
//! Pairs are [`KeyValue`]s, 8 bytes each, in a `STORAGE` buffer; the sorted pairs go to a
//! distinct one. CPU twin: [`sort_cpu`] (a stable sort by key); test `tests/gpu/sort.rs`.

pub use lampshade::KeyValue;

use crate::RuntimeError;

/// The sorter, with the workspace it keeps between sorts.
pub struct KeySort {
    sorter: lampshade::KeyValueSorter,
}

impl KeySort {
    /// A sorter on `device` and `queue`.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        Self {
            sorter: lampshade::KeyValueSorter::new(device, queue),
        }
    }

    /// Records the stable sort by key of the first `count` pairs of `input` into `output`
    /// (distinct buffers of at least `count` [`KeyValue`]s), every key below `2^key_bits`
    /// (at most 32: fewer bits, fewer passes).
    ///
    /// # Errors
    /// A key-bit bound above 32, buffers too small or without `STORAGE`, workspace the device
    /// cannot allocate.
    pub fn record(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        input: &wgpu::Buffer,
        output: &wgpu::Buffer,
        count: u32,
        key_bits: u32,
    ) -> Result<(), RuntimeError> {
        self.sorter
            .record_sort_with_key_bits(encoder, input, output, count, key_bits)
            .map_err(|e| RuntimeError::Gpu(format!("radix sort of {count} pairs: {e}")))
    }
}

/// The significant bits of keys below `bound` (at least 1).
pub fn key_bits(bound: u32) -> u32 {
    (32 - bound.saturating_sub(1).leading_zeros()).max(1)
}

/// CPU twin: the pairs stably sorted by key.
pub fn sort_cpu(pairs: &[KeyValue]) -> Vec<KeyValue> {
    let mut sorted = pairs.to_vec();
    sorted.sort_by_key(|p| p.key);
    sorted
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_bits_cover_the_bound() {
        assert_eq!(key_bits(0), 1);
        assert_eq!(key_bits(1), 1);
        assert_eq!(key_bits(2), 1);
        assert_eq!(key_bits(3), 2);
        assert_eq!(key_bits(256), 8);
        assert_eq!(key_bits(257), 9);
        assert_eq!(key_bits(u32::MAX), 32);
    }

    #[test]
    fn the_twin_is_stable() {
        let pairs = [
            KeyValue::new(2, 0),
            KeyValue::new(1, 1),
            KeyValue::new(2, 2),
            KeyValue::new(1, 3),
        ];
        let values: Vec<u32> = sort_cpu(&pairs).iter().map(|p| p.value).collect();
        assert_eq!(values, vec![1, 3, 0, 2]);
    }
}
