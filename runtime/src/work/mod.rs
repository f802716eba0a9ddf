//! GPU work you can count (issue 48): the warp replay of the CPU twins' loads ([`warp`]) and
//! the cost model that predicts GPU milliseconds from it ([`cost`]). The twins tell their loads
//! through `cssm_formats::visibility::QueryTally`; the kernels' own counters
//! (`visibility::QueryKernel::counting`) hold them to what the GPU does.

pub mod cost;
pub mod warp;
