//! Frame time of one method at the settings its table entry names (`MethodEntry::timing`: its
//! paper's table or figure), beside the methods it is compared with, measured in the same run
//! on the same device, per pass from GPU timestamps. Every method with timing rows gets this
//! benchmark from the method table; `reports/runtime.sh` runs it for each.
//!
//! ```text
//! cargo bench --bench method_time -- --method NAME [--size 1280x720] [--frames 5]
//!     [--scene DIR] [--shadow-resolution 2048] [--sweep OPTION=V1,V2,...] [--out FILE.md]
//! cargo bench --bench method_time -- --list      # the methods with timing rows
//! ```
//!
//! `--sweep` repeats every row once per value of one option (`vct`'s voxel resolutions, say).
//! Wall-clock milliseconds per frame from submit to the GPU's idle (median), the ratio to each
//! compared method's frame (light still, defaults), and GPU milliseconds per pass of the last
//! frame. A row whose light moves sets the light before every frame, so the method's prepare
//! passes run every frame. On lavapipe only the ratios mean something; absolute GPU times count
//! only from a real GPU (`reports/runtime.sh`).

use cssm::runtime::{self, method::MethodEntry};

#[path = "common/mod.rs"]
mod common;

use common::{Bench, arg, passes_cell, write_report};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.iter().any(|a| a == "--list") {
        for m in runtime::METHODS
            .iter()
            .filter(|m| !m.timing.rows.is_empty())
        {
            println!("{}", m.name);
        }
        return;
    }
    let name = arg(&args, "--method").unwrap_or_else(|| {
        let timed: Vec<&str> = runtime::METHODS
            .iter()
            .filter(|m| !m.timing.rows.is_empty())
            .map(|m| m.name)
            .collect();
        panic!("--method NAME, one of {}", timed.join(", "))
    });
    let entry = runtime::method::find(&name).unwrap_or_else(|e| panic!("{e}"));
    if entry.timing.rows.is_empty() {
        panic!("{name} has no timing rows: {}", entry.timing.about);
    }
    let sweep = arg(&args, "--sweep").map(|s| sweep(entry, &s));
    let bench = Bench::new((1280, 720));
    let compared = entry.timing.compare_with;
    let mut report = format!(
        "`{name}` on {}: {}.\n\n| settings | light | frame ms |{} GPU ms per pass, last frame |\n\
         | --- | --- | --- |{} --- |\n",
        bench.setting(),
        entry.timing.about,
        compared
            .iter()
            .map(|c| format!(" ratio to {c} |"))
            .collect::<String>(),
        " --- |".repeat(compared.len()),
    );
    let mut baselines = Vec::new();
    for &other in compared {
        let mut renderer = bench.renderer(other, &Default::default());
        let (ms, passes) = bench.timed(&mut renderer, None);
        baselines.push(ms);
        let ratios: String = compared
            .iter()
            .map(|&c| if c == other { " 1.00 |" } else { " |" })
            .collect();
        let row = format!(
            "| `{other}` (defaults) | still | {ms:.1} |{ratios} {} |\n",
            passes_cell(&passes)
        );
        print!("{row}");
        report += &row;
    }
    let values_swept: Vec<Option<&str>> = match &sweep {
        Some((_, values)) => values.iter().map(|v| Some(v.as_str())).collect(),
        None => vec![None],
    };
    for value in values_swept {
        for row in entry.timing.rows {
            let mut text = row.options.to_string();
            let mut label = row.label.to_string();
            if let (Some((option, _)), Some(value)) = (&sweep, value) {
                if !text.is_empty() {
                    text.push(',');
                }
                text += &format!("{option}={value}");
                label += &format!(", {option} {value}");
            }
            let values = entry
                .parse_options(&text)
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            let mut renderer = bench.renderer(&name, &values);
            let light = bench.scene.lights.first().filter(|_| row.moving_light);
            let (ms, passes) = bench.timed(&mut renderer, light);
            let ratios: String = baselines
                .iter()
                .map(|b| format!(" {:.2} |", ms / b))
                .collect();
            let row = format!(
                "| {label} | {} | {ms:.1} |{ratios} {} |\n",
                if row.moving_light { "moving" } else { "still" },
                passes_cell(&passes)
            );
            print!("{row}");
            report += &row;
        }
    }
    write_report(bench.out.as_deref(), &report);
}

/// `OPTION=V1,V2,...` checked against the method's options: the option's name and its values.
fn sweep(entry: &MethodEntry, text: &str) -> (String, Vec<String>) {
    let (option, values) = text
        .split_once('=')
        .unwrap_or_else(|| panic!("--sweep takes OPTION=V1,V2,..., not {text}"));
    let values: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
    for value in &values {
        let values = entry
            .parse_options(&format!("{option}={value}"))
            .unwrap_or_else(|e| panic!("--sweep: {e}"));
        entry
            .resolve(&values)
            .unwrap_or_else(|e| panic!("--sweep: {e}"));
    }
    (option.trim().to_string(), values)
}
