//! Frame time of `ssil` (Soler et al. 2010, Fig. 9) at the paper's settings, with and without
//! visibility, and `direct` as the baseline of the same run, per pass from GPU timestamps.
//!
//! ```text
//! cargo bench --bench ssil_time -- [--size 1280x720] [--frames 5] [--scene DIR]
//!     [--shadow-resolution 2048] [--out FILE.md]
//! ```
//!
//! Rows: Fig. 9's four settings (quarter resolution, 4 levels, 64 samples; quarter, 4, 256;
//! half, 4, 64; half, 5, 64; the paper's radius of 40 pixels), each without and with the voxel
//! visibility, then the method's defaults. Wall-clock milliseconds per frame from submit to
//! the GPU's idle (median) and GPU milliseconds per pass of the last frame. On lavapipe only
//! the ratios to `direct` and between rows mean something; absolute GPU times count only from
//! a real GPU (`reports/runtime.sh`).

use cssm::runtime;
use runtime::method::{OptionValue, OptionValues};

#[path = "common/mod.rs"]
mod common;

use common::{Bench, passes_cell, write_report};

fn main() {
    let bench = Bench::new((1280, 720));
    let mut report = format!(
        "`ssil` on {}, the camera and light at rest.\n\n\
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
    // Fig. 9: (start level, levels, samples), radius 40.
    let paper = [(2, 4, 64), (2, 4, 256), (1, 4, 64), (1, 5, 64)];
    let mut rows: Vec<(String, OptionValues)> = Vec::new();
    for (start, levels, samples) in paper {
        for visibility in ["none", "voxels"] {
            let mut values = OptionValues::default();
            values.set("start-level", OptionValue::Count(start));
            values.set("levels", OptionValue::Count(levels));
            values.set("level-samples", OptionValue::Count(samples));
            values.set("radius", OptionValue::Number(40.0));
            values.set("visibility", OptionValue::Choice(visibility));
            values.set("bounces", OptionValue::Count(1));
            let resolution = if start == 2 { "quarter" } else { "half" };
            rows.push((
                format!(
                    "{resolution}, {levels} levels, {samples} samples, 1 bounce, visibility \
                     {visibility}"
                ),
                values,
            ));
        }
    }
    rows.push(("defaults".into(), OptionValues::default()));
    for (label, values) in rows {
        let (ms, passes) = run("ssil", &values);
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
