//! The run data: the random-access layout of the piecewise-constant runs that the GPU queries
//! ([`RunData`]), and the file's entropy-coded form of it ([`PackedRuns`], LEB128 varints in
//! separate streams).

use serde::{Deserialize, Serialize};

use super::CssmError;

/// Number of consecutive depth maps per run-data segment: run starts are stored relative to
/// their segment in 16 bits, so a segment holds at most 2^16 maps.
pub const SEGMENT_MAPS: u32 = 1 << 16;

/// Piecewise-constant runs of every cube-map pixel along the depth-map sequence, laid out for
/// random access by (map index, pixel) (§3.1, §3.2).
///
/// The sequence of `map_count` maps is cut into segments of [`SEGMENT_MAPS`] maps. For segment
/// `s` and pixel `p` (`p = face * N * N + row * N + col`), the runs are
/// `runs[offsets[s * pixel_count + p] .. offsets[s * pixel_count + p + 1]]`, sorted by start;
/// the first one starts at 0. A run is one `u32`: `(start_within_segment << 16) | depth16`.
/// The depth of map `m` at pixel `p` is the value of the last run of segment `m / SEGMENT_MAPS`
/// whose start is `<= m % SEGMENT_MAPS`: a binary search over a handful of entries.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RunData {
    /// Number of depth maps (= defined texels).
    pub map_count: u32,
    /// Pixels per cube map, `6 * N * N`.
    pub pixel_count: u32,
    /// `segment_count * pixel_count + 1` prefix offsets into `runs`.
    pub offsets: Vec<u32>,
    /// Packed runs, `(start_within_segment << 16) | depth16`.
    pub runs: Vec<u32>,
}

impl RunData {
    /// Number of segments of [`SEGMENT_MAPS`] maps.
    pub fn segment_count(&self) -> u32 {
        self.map_count.div_ceil(SEGMENT_MAPS)
    }

    /// Quantised depth of map `map` at pixel `pixel`. Both must be in range.
    #[inline]
    pub fn lookup(&self, map: u32, pixel: u32) -> u16 {
        let segment = map / SEGMENT_MAPS;
        let local = map % SEGMENT_MAPS;
        let slot = (segment * self.pixel_count + pixel) as usize;
        let (lo, hi) = (self.offsets[slot] as usize, self.offsets[slot + 1] as usize);
        let runs = &self.runs[lo..hi];
        // Last run whose start <= local: partition point of "start <= local".
        let idx = runs.partition_point(|&r| (r >> 16) <= local);
        (runs[idx.max(1) - 1] & 0xFFFF) as u16
    }

    /// [`Self::lookup`] by the search the GPU query runs (`cssm_lookup_slot` in the runtime's
    /// `visibility/cssm.wgsl`): a binary search of at most `steps` steps (at least
    /// [`Self::search_steps`] find every map), which keeps the last run found at or before the
    /// map as it goes, telling `probed` the index of every run it loads, in order.
    pub fn lookup_traced(
        &self,
        map: u32,
        pixel: u32,
        steps: u32,
        mut probed: impl FnMut(u32),
    ) -> u16 {
        let local = map % SEGMENT_MAPS;
        let slot = self.slot(map, pixel) as usize;
        let mut first = self.offsets[slot] as usize;
        let mut count = self.offsets[slot + 1] as usize - first;
        let mut found = u32::from(u16::MAX);
        for _ in 0..steps {
            if count == 0 {
                break;
            }
            let half = count / 2;
            let i = first + half;
            probed(i as u32);
            let run = self.runs[i];
            if run >> 16 <= local {
                first = i + 1;
                count -= half + 1;
                found = run;
            } else {
                count = half;
            }
        }
        (found & 0xFFFF) as u16
    }

    /// The (segment, pixel) slot of map `map` at `pixel`: its runs are
    /// `runs[offsets[slot]..offsets[slot + 1]]`.
    pub fn slot(&self, map: u32, pixel: u32) -> u32 {
        map / SEGMENT_MAPS * self.pixel_count + pixel
    }

    /// Runs in the longest list of one (segment, pixel) slot.
    pub fn longest_list(&self) -> u32 {
        self.offsets
            .windows(2)
            .map(|w| w[1].saturating_sub(w[0]))
            .max()
            .unwrap_or(0)
    }

    /// Steps of [`Self::lookup_traced`] that find every map's run: the bit length of the
    /// [`Self::longest_list`] (a step leaves at most half the range).
    pub fn search_steps(&self) -> u32 {
        u32::BITS - self.longest_list().leading_zeros()
    }

    /// Bytes the random-access run data occupies in GPU memory: offsets plus runs.
    pub fn gpu_bytes(&self) -> u64 {
        4 * (self.offsets.len() as u64 + self.runs.len() as u64)
    }

    /// Uncompressed size, the denominator of every ratio: 2 bytes per cube-map pixel (paper,
    /// Tables 2 and 3).
    pub fn uncompressed_bytes(&self) -> u64 {
        2 * self.map_count as u64 * self.pixel_count as u64
    }
}

/// The entropy-coded form of a [`RunData`] (the file's "entropy stage"; the GPU keeps
/// [`RunData`]). Three streams, slot by slot in `(segment, pixel)` order: `counts` holds each
/// slot's number of runs (LEB128 varints); `lengths` every run's length in maps but each slot's
/// last (varints; the first run starts at 0); `depths` every run's depth as the 16-bit wrapping
/// difference (little-endian) to the depth that the *previous slot* (the neighbouring pixel)
/// holds at the run's start, since neighbouring pixels see nearly the same depths. Separate
/// streams keep similar numbers together for zstd, so the file comes out smaller than zstd of the
/// plain layout.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PackedRuns {
    /// Runs per slot.
    pub counts: Vec<u8>,
    /// Run lengths (maps), all but each slot's last run.
    pub lengths: Vec<u8>,
    /// Depth differences to the previous slot, 2 bytes each.
    pub depths: Vec<u8>,
}

fn put_varint(out: &mut Vec<u8>, mut v: u32) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Reads varints from a byte stream, refusing overlong or truncated ones.
struct VarintReader<'a> {
    bytes: &'a [u8],
    at: usize,
    name: &'static str,
}

impl VarintReader<'_> {
    fn next(&mut self) -> Result<u32, CssmError> {
        let mut v: u64 = 0;
        for shift in (0..35).step_by(7) {
            let Some(&b) = self.bytes.get(self.at) else {
                return Err(CssmError::Malformed(format!(
                    "packed runs: the {} stream ends early",
                    self.name
                )));
            };
            self.at += 1;
            v |= u64::from(b & 0x7F) << shift;
            if b & 0x80 == 0 {
                return u32::try_from(v).map_err(|_| {
                    CssmError::Malformed(format!("packed runs: a {} value overflows", self.name))
                });
            }
        }
        Err(CssmError::Malformed(format!(
            "packed runs: an over-long varint in the {} stream",
            self.name
        )))
    }

    fn finish(&self) -> Result<(), CssmError> {
        if self.at != self.bytes.len() {
            return Err(CssmError::Malformed(format!(
                "packed runs: {} trailing bytes in the {} stream",
                self.bytes.len() - self.at,
                self.name
            )));
        }
        Ok(())
    }
}

/// Depth that the runs of a slot (sorted by start) hold at map `start` of the segment, walking
/// `cursor` forward (starts are visited in increasing order); 0 for an empty slot.
#[inline]
fn depth_at(slot: &[u32], cursor: &mut usize, start: u32) -> u16 {
    while *cursor + 1 < slot.len() && slot[*cursor + 1] >> 16 <= start {
        *cursor += 1;
    }
    slot.get(*cursor).map_or(0, |&r| (r & 0xFFFF) as u16)
}

impl PackedRuns {
    /// Packs run data (deterministic).
    pub fn pack(runs: &RunData) -> PackedRuns {
        let mut p = PackedRuns::default();
        let mut prev: &[u32] = &[];
        for w in runs.offsets.windows(2) {
            let slot = &runs.runs[w[0] as usize..w[1] as usize];
            put_varint(&mut p.counts, slot.len() as u32);
            let mut cursor = 0;
            for (i, &r) in slot.iter().enumerate() {
                if let Some(&next) = slot.get(i + 1) {
                    put_varint(&mut p.lengths, (next >> 16) - (r >> 16));
                }
                let predicted = depth_at(prev, &mut cursor, r >> 16);
                let delta = ((r & 0xFFFF) as u16).wrapping_sub(predicted);
                p.depths.extend_from_slice(&delta.to_le_bytes());
            }
            prev = slot;
        }
        p
    }

    /// Unpacks into the run data of `map_count` maps of `pixel_count` pixels. Every count is
    /// checked against the bytes left before anything is allocated for it (a slot takes at least
    /// one byte of `counts`, a run two of `depths`), so a damaged stream cannot make this
    /// allocate more than its own size allows. The result still has to pass [`validate`].
    ///
    /// [`validate`]: fn@super::validate
    pub fn unpack(&self, map_count: u32, pixel_count: u32) -> Result<RunData, CssmError> {
        let slots = u64::from(map_count.div_ceil(SEGMENT_MAPS)) * u64::from(pixel_count);
        if slots > self.counts.len() as u64 {
            return Err(CssmError::Malformed(format!(
                "packed runs: {slots} slots but only {} count bytes",
                self.counts.len()
            )));
        }
        if self.depths.len() % 2 != 0 {
            return Err(CssmError::Malformed(
                "packed runs: the depth stream has an odd length".into(),
            ));
        }
        let mut counts = VarintReader {
            bytes: &self.counts,
            at: 0,
            name: "count",
        };
        let mut lengths = VarintReader {
            bytes: &self.lengths,
            at: 0,
            name: "length",
        };
        let mut offsets = Vec::with_capacity(slots as usize + 1);
        offsets.push(0u32);
        let mut total: u64 = 0;
        for _ in 0..slots {
            let c = counts.next()?;
            if c == 0 {
                return Err(CssmError::Malformed(
                    "packed runs: a slot with no runs".into(),
                ));
            }
            total += u64::from(c);
            if total > self.depths.len() as u64 / 2 {
                return Err(CssmError::Malformed(format!(
                    "packed runs: {total} runs but only {} depth bytes",
                    self.depths.len()
                )));
            }
            offsets.push(total as u32);
        }
        counts.finish()?;
        if total != self.depths.len() as u64 / 2 {
            return Err(CssmError::Malformed(format!(
                "packed runs: {} trailing bytes in the depth stream",
                self.depths.len() as u64 - 2 * total
            )));
        }
        let mut runs: Vec<u32> = Vec::with_capacity(total as usize);
        let mut prev = 0..0;
        for w in offsets.windows(2) {
            let here = runs.len();
            let mut start: u32 = 0;
            let mut cursor = 0;
            for i in w[0]..w[1] {
                if i > w[0] {
                    let len = lengths.next()?;
                    start = start
                        .checked_add(len)
                        .filter(|&s| len > 0 && s < SEGMENT_MAPS)
                        .ok_or_else(|| {
                            CssmError::Malformed(
                                "packed runs: a run start beyond its segment".into(),
                            )
                        })?;
                }
                let predicted = depth_at(&runs[prev.clone()], &mut cursor, start);
                let at = 2 * i as usize;
                let delta = u16::from_le_bytes([self.depths[at], self.depths[at + 1]]);
                runs.push((start << 16) | u32::from(predicted.wrapping_add(delta)));
            }
            prev = here..runs.len();
        }
        lengths.finish()?;
        Ok(RunData {
            map_count,
            pixel_count,
            offsets,
            runs,
        })
    }
}

#[cfg(test)]
mod lookup_tests {
    use super::*;

    /// Pixel lists of 1 to 300 runs with random starts; every map of the segment looked up.
    fn random_runs(seed: u64) -> RunData {
        let mut state = seed;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        let (pixel_count, map_count) = (24, 2000);
        let mut offsets = vec![0];
        let mut runs = Vec::new();
        for _ in 0..pixel_count {
            let count = 1 + next() % 300;
            let mut starts: Vec<u32> = (1..count).map(|_| 1 + next() % (map_count - 1)).collect();
            starts.push(0);
            starts.sort_unstable();
            starts.dedup();
            runs.extend(starts.iter().map(|&s| s << 16 | (next() & 0xFFFF)));
            offsets.push(runs.len() as u32);
        }
        RunData {
            map_count,
            pixel_count,
            offsets,
            runs,
        }
    }

    #[test]
    fn the_traced_lookup_finds_what_lookup_finds_in_search_steps_and_no_fewer() {
        for seed in 1..4 {
            let data = random_runs(seed);
            let steps = data.search_steps();
            assert!(1 << steps > data.longest_list());
            let mut missed_with_fewer = 0;
            for pixel in 0..data.pixel_count {
                for map in 0..data.map_count {
                    let code = data.lookup(map, pixel);
                    let mut loads = 0;
                    assert_eq!(data.lookup_traced(map, pixel, steps, |_| loads += 1), code);
                    assert!(loads >= 1 && loads <= steps);
                    // More steps change nothing: the search has ended.
                    assert_eq!(data.lookup_traced(map, pixel, steps + 3, |_| {}), code);
                    missed_with_fewer +=
                        usize::from(data.lookup_traced(map, pixel, steps - 1, |_| {}) != code);
                }
            }
            // The bound is tight: one step fewer misses some maps.
            assert!(missed_with_fewer > 0);
        }
    }
}
