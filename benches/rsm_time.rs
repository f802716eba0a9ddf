//! Frame time of `rsm` (Bang 2011, Tables 5.1-5.3) with and without the micro linear buffer,
//! measured in the same run on the same device, per pass from GPU timestamps.
//!
//! ```text
//! cargo bench --bench rsm_time -- [--size 1280x720] [--frames 5] [--scene DIR]
//!     [--shadow-resolution 512] [--out FILE.md]
//! ```
//!
//! Two rows per variant: a static light (the RSM rendered once, a frame is the G-buffer, direct
//! light, sampling, filters, resolve, compose and tone mapping) and a light that moves every
//! frame (the thesis' setting: the RSM rendered every frame). Wall-clock milliseconds per frame
//! from submit to the GPU's idle (median) and GPU milliseconds per pass of the last frame. On
//! lavapipe only the ratio with/without visibility means something; absolute GPU times count
//! only from a real GPU (`reports/runtime.sh`).

use cssm::runtime;
use runtime::method::{OptionValue, OptionValues};

#[path = "common/mod.rs"]
mod common;

use common::{Bench, passes_cell, write_report};

fn main() {
    let bench = Bench::new((1280, 720));
    let mut report = format!(
        "`rsm` on {}, default options.\n\n\
         | visibility | light | frame ms | GPU ms per pass, last frame |\n\
         | --- | --- | --- | --- |\n",
        bench.setting()
    );
    let mut medians = Vec::new();
    for visibility in ["micro-buffer", "none"] {
        for moving in [false, true] {
            let mut values = OptionValues::default();
            values.set("visibility", OptionValue::Choice(visibility));
            let mut renderer = bench.renderer("rsm", &values);
            let light = bench.scene.lights.first().filter(|_| moving);
            let (ms, passes) = bench.timed(&mut renderer, light);
            medians.push(ms);
            let row = format!(
                "| {visibility} | {} | {ms:.1} | {} |\n",
                if moving { "moving" } else { "static" },
                passes_cell(&passes)
            );
            print!("{row}");
            report += &row;
        }
    }
    let ratio = format!(
        "\nVisibility costs {:.2}x the frame without it (static light), {:.2}x (moving light).\n",
        medians[0] / medians[2],
        medians[1] / medians[3]
    );
    print!("{ratio}");
    report += &ratio;
    write_report(bench.out.as_deref(), &report);
}
