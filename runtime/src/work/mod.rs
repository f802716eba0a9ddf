//! GPU work you can count (issue 48): the warp replay of the CPU twins' loads ([`warp`]) and
//! the cost model that predicts GPU milliseconds from it ([`cost`]). The twins tell their loads
//! through `cssm_formats::visibility::QueryTally`; the kernels' own counters
//! (`visibility::QueryKernel::counting`) hold them to what the GPU does.

pub mod cost;
pub mod passes;
pub mod warp;

use cssm_formats::visibility::{QueryTally, QueryWork};

/// What a pass's CPU twin tells of its walk besides the query's loads: the final gather's and
/// the radiosity gather's nodes (`lightcuts::cpu::gather_planes_counted`).
pub trait GatherTally: QueryTally {
    /// The walk's loop reaches its `iteration`-th node, node `node` of the hierarchy (the loads
    /// that follow issue with the other lanes' same iteration).
    fn node(&mut self, iteration: u32, node: u32) {
        let _ = (iteration, node);
    }

    /// The node reached last asks the visibility query.
    fn query(&mut self) {}
}

impl GatherTally for QueryWork {}
