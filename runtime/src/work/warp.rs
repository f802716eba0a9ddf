//! The warp replay (issue 48): lanes' loads grouped as a GPU warp executes them. A warp runs its
//! 32 lanes in lock step: a load instruction issues once for every lane that reaches it, and the
//! memory system serves the distinct 32-byte sectors those lanes touch. The CPU twins tell every
//! load with the site of the code that makes it (`cssm_formats::visibility::Site`); lanes that
//! reach the same site (in the same iteration of the kernel's loops) issue together.

use std::collections::{BTreeMap, BTreeSet};

use cssm_formats::visibility::{Buffer, Load, QueryTally, Site};

/// Lanes of a warp (NVIDIA; AMD's wave64 halves the warps and doubles each one's lanes).
pub const WARP_LANES: usize = 32;

/// Bytes of the memory system's unit of transfer between L2 and the cores.
pub const SECTOR_BYTES: u64 = 32;

/// Bytes of DRAM's unit of access (HBM's burst): a sector read alone from memory costs the
/// transfer of its whole 64-byte atom.
pub const ATOM_BYTES: u64 = 64;

/// Where a load issues: the kernel's own loop iteration (0 in straight code), the query's
/// site, and the kind of load there.
pub type SiteKey = (u32, Site, u8);

/// One lane's loads in program order: where each issues and the bytes it reads.
#[derive(Clone, Debug, Default)]
pub struct LaneTrace {
    /// (site, buffer, first byte, bytes) of every load.
    pub loads: Vec<(SiteKey, Buffer, u64, u64)>,
    /// The kernel loop iteration the next loads belong to ([`Self::iteration`]).
    iteration: u32,
}

impl LaneTrace {
    /// Starts iteration `i` of the kernel's loop: the loads told from now on issue with those of
    /// the other lanes' iteration `i`.
    pub fn iteration(&mut self, i: u32) {
        self.iteration = i;
    }

    /// A load of `bytes` bytes at byte `start` of `buffer`, at `key` (for kernels' own loads,
    /// outside the query).
    pub fn push(&mut self, key: SiteKey, buffer: Buffer, start: u64, bytes: u64) {
        self.loads.push((key, buffer, start, bytes));
    }
}

/// A stable small number for each kind of [`Load`] (part of its [`SiteKey`]).
fn kind(load: Load) -> u8 {
    match load {
        Load::TriangleUvs(_) => 0,
        Load::GridCell(_) => 1,
        Load::TexelChart(_) => 2,
        Load::Texel(_) => 3,
        Load::Offsets(_) => 4,
        Load::Probe(_) => 5,
    }
}

impl QueryTally for LaneTrace {
    fn load(&mut self, site: Site, load: Load) {
        let (buffer, start, bytes) = load.bytes();
        self.loads
            .push(((self.iteration, site, kind(load)), buffer, start, bytes));
    }
}

/// What warps did, summed over warps.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WarpStats {
    /// Warps replayed.
    pub warps: u64,
    /// Lanes in them (the last warp of a launch may be partial).
    pub lanes: u64,
    /// Load instructions issued: sites reached by at least one lane of a warp.
    pub load_instructions: u64,
    /// Lanes active at those instructions, summed.
    pub lane_loads: u64,
    /// Distinct 32-byte sectors those instructions touched, summed.
    pub sectors: u64,
    /// Distinct 64-byte DRAM atoms those instructions touched, summed.
    pub atoms: u64,
}

impl std::ops::AddAssign for WarpStats {
    fn add_assign(&mut self, o: Self) {
        self.warps += o.warps;
        self.lanes += o.lanes;
        self.load_instructions += o.load_instructions;
        self.lane_loads += o.lane_loads;
        self.sectors += o.sectors;
        self.atoms += o.atoms;
    }
}

impl WarpStats {
    /// Of the lanes a load instruction could serve, the share active: 1 when every lane of
    /// every warp reaches every load, 1/32 when one lane reaches each.
    pub fn lane_efficiency(&self) -> f64 {
        self.lane_loads as f64 / (WARP_LANES as u64 * self.load_instructions).max(1) as f64
    }

    /// Distinct 32-byte sectors a warp's load instruction touches, on average: 1 when the lanes
    /// read together, up to 32 (64 for 64-byte records) when each reads its own.
    pub fn sectors_per_load(&self) -> f64 {
        self.sectors as f64 / self.load_instructions.max(1) as f64
    }
}

/// Replays one warp of `lanes` (at most [`WARP_LANES`]).
pub fn replay_warp(lanes: &[LaneTrace]) -> WarpStats {
    debug_assert!(lanes.len() <= WARP_LANES);
    // Per site: the lanes that reach it and the sectors they touch.
    let mut sites: BTreeMap<SiteKey, (u64, BTreeSet<(Buffer, u64)>)> = BTreeMap::new();
    let mut stats = WarpStats {
        warps: 1,
        lanes: lanes.len() as u64,
        ..Default::default()
    };
    for lane in lanes {
        for &(key, buffer, start, bytes) in &lane.loads {
            let (active, sectors) = sites.entry(key).or_default();
            *active += 1;
            for sector in start / SECTOR_BYTES..=(start + bytes.max(1) - 1) / SECTOR_BYTES {
                sectors.insert((buffer, sector));
            }
        }
    }
    for (active, sectors) in sites.values() {
        stats.load_instructions += 1;
        stats.lane_loads += active;
        stats.sectors += sectors.len() as u64;
        let per_atom = ATOM_BYTES / SECTOR_BYTES;
        let atoms: BTreeSet<(Buffer, u64)> =
            sectors.iter().map(|&(b, s)| (b, s / per_atom)).collect();
        stats.atoms += atoms.len() as u64;
    }
    stats
}

/// Replays `lanes` in warps of [`WARP_LANES`] consecutive lanes (a 1D launch: invocation `i` is
/// lane `i % 32` of warp `i / 32`).
pub fn replay(lanes: &[LaneTrace]) -> WarpStats {
    let mut stats = WarpStats::default();
    for warp in lanes.chunks(WARP_LANES) {
        stats += replay_warp(warp);
    }
    stats
}

/// The pixels of the two warps of tile `tile` (row-major, `width.div_ceil(8)` across) of a
/// `width` x `height` launch of 8x8 workgroups ([`crate::shaders::WORKGROUP_2D`]): each workgroup's 64 invocations in row-major
/// order (`local_invocation_index`), whose first 32 (the tile's top four rows) form one warp and
/// last 32 the other. A tile at the image's edge has partial (or empty) warps.
pub fn tile_warps(width: u32, height: u32, tile: u32) -> [Vec<(u32, u32)>; 2] {
    const SIDE: u32 = crate::shaders::WORKGROUP_2D;
    const ROWS: u32 = WARP_LANES as u32 / SIDE;
    let tiles_x = width.div_ceil(SIDE).max(1);
    let (x0, y0) = (tile % tiles_x * SIDE, tile / tiles_x * SIDE);
    [0, 1].map(|half| {
        (y0 + ROWS * half..(y0 + ROWS * (half + 1)).min(height))
            .flat_map(|y| (x0..(x0 + SIDE).min(width)).map(move |x| (x, y)))
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lane(loads: &[(u8, u32)]) -> LaneTrace {
        let mut trace = LaneTrace::default();
        for &(tap, run) in loads {
            trace.load(
                Site {
                    tap,
                    ..Default::default()
                },
                Load::Probe(run),
            );
        }
        trace
    }

    #[test]
    fn lanes_reading_together_share_sectors_and_diverging_lanes_idle() {
        // 32 lanes read 32 consecutive runs at one site: one instruction, 4 sectors, all active.
        let together: Vec<LaneTrace> = (0..32).map(|i| lane(&[(0, i)])).collect();
        let s = replay_warp(&together);
        assert_eq!((s.load_instructions, s.lane_loads, s.sectors), (1, 32, 4));
        assert_eq!(s.lane_efficiency(), 1.0);
        // Each lane 1 KiB apart: 32 sectors.
        let apart: Vec<LaneTrace> = (0..32).map(|i| lane(&[(0, 256 * i)])).collect();
        assert_eq!(replay_warp(&apart).sectors_per_load(), 32.0);
        // Half the lanes at one site, half at another: two instructions, each half full.
        let split: Vec<LaneTrace> = (0..32).map(|i| lane(&[((i % 2) as u8, 0)])).collect();
        let s = replay_warp(&split);
        assert_eq!((s.load_instructions, s.sectors), (2, 2));
        assert_eq!(s.lane_efficiency(), 0.5);
        // A texel record spans two sectors.
        let mut t = LaneTrace::default();
        t.load(Site::default(), Load::Texel(3));
        let s = replay_warp(&[t]);
        assert_eq!((s.sectors, s.atoms), (2, 1));
    }

    #[test]
    fn tiles_make_warps_of_four_rows_of_eight() {
        let [top, bottom] = tile_warps(16, 8, 1);
        assert_eq!((top.len(), bottom.len()), (32, 32));
        // The second tile's top warp: rows 0-3 of columns 8-15.
        assert_eq!(
            &top[..9],
            &[
                (8, 0),
                (9, 0),
                (10, 0),
                (11, 0),
                (12, 0),
                (13, 0),
                (14, 0),
                (15, 0),
                (8, 1)
            ]
        );
        assert_eq!(bottom[0], (8, 4));
        // A partial tile makes partial warps: a 10x5 image's second tile is 2 wide, 5 high.
        let sizes = tile_warps(10, 5, 1).map(|w| w.len());
        assert_eq!(sizes, [8, 2]);
        assert_eq!(tile_warps(10, 5, 0).map(|w| w.len()), [32, 8]);
    }
}
