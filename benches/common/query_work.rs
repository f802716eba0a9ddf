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

/// Which kernel's loads are replayed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// Today's query.
    Lean,
    /// The query before the lean rewrite (commit 82dc5c9 and before, as measured on the H200 at
    /// 4eec3d2): the same loads, and after each search one more, of the run it had found.
    Before,
}

/// One lane: the counters, the trace, and for [`Kernel::Before`] the runs to find the reload in.
struct Lane<'a> {
    work: QueryWork,
    trace: LaneTrace,
    reload: Option<&'a RunData>,
}

impl QueryTally for Lane<'_> {
    fn load(&mut self, site: Site, load: Load) {
        self.work.load(site, load);
        self.trace.load(site, load);
    }

    fn lookup(&mut self, site: Site, slot: u32, local: u32) {
        if let Some(runs) = self.reload {
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
) -> (QueryWork, WarpStats) {
    let mut work = QueryWork::default();
    let lanes: Vec<LaneTrace> = items
        .iter()
        .map(|item| {
            let mut lane = Lane {
                work: QueryWork::default(),
                trace: LaneTrace::default(),
                reload: (kernel == Kernel::Before).then_some(&file.runs),
            };
            ask(item, &mut lane);
            work += lane.work;
            lane.trace
        })
        .collect();
    (work, replay(&lanes))
}

/// The query kernel (`query.wgsl`: one `cssm_visibility` a thread) over the first `sample` of
/// `pairs`, in warps of 32 consecutive pairs.
pub fn random(file: &CssmFile, pairs: &[QueryPair], sample: usize, kernel: Kernel) -> Counted {
    let query = VisibilityQuery::new(file, Default::default());
    let pairs = &pairs[..pairs.len().min(sample)];
    let (work, stats) = replayed(file, kernel, pairs, |pair, lane| {
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
    let (work, stats) = replayed(file, kernel, receivers, |r, lane| {
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
                        let mut lane = Lane {
                            work: QueryWork::default(),
                            trace: LaneTrace::default(),
                            reload: (kernel == Kernel::Before).then_some(&file.runs),
                        };
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
                counted.stats += replay_warp(&lanes);
            }
        }
    }
    counted
}
