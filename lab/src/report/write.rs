//! The report's files: `compression.md` (tables, winners, targets), `compression.csv` (one line
//! per row, every figure) and `compression.svg` (ratio against atlas resolution). Each is
//! written atomically (temporary file, then rename), so a failed run leaves the old ones.
//!
//! Here the three files written ([`write_all`]) and the figures' formats; `write/markdown.rs`
//! the Markdown's tables and which option wins, `write/targets.rs` the targets and the
//! time per table, `write/csv.rs` the CSV, `write/chart.rs` the chart.

mod chart;
mod csv;
mod markdown;
mod targets;

use std::path::Path;

pub use chart::svg;
pub use csv::csv;
pub use markdown::markdown;

use super::{Report, Row, TableId};

/// Agreement within this many percentage points of the baseline counts as "the same accuracy"
/// (every row is checked on the same pairs).
pub const SAME_ACCURACY_POINTS: f64 = 0.1;

/// Writes the three files into `out`.
pub fn write_all(report: &Report, out: &Path) -> Result<(), String> {
    let files = [
        ("compression.md", markdown(report)),
        ("compression.csv", csv(report)),
        ("compression.svg", svg(report)?),
    ];
    for (name, text) in files {
        // Never through a link planted under one of these fixed names.
        let path = cssm_formats::files::output_in(out, name).map_err(|e| e.to_string())?;
        cssm_formats::cssm::write_bytes_atomic(&path, text.as_bytes())
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn bytes(b: u64) -> String {
    cssm_formats::files::human_bytes(b, 1)
}

fn seconds(s: f64) -> String {
    if s < 60.0 {
        format!("{s:.1} s")
    } else {
        format!("{:.0} min {:.0} s", (s / 60.0).floor(), s % 60.0)
    }
}

fn pct(f: f64) -> String {
    format!("{:.2}%", 100.0 * f)
}

/// Agreement over the pairs that exchange light, and over all pairs in brackets.
fn agree(m: &super::Measured) -> String {
    format!("{} ({})", pct(m.agreement), pct(m.agreement_all))
}

fn rows(report: &Report, table: TableId) -> impl Iterator<Item = &Row> {
    report.rows.iter().filter(move |r| r.plan.table == table)
}
