//! What a pass does, counted by its CPU twin (issue 48 item 0; `cssm render --stats`): the
//! final gather's walk over the hierarchy for a sample of its pixels' 8x8 tiles, every node
//! visited and queried, every load of the CSSM query, the tiles' warps replayed
//! ([`super::warp`]) and the cost model's milliseconds for the whole launch ([`super::cost`]).

use cssm_formats::{
    CssmFile, Scene,
    visibility::{Buffer, Load, QueryTally, QueryWork, Site, VisibilityQuery},
};
use glam::Vec3;

use super::{
    GatherTally,
    cost::{CostModel, Launch},
    warp::{LaneTrace, WARP_LANES, WarpStats, replay_warp, tile_warps},
};
use crate::{
    RuntimeError,
    common::camera::View,
    gpu_types::GpuMaterial,
    lightcuts::cpu::{Receiver, gather_planes_counted, receivers},
    radiosity::cpu::TwinScene,
};

/// Mean, 95th percentile and largest of a count over receivers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// 95th percentile.
    pub p95: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    fn of(mut values: Vec<u32>) -> Self {
        if values.is_empty() {
            return Self::default();
        }
        values.sort_unstable();
        let n = values.len();
        Self {
            mean: values.iter().map(|&v| f64::from(v)).sum::<f64>() / n as f64,
            p95: f64::from(values[(n * 95 / 100).min(n - 1)]),
            max: f64::from(values[n - 1]),
        }
    }
}

/// One pass's work, counted on a sample of its receivers.
#[derive(Clone, Debug, Default)]
pub struct PassStats {
    /// The pass.
    pub pass: &'static str,
    /// Threads the pass launches (one a receiver).
    pub threads: u64,
    /// Threads the cost model's device holds resident.
    pub resident_threads: u64,
    /// Receivers counted (those of the sampled tiles that see a surface).
    pub sampled: usize,
    /// Nodes visited per receiver.
    pub visited: Spread,
    /// Nodes queried per receiver (the cut's nodes with light and transfer).
    pub queried: Spread,
    /// The CSSM query's work over the sample.
    pub work: QueryWork,
    /// The sampled tiles' warps replayed (the walk's node loads and the query's).
    pub warps: WarpStats,
    /// The cost model's milliseconds for the whole launch (memory alone: a floor).
    pub predicted_ms: f64,
    /// The device the prediction is for.
    pub model: &'static str,
}

impl PassStats {
    /// CSSM taps per query.
    pub fn taps_per_query(&self) -> f64 {
        self.work.taps as f64 / (self.queried.mean * self.sampled as f64).max(1.0)
    }

    /// Taps per receiver.
    pub fn taps_per_receiver(&self) -> f64 {
        self.work.taps as f64 / self.sampled.max(1) as f64
    }

    /// Search steps per tap.
    pub fn steps_per_tap(&self) -> f64 {
        self.work.search_steps as f64 / self.work.taps.max(1) as f64
    }

    /// Bytes the query reads per receiver.
    pub fn query_bytes_per_receiver(&self) -> f64 {
        self.work.bytes() as f64 / self.sampled.max(1) as f64
    }
}

impl std::fmt::Display for PassStats {
    /// The stats as `cssm render --stats` prints them, a line each.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let spread = |s: Spread| format!("mean {:.1}, p95 {:.0}, max {:.0}", s.mean, s.p95, s.max);
        writeln!(
            f,
            "  receivers counted {}; threads {} against the model device's {} resident",
            self.sampled, self.threads, self.resident_threads
        )?;
        writeln!(f, "  nodes visited per receiver: {}", spread(self.visited))?;
        writeln!(f, "  nodes queried per receiver: {}", spread(self.queried))?;
        writeln!(
            f,
            "  CSSM taps per query {:.2}, per receiver {:.0}; search steps per tap {:.2}; \
             query bytes per receiver {:.0}",
            self.taps_per_query(),
            self.taps_per_receiver(),
            self.steps_per_tap(),
            self.query_bytes_per_receiver()
        )?;
        writeln!(
            f,
            "  warp replay: lane efficiency {:.2}, {:.2} sectors per warp load",
            self.warps.lane_efficiency(),
            self.warps.sectors_per_load()
        )?;
        write!(
            f,
            "  predicted GPU ms (memory alone, a floor): {:.2} on {}",
            self.predicted_ms, self.model
        )
    }
}

/// One lane of the replay: the query's counters and loads, the walk's nodes.
#[derive(Default)]
struct GatherLane {
    work: QueryWork,
    trace: LaneTrace,
    visited: u32,
    queried: u32,
}

impl QueryTally for GatherLane {
    fn load(&mut self, site: Site, load: Load) {
        self.work.load(site, load);
        self.trace.load(site, load);
    }
}

impl GatherTally for GatherLane {
    fn node(&mut self, iteration: u32, node: u32) {
        self.visited += 1;
        self.trace.iteration(iteration);
        // The walk reads the node (96 bytes) and its radiance (16) at every visit.
        let own = |kind| {
            (
                iteration,
                Site {
                    finding: 3,
                    ..Site::default()
                },
                kind,
            )
        };
        let node = u64::from(node);
        self.trace.push(own(20), Buffer::Kernel(1), 96 * node, 96);
        self.trace.push(own(21), Buffer::Kernel(2), 16 * node, 16);
    }

    fn query(&mut self) {
        self.queried += 1;
    }
}

/// The stats of a pass over `warps` (each a warp's lanes; `None` an idle lane), `walk` telling
/// one receiver's work to its lane: the counts summed, the warps replayed, and the launch of
/// `threads` threads over `file` priced by the cost model.
fn count_warps<R>(
    pass: &'static str,
    data: u64,
    threads: u64,
    warps: impl Iterator<Item = Vec<Option<R>>>,
    mut walk: impl FnMut(&R, &mut GatherLane),
) -> PassStats {
    let mut stats = PassStats {
        pass,
        threads,
        resident_threads: CostModel::H200.resident_threads as u64,
        model: CostModel::H200.device,
        ..Default::default()
    };
    let (mut visited, mut queried) = (Vec::new(), Vec::new());
    for warp in warps {
        let lanes: Vec<LaneTrace> = warp
            .iter()
            .map(|receiver| {
                let mut lane = GatherLane::default();
                if let Some(r) = receiver {
                    walk(r, &mut lane);
                    visited.push(lane.visited);
                    queried.push(lane.queried);
                    stats.work += lane.work;
                    stats.sampled += 1;
                }
                lane.trace
            })
            .collect();
        if !lanes.is_empty() {
            stats.warps += replay_warp(&lanes);
        }
    }
    stats.visited = Spread::of(visited);
    stats.queried = Spread::of(queried);
    stats.predicted_ms = CostModel::H200.predict_ms(&Launch {
        stats: stats.warps.scaled(threads.div_ceil(WARP_LANES as u64)),
        threads,
        data_bytes: data,
    });
    stats
}

/// The bytes a walk over `file` reads: the query's data and the hierarchy, a node (96 bytes)
/// and its radiance (16).
fn walk_data_bytes(file: &CssmFile) -> u64 {
    file.runs.gpu_bytes()
        + super::cost::query_table_bytes(file)
        + 112 * file.hierarchy.nodes.len() as u64
}

/// The final gather's stats (`lightcuts/final_gather.wgsl`) at `width` x `height`, gathering at
/// one pixel in `downsample`² (the representative taken as each block's top-left pixel) as
/// `form` says, from node radiance `radiance` with the oracle's `threshold` and `exposure`
/// (the far field's bicubic lookup is not counted: 16 texels and their values a pixel, against
/// the walks' hundreds of nodes): every `step`-th tile
/// of the gather's 8x8 tiles counted so that about `tiles` are, each tile's two warps (its top
/// and bottom four rows).
///
/// # Errors
/// A texture of the scene that does not load.
#[allow(clippy::too_many_arguments)]
pub fn final_gather_stats(
    scene: &Scene,
    file: &CssmFile,
    view: &View,
    radiance: &[Vec3],
    form: crate::lightcuts::cpu::TwinGather,
    downsample: u32,
    threshold: f32,
    exposure: f32,
    tiles: u32,
) -> Result<PassStats, RuntimeError> {
    let query = VisibilityQuery::new(file, Default::default());
    let twin = TwinScene::baked(&query, &crate::radiosity::emitting_materials(scene));
    let seen = receivers(scene, file, view)?;
    let ds = downsample.max(1);
    let (lw, lh) = (view.width.div_ceil(ds), view.height.div_ceil(ds));
    let tile_count = lw.div_ceil(8) * lh.div_ceil(8);
    let step = (tile_count / tiles.max(1)).max(1);
    let material = |triangle: u32| {
        let m = &scene.materials[scene.triangle_materials[triangle as usize] as usize];
        GpuMaterial {
            kd: m.kd,
            ns: m.ns,
            ks: m.ks,
            ..Default::default()
        }
    };
    let warps = (0..tile_count)
        .step_by(step as usize)
        .flat_map(|tile| tile_warps(lw, lh, tile))
        .map(|pixels| {
            pixels
                .into_iter()
                .map(|(x, y)| {
                    let (px, py) = ((x * ds).min(view.width - 1), (y * ds).min(view.height - 1));
                    seen[(py * view.width + px) as usize]
                })
                .collect()
        });
    Ok(count_warps(
        "final gather",
        walk_data_bytes(file),
        u64::from(lw) * u64::from(lh),
        warps,
        |&(r, triangle): &(Receiver, u32), lane| {
            gather_planes_counted(
                &twin,
                radiance,
                form,
                threshold,
                exposure,
                None,
                &r,
                &material(triangle),
                lane,
            );
        },
    ))
}

/// The radiosity gather's stats (`radiosity/gather.wgsl`, one thread a leaf texel in the
/// hierarchy's leaf order) for one bounce from node radiance `radiance`, texels reflecting
/// `albedo`, with the oracle's `threshold` and `exposure`: every `step`-th warp of 32
/// consecutive leaves counted so that about `warps` are. With a `split` (its near radius above
/// 0), the same kernel as `lightcuts`' far-field pass (what it leaves to the pixels left out;
/// `emitting`, per material, whether it emits: [`crate::radiosity::emitting_materials`]).
pub fn radiosity_gather_stats(
    file: &CssmFile,
    radiance: &[Vec3],
    albedo: &[Vec3],
    (threshold, exposure): (f32, f32),
    (split, emitting): (crate::radiosity::cpu::FarSplit, &[bool]),
    warps: u32,
) -> PassStats {
    let query = VisibilityQuery::new(file, Default::default());
    let twin = TwinScene::baked(&query, emitting);
    let nodes = &twin.hierarchy.nodes;
    let leaves: Vec<u32> = nodes
        .iter()
        .filter(|n| n.count == 1)
        .map(|n| twin.hierarchy.leaf_texels[n.first as usize])
        .collect();
    let all = leaves.len().div_ceil(WARP_LANES);
    let step = (all / warps.max(1) as usize).max(1);
    let traversal = crate::radiosity::cpu::Traversal {
        threshold,
        exposure,
    };
    let sampled = leaves
        .chunks(WARP_LANES)
        .step_by(step)
        .map(|warp| warp.iter().map(|&t| Some(t)).collect());
    let pass = if split.near_radius > 0.0 {
        "lightcuts far field"
    } else {
        "radiosity gather"
    };
    count_warps(
        pass,
        walk_data_bytes(file),
        leaves.len() as u64,
        sampled,
        |&texel: &u32, lane| {
            let t = &twin.texels[texel as usize];
            crate::radiosity::cpu::gather_texel_split(
                &twin,
                nodes,
                radiance,
                &traversal,
                split,
                texel,
                t.pos(),
                t.nrm(),
                albedo[texel as usize].max_element(),
                lane,
            );
        },
    )
}

/// A lane of [`link_product_stats`]: its lane in the workgroup, its receiver's table entry
/// (leaf), links and slot start.
type ProductLane<'a> = (usize, usize, &'a [crate::radiosity::cpu::Link], u64);

/// The stats of a product over cached links (`radiosity/product.wgsl`: a workgroup of
/// [`crate::shaders::WORKGROUP_1D`] lanes a leaf texel, in leaf order, its lanes striding over
/// the leaf's links together; the radiosity's bounce or, with `far`, `lightcuts`' far field)
/// over `leaf_count` leaves and `node_count` nodes, `cut` giving a leaf's links
/// (`radiosity::cpu::receiver_links`): runs of 32 consecutive leaves, every `step`-th, counted
/// so that about `warps` runs are, each leaf's slot laid out from its run's first as
/// `radiosity::links::slot_capacity` lays them (the buffer's size, for the cost model, from
/// the sampled slots' mean). No CSSM query: the nodes visited a receiver are its links; a
/// warp's loads are the leaf's table entry (8 bytes, the same for every lane), then per
/// stride a link (8), its bound (4) and its node's radiance (16) a lane. The workgroup's sum
/// in shared memory is not counted.
pub fn link_product_stats(
    (leaf_count, node_count): (usize, usize),
    cut: impl Fn(usize) -> Vec<crate::radiosity::cpu::Link>,
    far: bool,
    warps: u32,
) -> PassStats {
    let group = crate::shaders::WORKGROUP_1D as usize;
    let runs = leaf_count.div_ceil(WARP_LANES);
    let step = (runs / warps.max(1) as usize).max(1);
    // The sampled leaves: (leaf, links, slot start).
    let mut sampled = Vec::new();
    for run in (0..runs).step_by(step) {
        let mut start = 0u64;
        for leaf in run * WARP_LANES..((run + 1) * WARP_LANES).min(leaf_count) {
            let links = cut(leaf);
            let capacity = crate::radiosity::links::slot_capacity(links.len() as u32);
            sampled.push((leaf, links, start));
            start += u64::from(capacity);
        }
    }
    let slots: u64 = sampled
        .iter()
        .map(|(_, l, _)| u64::from(crate::radiosity::links::slot_capacity(l.len() as u32)))
        .sum();
    let mean_slots = slots as f64 / sampled.len().max(1) as f64;
    // Each leaf's workgroup in warps of 32 of its lanes.
    let lanes = sampled.iter().flat_map(|(leaf, links, start)| {
        (0..group).step_by(WARP_LANES).map(move |first| {
            (first..first + WARP_LANES)
                .map(|lane| Some((lane, *leaf, &links[..], *start)))
                .collect::<Vec<_>>()
        })
    });
    let own = |iteration, kind| {
        (
            iteration,
            Site {
                finding: 3,
                ..Site::default()
            },
            kind,
        )
    };
    let mut stats = count_warps(
        if far {
            "lightcuts far-field product"
        } else {
            "radiosity product"
        },
        // The links and their bounds, the table, the node radiance.
        (12.0 * mean_slots * leaf_count as f64) as u64
            + 8 * leaf_count as u64
            + 16 * node_count as u64,
        (group * leaf_count) as u64,
        lanes,
        |&(lane, leaf, links, start): &ProductLane, trace| {
            trace
                .trace
                .push(own(0, 22), Buffer::Kernel(7), 8 * leaf as u64, 8);
            for (k, i) in (lane..links.len()).step_by(group).enumerate() {
                let (k, at) = (k as u32 + 1, start + i as u64);
                trace.trace.push(own(k, 23), Buffer::Kernel(8), 8 * at, 8);
                trace.trace.push(own(k, 24), Buffer::Kernel(9), 4 * at, 4);
                let node = u64::from(links[i].node);
                trace
                    .trace
                    .push(own(k, 25), Buffer::Kernel(4), 16 * node, 16);
            }
        },
    );
    // Per receiver, not per lane.
    stats.sampled = sampled.len();
    stats.visited = Spread::of(sampled.iter().map(|(_, l, _)| l.len() as u32).collect());
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 32 leaves, each with 100 links to node 0: each leaf's workgroup is two warps, whose
    /// lanes read the table entry together (1 sector), then per stride 32 consecutive links (8
    /// sectors), bounds (4) and the one node's radiance (1); the lanes past the links idle.
    #[test]
    fn a_product_warp_strides_over_one_receivers_links() {
        let link = crate::radiosity::cpu::Link {
            node: 0,
            transfer: 1.0,
            bound: 0.0,
        };
        let stats = link_product_stats((32, 1), |_| vec![link; 100], false, 1);
        let group = crate::shaders::WORKGROUP_1D as u64;
        assert_eq!((stats.threads, stats.sampled), (32 * group, 32));
        assert_eq!(stats.visited.mean, 100.0);
        // 100 links over 64 lanes: two strides, the second with 36 lanes (the first warp full,
        // the second's 4 lanes); each warp: the entry, then its strides' three loads.
        let warps = 32 * 2;
        assert_eq!(stats.warps.warps, warps);
        assert_eq!(stats.warps.load_instructions, 32 * (1 + 2 * 3 + 1 + 2 * 3));
        assert!(stats.warps.sectors_per_load() < 5.0, "{:?}", stats.warps);
        assert_eq!(stats.work, QueryWork::default());
    }
}
