//! The query benchmarks' counts (issue 48): the CPU twin's work and warp replay of the query
//! kernels on a sample of a benchmark's own queries, and the cost model's prediction from them.

use cssm::{
    formats::{
        CssmFile,
        cssm::RunData,
        visibility::{Buffer, Load, QueryTally, QueryWork, Site, VisibilityQuery},
    },
    runtime::{
        visibility::{
            QueryPair,
            gather::Receiver,
            tiles::{TILE_PIXELS, TilePixel, TileSenders},
        },
        work::{
            cost::{CostModel, Launch},
            warp::{LaneTrace, WARP_LANES, WarpStats, replay, replay_warp},
        },
    },
};

/// Which kernel's loads are replayed: today's query, the one before it, or today's over another
/// layout of the run data (issue 48 item 2: what a tap would cost were its depth found
/// otherwise).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel<'a> {
    /// Today's query.
    Lean,
    /// The query before the lean rewrite (commit 82dc5c9 and before, as measured on the H200 at
    /// 4eec3d2): the same loads, and after each search one more, of the run it had found.
    Before,
    /// Every map decoded: a tap reads its pixel's 16-bit depth, one load and no search.
    Decoded,
    /// Quad-merged runs: one list per 2x2 PCF footprint, each run holding the four pixels'
    /// depths (16 bytes); a footprint searches once for its four taps.
    QuadRuns(&'a QuadRuns),
}

/// The runs merged over every 2x2 pixel footprint (the PCF's: pixel (x, y) with x + 1 and
/// y + 1, clamped to the face), one list per footprint origin and segment: a footprint's run
/// starts where any of its four pixels' does.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct QuadRuns {
    /// Slot `segment * pixel_count + pixel` (the origin's): its starts are
    /// `starts[offsets[slot]..offsets[slot + 1]]`.
    pub offsets: Vec<u32>,
    /// Run starts within the segment, sorted per slot.
    pub starts: Vec<u32>,
}

/// Bytes a quad-merged run takes: its start and four 16-bit depths, padded to 16.
pub const QUAD_RUN_BYTES: u64 = 16;

impl QuadRuns {
    /// The quad lists of `runs` at cube resolution `n`.
    pub fn new(runs: &RunData, n: u32) -> Self {
        let mut offsets = vec![0u32];
        let mut starts = Vec::new();
        let segments = runs.segment_count().max(1);
        for segment in 0..segments {
            for pixel in 0..runs.pixel_count {
                let (face, rest) = (pixel / (n * n), pixel % (n * n));
                let (x0, y0) = (rest % n, rest / n);
                let (x1, y1) = ((x0 + 1).min(n - 1), (y0 + 1).min(n - 1));
                let mut merged: Vec<u32> = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
                    .iter()
                    .flat_map(|&(x, y)| {
                        let slot = (segment * runs.pixel_count + face * n * n + y * n + x) as usize;
                        let (lo, hi) =
                            (runs.offsets[slot] as usize, runs.offsets[slot + 1] as usize);
                        runs.runs[lo..hi].iter().map(|r| r >> 16)
                    })
                    .collect();
                merged.sort_unstable();
                merged.dedup();
                starts.extend(merged);
                offsets.push(starts.len() as u32);
            }
        }
        Self { offsets, starts }
    }

    /// Bytes on the GPU: offsets and runs.
    pub fn bytes(&self) -> u64 {
        4 * self.offsets.len() as u64 + QUAD_RUN_BYTES * self.starts.len() as u64
    }
}

/// One lane: the counters, the trace, and the layout its taps find their depths in.
struct Lane<'a> {
    work: QueryWork,
    trace: LaneTrace,
    kernel: Kernel<'a>,
    runs: &'a RunData,
    cube: u32,
    /// The current texel query's footprint has been searched ([`Kernel::QuadRuns`]).
    searched: bool,
}

impl<'a> Lane<'a> {
    fn new(file: &'a CssmFile, kernel: Kernel<'a>) -> Self {
        Self {
            work: QueryWork::default(),
            trace: LaneTrace::default(),
            kernel,
            runs: &file.runs,
            cube: file.params.cube_resolution,
            searched: false,
        }
    }
}

impl QueryTally for Lane<'_> {
    fn load(&mut self, site: Site, load: Load) {
        self.work.load(site, load);
        if let Load::Texel(_) = load {
            // A texel's query begins: its footprint is still to search.
            self.searched = false;
        }
        let searched = matches!(load, Load::Offsets(_) | Load::Probe(_));
        if !searched || matches!(self.kernel, Kernel::Lean | Kernel::Before) {
            self.trace.load(site, load);
        }
    }

    fn lookup(&mut self, site: Site, slot: u32, local: u32) {
        let runs = self.runs;
        let probe = |step: u8| (0, Site { step, ..site }, 5);
        match self.kernel {
            Kernel::Lean => {}
            Kernel::Before => {
                let (lo, hi) = (
                    runs.offsets[slot as usize] as usize,
                    runs.offsets[slot as usize + 1] as usize,
                );
                let found = lo
                    + runs.runs[lo..hi]
                        .partition_point(|&r| r >> 16 <= local)
                        .max(1)
                    - 1;
                // After the 17 unrolled steps.
                self.trace
                    .load(Site { step: 18, ..site }, Load::Probe(found as u32));
            }
            Kernel::Decoded => {
                let map = slot / runs.pixel_count * cssm::formats::cssm::SEGMENT_MAPS + local;
                let pixel = slot % runs.pixel_count;
                let at = 2 * (u64::from(map) * u64::from(runs.pixel_count) + u64::from(pixel));
                self.trace.push(probe(0), Buffer::Runs, at, 2);
            }
            Kernel::QuadRuns(quads) => {
                if self.searched {
                    return;
                }
                self.searched = true;
                // The footprint's origin: this tap's pixel less its place in the 2x2.
                let n = self.cube;
                let pixel = slot % runs.pixel_count;
                let (dx, dy) = (u32::from(site.tap & 1), u32::from(site.tap >> 1));
                let rest = pixel % (n * n);
                let (x, y) = ((rest % n).saturating_sub(dx), (rest / n).saturating_sub(dy));
                let origin = slot - rest + y * n + x;
                let (lo, hi) = (
                    quads.offsets[origin as usize] as usize,
                    quads.offsets[origin as usize + 1] as usize,
                );
                let key = (0, Site { tap: 0, ..site }, 6);
                self.trace
                    .push(key, Buffer::Offsets, 4 * u64::from(origin), 8);
                // The search over the merged starts, as the lean query's.
                let (mut first, mut count, mut step) = (lo, hi - lo, 1u8);
                while count > 0 {
                    let half = count / 2;
                    let i = first + half;
                    self.trace.push(
                        (
                            0,
                            Site {
                                tap: 0,
                                step,
                                ..site
                            },
                            7,
                        ),
                        Buffer::Runs,
                        QUAD_RUN_BYTES * i as u64,
                        QUAD_RUN_BYTES,
                    );
                    if quads.starts[i] <= local {
                        first = i + 1;
                        count -= half + 1;
                    } else {
                        count = half;
                    }
                    step += 1;
                }
            }
        }
    }
}

/// A sample of a kernel's queries, counted and replayed.
#[derive(Clone, Copy, Debug, Default)]
pub struct Counted {
    /// The CPU twin's counters over the sample.
    pub work: QueryWork,
    /// Queries in the sample.
    pub queries: usize,
    /// The sample's warps replayed.
    pub stats: WarpStats,
    /// Loads of the run data (offsets and runs, or whatever holds the depths) over the sample.
    pub depth_loads: u64,
}

/// Loads of `lane` that find depths (offsets and runs).
fn depth_loads(lane: &LaneTrace) -> u64 {
    lane.loads
        .iter()
        .filter(|(_, buffer, _, _)| matches!(buffer, Buffer::Offsets | Buffer::Runs))
        .count() as u64
}

impl Counted {
    /// The cost model's milliseconds for the whole launch of `threads` threads, reading
    /// `data_bytes` of data: the sample's replay scaled to the launch's warps.
    pub fn predicted_ms(&self, model: &CostModel, threads: u64, data_bytes: u64) -> f64 {
        let warps = threads.div_ceil(WARP_LANES as u64);
        model.predict_ms(&Launch {
            stats: self.stats.scaled(warps),
            threads,
            data_bytes,
        })
    }
}

/// One lane a item of `items`, each asked by `ask`: the lanes' counters summed, and the warp
/// replay of the lanes in warps of 32 consecutive items.
fn replayed<T>(
    file: &CssmFile,
    kernel: Kernel,
    items: &[T],
    mut ask: impl FnMut(&T, &mut Lane),
) -> (QueryWork, WarpStats, u64) {
    let mut work = QueryWork::default();
    let mut depth = 0;
    let lanes: Vec<LaneTrace> = items
        .iter()
        .map(|item| {
            let mut lane = Lane::new(file, kernel);
            ask(item, &mut lane);
            work += lane.work;
            depth += depth_loads(&lane.trace);
            lane.trace
        })
        .collect();
    (work, replay(&lanes), depth)
}

/// The query kernel (`query.wgsl`: one `cssm_visibility` a thread) over the first `sample` of
/// `pairs`, in warps of 32 consecutive pairs.
pub fn random(file: &CssmFile, pairs: &[QueryPair], sample: usize, kernel: Kernel) -> Counted {
    let query = VisibilityQuery::new(file, Default::default());
    let pairs = &pairs[..pairs.len().min(sample)];
    let (work, stats, depth_loads) = replayed(file, kernel, pairs, |pair, lane| {
        query.visibility_from_surface_counted(
            pair.sender_triangle as usize,
            pair.sender_bary,
            pair.receiver.into(),
            Some(pair.receiver_normal.into()),
            lane,
        );
    });
    Counted {
        work,
        queries: pairs.len(),
        stats,
        depth_loads,
    }
}

/// The gather kernel (`gather.wgsl`: a thread loops over `senders` texels from its first) over
/// the first `sample` receivers, in warps of 32 consecutive receivers.
pub fn gather(
    file: &CssmFile,
    receivers: &[Receiver],
    senders: u32,
    sample: usize,
    kernel: Kernel,
) -> Counted {
    let query = VisibilityQuery::new(file, Default::default());
    let texels = (file.texels.len() as u32).max(1);
    let receivers = &receivers[..receivers.len().min(sample)];
    let (work, stats, depth_loads) = replayed(file, kernel, receivers, |r, lane| {
        for k in 0..senders {
            lane.trace.iteration(k);
            query.answer_oriented_counted(
                (r.first_sender + k) % texels,
                r.position.into(),
                Some(r.normal.into()),
                Site::default(),
                lane,
            );
        }
    });
    Counted {
        work,
        queries: receivers.len() * senders as usize,
        stats,
        depth_loads,
    }
}

/// The tile kernel (`tiles.wgsl`: a workgroup a tile of 8x8 pixels and a sender, a two-ended
/// query a thread) over every `tile_step`-th tile of `pixels` and every sender: each
/// workgroup's two warps (the tile's top and bottom four rows) replayed, the kernel's own loads
/// (its pixel's record, the sender's texel record) with the query's.
pub fn tiles(
    file: &CssmFile,
    pixels: &[TilePixel],
    senders: TileSenders,
    tile_step: usize,
    kernel: Kernel,
) -> Counted {
    let query = VisibilityQuery::new(file, Default::default());
    let texels = file.texels.len() as u32;
    let mut counted = Counted::default();
    for tile in pixels.chunks(TILE_PIXELS).step_by(tile_step.max(1)) {
        let first =
            (tile.as_ptr() as usize - pixels.as_ptr() as usize) / std::mem::size_of::<TilePixel>();
        for k in 0..senders.count {
            let texel = senders.texel(k, texels);
            let y = &file.texels[texel as usize];
            for (half, warp) in tile.chunks(WARP_LANES).enumerate() {
                let (work, lanes): (Vec<QueryWork>, Vec<LaneTrace>) = warp
                    .iter()
                    .enumerate()
                    .map(|(lane_index, q)| {
                        let mut lane = Lane::new(file, kernel);
                        let i = first + half * WARP_LANES + lane_index;
                        let own = |kind: u8| {
                            (
                                0,
                                Site {
                                    finding: 2,
                                    ..Default::default()
                                },
                                kind,
                            )
                        };
                        lane.trace
                            .push(own(10), Buffer::Kernel(0), 48 * i as u64, 48);
                        if q.triangle != u32::MAX {
                            lane.trace
                                .push(own(11), Buffer::Texels, 64 * u64::from(texel), 64);
                            counted.queries += 1;
                        }
                        cssm::runtime::visibility::tiles::tile_query(
                            &query,
                            q,
                            texel,
                            y.pos(),
                            y.nrm(),
                            &mut lane,
                        );
                        (lane.work, lane.trace)
                    })
                    .unzip();
                for w in work {
                    counted.work += w;
                }
                counted.depth_loads += lanes.iter().map(depth_loads).sum::<u64>();
                counted.stats += replay_warp(&lanes);
            }
        }
    }
    counted
}
