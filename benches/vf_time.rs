//! Frame time of `vf` (Chen et al. 2014, Table 1) at the paper's settings and the method's
//! defaults, with and without the visibility filter, and `direct` as the baseline of the same
//! run, per pass from GPU timestamps.
//!
//! ```text
//! cargo bench --bench vf_time -- [--size 1280x720] [--frames 5] [--scene DIR]
//!     [--shadow-resolution 2048] [--out FILE.md]
//! ```
//!
//! Rows: Table 1's marching sizes for a 512² image scaled to the image (64² and 128² of 512²:
//! marching factors 8 and 4, gathering at half resolution, the 7x7 filter), each without and
//! with the filter, then the method's defaults. Wall-clock milliseconds per frame from submit
//! to the GPU's idle (median) and GPU milliseconds per pass of the last frame (the passes:
//! proxy hash, sort, cells; vpl light, voxel sh; shadow rays; visibility filter; vf gather;
//! upsample; vf resolve). On lavapipe only the ratios to `direct` and between rows mean
//! something; absolute GPU times count only from a real GPU (`reports/runtime.sh`).

use cssm::runtime;
use runtime::method::{OptionValue, OptionValues};

#[path = "common/mod.rs"]
mod common;

use common::{Bench, passes_cell, write_report};

fn main() {
    let bench = Bench::new((1280, 720));
    let mut report = format!(
        "`vf` on {}, the camera and light at rest.\n\n\
         | settings | frame ms | ratio to direct | GPU ms per pass, last frame |\n\
         | --- | --- | --- | --- |\n",
        bench.setting()
    );
    let run = |name: &str, values: &OptionValues| {
        let mut renderer = bench.renderer(name, values);
        bench.timed(&mut renderer, None)
    };
    let (direct_ms, direct_passes) = run("direct", &OptionValues::default());
    let row = format!(
        "| `direct` (baseline) | {direct_ms:.1} | 1.00 | {} |\n",
        passes_cell(&direct_passes)
    );
    print!("{row}");
    report += &row;
    let mut rows: Vec<(String, OptionValues)> = Vec::new();
    // Table 1: marching 64² and 128² of a 512² image; gathering at 256² of it.
    for (march, size) in [(8, 64), (4, 128)] {
        for filter in [0, 3] {
            let mut values = OptionValues::default();
            values.set("march", OptionValue::Count(march));
            values.set("gather", OptionValue::Count(2));
            values.set("filter", OptionValue::Count(filter));
            let filtered = if filter == 0 {
                "no filter"
            } else {
                "7x7 filter"
            };
            rows.push((
                format!("marching 1/{march} ({size}² of 512²), {filtered}"),
                values,
            ));
        }
    }
    rows.push(("defaults".into(), OptionValues::default()));
    for (label, values) in rows {
        let (ms, passes) = run("vf", &values);
        let row = format!(
            "| {label} | {ms:.1} | {:.2} | {} |\n",
            ms / direct_ms,
            passes_cell(&passes)
        );
        print!("{row}");
        report += &row;
    }
    write_report(bench.out.as_deref(), &report);
}
