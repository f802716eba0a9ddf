//! The GPU query's work, load by load (issue 48: GPU work you can count). The CPU reference
//! ([`super::VisibilityQuery`]) follows the GPU query's control flow (the runtime's
//! `visibility/cssm.wgsl`) exactly, so its `*_counted` functions can report every memory read
//! the GPU makes for the same query, and where in the code it makes it: [`QueryWork`] sums them
//! into the counters the kernels also count (`tests/gpu/query.rs` holds the two equal, query for
//! query); the runtime's warp replay groups them by [`Site`] across the lanes of a warp.

/// One memory read of the GPU query, in the buffers of the CSSM bind group.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Load {
    /// A triangle's six atlas coordinates (24 bytes), turning a surface point into atlas space.
    TriangleUvs(u32),
    /// An atlas grid cell (4 bytes): which texel covers it.
    GridCell(u32),
    /// A texel's chart (4 bytes of its record), the sender filter's same-chart test.
    TexelChart(u32),
    /// A texel's record (64 bytes): the cube map a query asks.
    Texel(u32),
    /// A (segment, pixel) slot's two run offsets (8 bytes): where its run list lies.
    Offsets(u32),
    /// A search step's probe (4 bytes; run index).
    Probe(u32),
}

/// The buffers of [`Load`], as the GPU binds them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Buffer {
    /// `cssm_triangle_uvs`: 6 floats a triangle.
    TriangleUvs,
    /// `cssm_grid`: a texel index an atlas cell.
    Grid,
    /// `cssm_texels`: 64-byte records (`GpuTexel`).
    Texels,
    /// `cssm_offsets`: a `u32` a slot, and one more.
    Offsets,
    /// `cssm_runs`: a `u32` a run (over however many bindings).
    Runs,
    /// A buffer of the kernel's own (its inputs), numbered by it: for a kernel's loads outside
    /// the query, which only a warp replay is told of.
    Kernel(u8),
}

/// Bytes of a texel record on the GPU (`GpuTexel`).
pub const TEXEL_BYTES: u64 = 64;
/// Offset of `chart` in a texel record (after position, area and normal).
pub const TEXEL_CHART_OFFSET: u64 = 28;

impl Load {
    /// The buffer read, the first byte and the bytes read.
    pub fn bytes(self) -> (Buffer, u64, u64) {
        match self {
            Load::TriangleUvs(t) => (Buffer::TriangleUvs, 24 * u64::from(t), 24),
            Load::GridCell(c) => (Buffer::Grid, 4 * u64::from(c), 4),
            Load::TexelChart(t) => (
                Buffer::Texels,
                TEXEL_BYTES * u64::from(t) + TEXEL_CHART_OFFSET,
                4,
            ),
            Load::Texel(t) => (Buffer::Texels, TEXEL_BYTES * u64::from(t), TEXEL_BYTES),
            Load::Offsets(slot) => (Buffer::Offsets, 4 * u64::from(slot), 8),
            Load::Probe(i) => (Buffer::Runs, 4 * u64::from(i), 4),
        }
    }
}

/// Where in the GPU query's code a load happens: every lane of a warp that reaches the same
/// site executes the same instruction (the query is unrolled over ends, sender slots, PCF taps
/// and search steps), so the warp replay groups loads by it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Site {
    /// Which end of a two-ended query asks (0: the sender's cube maps, 1: the receiver's).
    pub end: u8,
    /// The sender slot of the end's 2x2 sender filter (`CssmSenders`' x, y, z, w), or the
    /// sender-finding step (0: the point's cell and its neighbourhood, 1-4: the filter's taps).
    pub sender: u8,
    /// The PCF tap (0-3: the 2x2 pixels in `cssm_answer_texel`'s order), or the cell of the
    /// point's neighbourhood searched (0: its own, 1-25: the 5x5 around it).
    pub tap: u8,
    /// The search step (0: the offsets, k: the k-th probe).
    pub step: u8,
    /// Finding the senders (1) rather than asking their cube maps (0).
    pub finding: u8,
}

/// What a counted query reports its loads to.
pub trait QueryTally {
    /// The GPU query reads `load` at `site`.
    fn load(&mut self, site: Site, load: Load);

    /// A tap at `site` searches the run list of slot `slot` for the map at `local` in its
    /// segment (after loading its offsets): for a tally that models another search over the
    /// same lists.
    fn lookup(&mut self, site: Site, slot: u32, local: u32) {
        let _ = (site, slot, local);
    }
}

/// The work of visibility queries, counted as the GPU query does it: what its kernels'
/// counters report (`CssmWork` in the runtime's `visibility/cssm.wgsl`) and what the GPU cost
/// of a pass is predicted from. Sums over queries with `+=`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct QueryWork {
    /// Pixel tests that read the run data (a don't-care pixel reads nothing).
    pub taps: u64,
    /// Binary-search steps, each one load of a run: at most the file's
    /// [`RunData::search_steps`] a tap.
    ///
    /// [`RunData::search_steps`]: crate::cssm::RunData::search_steps
    pub search_steps: u64,
    /// Texel records loaded, one per sender texel asked.
    pub texel_loads: u64,
    /// Atlas grid cells and texels' charts read, finding a point's senders.
    pub sender_loads: u64,
    /// Triangles' atlas coordinates read.
    pub triangle_loads: u64,
}

impl QueryTally for QueryWork {
    fn load(&mut self, _: Site, load: Load) {
        match load {
            Load::TriangleUvs(_) => self.triangle_loads += 1,
            Load::GridCell(_) | Load::TexelChart(_) => self.sender_loads += 1,
            Load::Texel(_) => self.texel_loads += 1,
            Load::Offsets(_) => self.taps += 1,
            Load::Probe(_) => self.search_steps += 1,
        }
    }
}

impl std::ops::AddAssign for QueryWork {
    fn add_assign(&mut self, other: Self) {
        self.taps += other.taps;
        self.search_steps += other.search_steps;
        self.texel_loads += other.texel_loads;
        self.sender_loads += other.sender_loads;
        self.triangle_loads += other.triangle_loads;
    }
}

impl QueryWork {
    /// Bytes read: 64 a texel record, 24 a triangle's coordinates, 8 a tap's two offsets, 4 a
    /// grid cell, chart or run.
    pub fn bytes(&self) -> u64 {
        TEXEL_BYTES * self.texel_loads
            + 24 * self.triangle_loads
            + 4 * self.sender_loads
            + 8 * self.taps
            + 4 * self.search_steps
    }
}
