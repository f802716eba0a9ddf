//! What a bake, a `.cssm` file and an accuracy check come to, as `cssm bake`, `cssm inspect` and
//! `cssm check` print them: one struct per command, written as
//! one JSON object for `--json` ([`BakeSummary::to_json`]) and formatted as text otherwise (its
//! `Display`), so the two outputs always tell the same figures. `cssm report compression` reads
//! its child processes' `--json` back into the same types.
//!
//! The JSON has its keys in alphabetical order and its floats printed as `f64`: the bytes these
//! commands have always printed, which scripts parse.
//!
//! ```
//! let json = r#"{"agreement":0.98,"causes_atlas":0,"causes_cube":0,"causes_filter":1,"causes_near":0,"exchanging_agreement":0.99,"exchanging_false_occluded_rate":0.01,"exchanging_false_visible_rate":0.02,"exchanging_pairs":7,"false_occluded_rate":0.01,"false_visible_rate":0.03,"occluded_occluded":4,"occluded_visible":0,"pairs":10,"seconds":0.5,"unmapped":0,"visible_occluded":1,"visible_visible":5}"#;
//! let check: cssm_output::summary::CheckSummary = serde_json::from_str(json)?;
//! assert_eq!(check.exchanging_pairs, 7);
//! assert_eq!(check.to_json(), json);
//! # Ok::<(), serde_json::Error>(())
//! ```
//!
//! One file per command: `bake` ([`BakeSummary`], and the process's [`peak_rss_bytes`]),
//! `inspect` ([`InspectSummary`]), `chunk` ([`ChunkSummary`], `cssm bake --chunk` and
//! `cssm inspect` of a chunk), `check` ([`CheckSummary`]); the JSON and text helpers they share
//! are here.

mod bake;
mod check;
mod chunk;
mod inspect;
#[cfg(test)]
mod tests;

use serde::Serialize;

use cssm_formats as formats;

pub use bake::{BakeSummary, peak_rss_bytes};
pub use check::CheckSummary;
pub use chunk::ChunkSummary;
pub use inspect::InspectSummary;

/// `value` as one line of JSON, keys in alphabetical order (serde_json's map) and `f32` fields
/// printed as the `f64` they widen to.
fn json_line<T: Serialize>(value: &T) -> String {
    serde_json::to_value(value)
        .expect("a summary has string keys only")
        .to_string()
}

/// Fields of moving objects stay out of a static scene's JSON, which keeps the keys it always had.
fn is_zero(n: &u64) -> bool {
    *n == 0
}

fn is_zero_seconds(s: &f64) -> bool {
    *s == 0.0
}

fn human_bytes(bytes: u64) -> String {
    formats::files::human_bytes(bytes, 2)
}
