//! Per-pixel piecewise-constant compression along the depth-map sequence (§3.1, after CSM and
//! Weiskopf and Ertl's dual depth layers): every pixel's run continues while one code still lies
//! inside every member's acceptable interval (don't-care members join any run); a new run starts
//! when the intersection would become empty. This greedy cut gives the fewest runs possible for
//! the sequence, since any run that reached further would have to contain a member whose interval
//! misses the intersection.
//!
//! The compressor is fed maps in sequence order in batches and never holds more than the current
//! batch, one open run per pixel and the closed runs of the current segment.
//!
//! Two options go beyond the paper ([`CompressOptions`]):
//! - [`RunValue`]: which code of the intersection a run stores. The paper stores "an arbitrary
//!   depth value between the first and second intersection"; the middle is the default.
//! - `merge_short_runs` (lossy, off by default): a run of at most that many maps that sits between
//!   two runs whose intervals still intersect is dropped and the two neighbours become one run.
//!   Those few maps then hold a wrong depth in that pixel; the accuracy check says what it costs.

use cssm_formats::cssm::{RunData, SEGMENT_MAPS};
use rayon::prelude::*;

use crate::cubemap::Interval;

/// Which code of its intersection interval `[lo, hi]` a run stores.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RunValue {
    /// The middle code, `(lo + hi) / 2`: the largest margin on both sides in code units.
    #[default]
    Middle,
    /// The harmonic mean of the two depths: equal *relative* margins above the near layer and
    /// below the far one, since the depth error of a moved sender grows with depth.
    Balanced,
}

impl RunValue {
    /// Every choice, default first.
    pub const ALL: [RunValue; 2] = [RunValue::Middle, RunValue::Balanced];

    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            RunValue::Middle => "middle",
            RunValue::Balanced => "balanced",
        }
    }

    /// The stored code for the interval `[lo, hi]` (always inside it). `near_codes` is the near
    /// distance in code units (depth `d` has code `(d - near) * scale`, so depth is proportional
    /// to `code + near_codes`).
    pub fn pick(self, lo: u16, hi: u16, near_codes: f64) -> u16 {
        match self {
            RunValue::Middle => ((u32::from(lo) + u32::from(hi)) / 2) as u16,
            RunValue::Balanced => {
                let (l, h) = (f64::from(lo) + near_codes, f64::from(hi) + near_codes);
                let v = 2.0 * l * h / (l + h) - near_codes;
                (v.round() as u32).clamp(u32::from(lo), u32::from(hi)) as u16
            }
        }
    }
}

impl std::fmt::Display for RunValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for RunValue {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "middle" => Ok(RunValue::Middle),
            "balanced" => Ok(RunValue::Balanced),
            other => Err(format!(
                "unknown run value '{other}': expected middle or balanced"
            )),
        }
    }
}

/// Options of the compressor.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompressOptions {
    /// Which code a run stores.
    pub run_value: RunValue,
    /// Lossy: drop runs of at most this many maps between two runs whose intervals intersect
    /// (0: lossless, the paper's compression).
    pub merge_short_runs: u32,
    /// Near distance in code units, for [`RunValue::Balanced`].
    pub near_codes: f64,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Open {
    start: u32,
    lo: u16,
    hi: u16,
}

/// Per pixel, for the lossy merge: the last (up to) two closed runs, not yet packed, since a
/// short run can only be judged once the run after it is closed. Merging online keeps the
/// compressor's memory at 4 bytes per closed run, as without merging.
#[derive(Clone, Copy, Debug, Default)]
struct Tail {
    runs: [Open; 2],
    len: u8,
}

/// Closes run `x` of one pixel: packs it into `closed`, or with merging on, first drops the run
/// before it when that one has at most `merge_short_runs` maps and the run before *it* still
/// intersects `x` (which then absorbs `x`).
#[inline]
fn close_run(closed: &mut Vec<u32>, tail: &mut Tail, x: Open, options: &CompressOptions) {
    if options.merge_short_runs == 0 {
        push_run(closed, pack(&x, options));
        return;
    }
    if tail.len == 2 {
        let [z, y] = tail.runs;
        let (lo, hi) = (z.lo.max(x.lo), z.hi.min(x.hi));
        if x.start - y.start <= options.merge_short_runs && lo <= hi {
            tail.runs[0] = Open { lo, hi, ..z };
            tail.len = 1;
        } else {
            push_run(closed, pack(&z, options));
            tail.runs = [y, x];
        }
        return;
    }
    tail.runs[tail.len as usize] = x;
    tail.len += 1;
}

/// Appends a packed run to a pixel's list, growing it by a quarter at a time instead of
/// doubling: the lists of a segment hold all its runs (hundreds of MiB for a large scene), and
/// doubling would leave up to as much again unused until the segment closes.
#[inline]
fn push_run(closed: &mut Vec<u32>, run: u32) {
    if closed.len() == closed.capacity() {
        closed.reserve_exact((closed.capacity() / 4).max(16));
    }
    closed.push(run);
}

/// Packs the runs still held in `tail` (end of a segment).
fn flush(closed: &mut Vec<u32>, tail: &mut Tail, options: &CompressOptions) {
    for r in &tail.runs[..tail.len as usize] {
        push_run(closed, pack(r, options));
    }
    tail.len = 0;
}

/// Pixels per parallel task of [`Compressor::push`].
const PIXEL_BLOCK: usize = 1024;

/// Streaming compressor of one CSSM.
pub struct Compressor {
    pixel_count: u32,
    map_count: u32,
    maps_seen: u32,
    open: Vec<Open>,
    /// Closed runs of the current segment, one list per pixel, packed as in [`RunData`].
    segment_runs: Vec<Vec<u32>>,
    /// Runs awaiting the lossy merge, one per pixel (unused when merging is off).
    tails: Vec<Tail>,
    options: CompressOptions,
    offsets: Vec<u32>,
    runs: Vec<u32>,
}

impl Compressor {
    /// A lossless compressor for `map_count` maps of `pixel_count` pixels storing middle codes.
    pub fn new(pixel_count: u32, map_count: u32) -> Self {
        Self::with_options(pixel_count, map_count, CompressOptions::default())
    }

    /// A compressor with `options`.
    pub fn with_options(pixel_count: u32, map_count: u32, options: CompressOptions) -> Self {
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
            tails: vec![Tail::default(); pixel_count as usize],
            offsets: vec![0],
            runs: Vec::new(),
            options,
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
            let options = self.options;
            // Blocks of pixels, each walked map by map: the maps' rows are read in order (the
            // batch was just written by the renderers' threads, and reading it pixel by pixel
            // down the maps stalled on every load: 17% of a Cornell bake's CPU time), and the
            // block's open runs stay in the first-level cache.
            self.open
                .par_chunks_mut(PIXEL_BLOCK)
                .zip(self.segment_runs.par_chunks_mut(PIXEL_BLOCK))
                .zip(self.tails.par_chunks_mut(PIXEL_BLOCK))
                .enumerate()
                .for_each(|(block, ((opens, closed), tails))| {
                    let first_pixel = block * PIXEL_BLOCK;
                    for k in 0..take {
                        let row = &chunk[k * pc + first_pixel..][..opens.len()];
                        for (i, &(a, b)) in row.iter().enumerate() {
                            let open = &mut opens[i];
                            let lo = open.lo.max(a);
                            let hi = open.hi.min(b);
                            if lo <= hi {
                                open.lo = lo;
                                open.hi = hi;
                            } else {
                                close_run(&mut closed[i], &mut tails[i], *open, &options);
                                *open = Open {
                                    start: first_map + k as u32,
                                    lo: a,
                                    hi: b,
                                };
                            }
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
        let options = self.options;
        // Close every pixel's open run, and trim the per-pixel lists to their length, one at a
        // time, so that the slack of their growth is given back before the segment's runs are
        // copied into one array (the peak is then about twice the segment's runs).
        self.open
            .par_iter_mut()
            .zip(self.segment_runs.par_iter_mut())
            .zip(self.tails.par_iter_mut())
            .for_each(|((open, closed), tail)| {
                close_run(closed, tail, *open, &options);
                flush(closed, tail, &options);
                closed.shrink_to_fit();
            });
        let closing: usize = self.segment_runs.iter().map(Vec::len).sum();
        self.runs.reserve_exact(closing);
        for (open, closed) in self.open.iter_mut().zip(self.segment_runs.iter_mut()) {
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

/// Packs a closed run: start within its segment, and the code [`RunValue`] picks inside its
/// interval.
#[inline]
fn pack(run: &Open, options: &CompressOptions) -> u32 {
    let value = options.run_value.pick(run.lo, run.hi, options.near_codes);
    ((run.start % SEGMENT_MAPS) << 16) | u32::from(value)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn compress(maps: &[Vec<Interval>], pixel_count: u32) -> RunData {
        compress_with(maps, pixel_count, CompressOptions::default())
    }

    fn compress_with(maps: &[Vec<Interval>], pixel_count: u32, o: CompressOptions) -> RunData {
        let mut c = Compressor::with_options(pixel_count, maps.len() as u32, o);
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

    /// Reference for the online merge, in place, over a whole segment: while a run of at most `max_len` maps lies between two runs whose
    /// intervals intersect, drop it and join its neighbours (their intersection). `runs` are one
    /// pixel's runs of one segment in order; the last one's length is taken as unbounded.
    fn merge_short_runs(runs: &mut Vec<Open>, max_len: u32) {
        let mut kept: Vec<Open> = Vec::with_capacity(runs.len());
        let mut i = 0;
        while i < runs.len() {
            if let (Some(prev), Some(next)) = (kept.last_mut(), runs.get(i + 1)) {
                let (lo, hi) = (prev.lo.max(next.lo), prev.hi.min(next.hi));
                if next.start - runs[i].start <= max_len && lo <= hi {
                    prev.lo = lo;
                    prev.hi = hi;
                    i += 2;
                    continue;
                }
            }
            kept.push(runs[i]);
            i += 1;
        }
        *runs = kept;
    }

    #[test]
    fn a_short_excursion_is_merged_only_when_asked() {
        // Pixel 0: wall, one map of block, wall again.
        let maps = vec![
            vec![(100u16, u16::MAX)],
            vec![(110, u16::MAX)],
            vec![(20, 40)],
            vec![(105, u16::MAX)],
        ];
        assert_eq!(compress(&maps, 1).runs.len(), 3);
        let merged = compress_with(
            &maps,
            1,
            CompressOptions {
                merge_short_runs: 1,
                ..Default::default()
            },
        );
        assert_eq!(merged.runs.len(), 1);
        // The merged run holds the intersection of its neighbours: [110, MAX].
        assert!(merged.lookup(0, 0) >= 110 && merged.lookup(3, 0) >= 110);
        // An excursion longer than the limit stays.
        let mut longer = maps.clone();
        longer.insert(2, vec![(25, 45)]);
        let kept = compress_with(
            &longer,
            1,
            CompressOptions {
                merge_short_runs: 1,
                ..Default::default()
            },
        );
        assert_eq!(kept.runs.len(), 3);
    }

    #[test]
    fn balanced_value_is_inside_and_below_the_middle() {
        for (lo, hi) in [
            (0u16, 0u16),
            (10, 20),
            (100, 60000),
            (5, u16::MAX),
            (65535, 65535),
        ] {
            let m = RunValue::Middle.pick(lo, hi, 131.0);
            let b = RunValue::Balanced.pick(lo, hi, 131.0);
            assert!(lo <= b && b <= hi && b <= m, "{lo} {hi}: {b} {m}");
        }
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
            let count = compress(&maps, 3).runs.len();
            for run_value in RunValue::ALL {
                let o = CompressOptions { run_value, near_codes: 131.0, ..Default::default() };
                let rd = compress_with(&maps, 3, o);
                // The run value never changes the (minimal) cut.
                prop_assert_eq!(rd.runs.len(), count);
                for (k, m) in maps.iter().enumerate() {
                    for (p, &(a, b)) in m.iter().enumerate() {
                        let v = rd.lookup(k as u32, p as u32);
                        prop_assert!(a <= v && v <= b, "map {} pixel {} value {} not in [{}, {}]", k, p, v, a, b);
                    }
                }
            }
            // Merging never adds runs, and the online merge equals the whole-segment reference.
            for k in 1..4u32 {
                let o = CompressOptions { merge_short_runs: k, ..Default::default() };
                let merged = compress_with(&maps, 3, o);
                prop_assert!(merged.runs.len() <= count);
                let mut expected = Vec::new();
                for p in 0..3 {
                    let mut runs: Vec<Open> = Vec::new();
                    let mut cur = Open { start: 0, lo: 0, hi: u16::MAX };
                    for (m, map) in maps.iter().enumerate() {
                        let (a, b) = map[p];
                        let (lo, hi) = (cur.lo.max(a), cur.hi.min(b));
                        if lo <= hi {
                            cur.lo = lo;
                            cur.hi = hi;
                        } else {
                            runs.push(cur);
                            cur = Open { start: m as u32, lo: a, hi: b };
                        }
                    }
                    runs.push(cur);
                    merge_short_runs(&mut runs, k);
                    expected.extend(runs.iter().map(|r| pack(r, &o)));
                }
                prop_assert_eq!(&merged.runs, &expected);
            }
        }
    }
}
