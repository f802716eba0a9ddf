//! One row of `cssm report compression` measured: a child `cssm bake --json` (its figures and
//! its own peak memory) and a child `cssm check --json` on its file, their JSON summaries read
//! into the row's [`Measured`].

use std::path::Path;
use std::process::Command;

use cssm_output::summary::{BakeSummary, CheckSummary};

use super::{Measured, Plan};

/// Runs `cssm bake` and `cssm check` for one row in child processes.
pub(super) fn bake_and_check(
    exe: &Path,
    scene: &Path,
    plan: &Plan,
    file: &Path,
    pairs: u64,
) -> Result<Measured, String> {
    let v = &plan.variant;
    let bake: BakeSummary = child_json(
        Command::new(exe)
            .arg("bake")
            .arg(scene)
            .arg("-o")
            .arg(file)
            .args(["--atlas", &plan.atlas.to_string()])
            .args(["--cube", &plan.cube.to_string()])
            .args(["--traversal", v.traversal.name()])
            .args(["--chart-order", v.chart_order.name()])
            .args(["--run-value", v.run_value.name()])
            .args(["--merge-short-runs", &v.merge_short_runs.to_string()])
            .args(["--file-coding", v.file_coding.name()])
            .args(["--second-layer", v.second_layer.name()])
            .args(["--pixel-grid", v.pixel_grid.name()])
            .args(["--cube-frame", v.cube_frame.name()])
            .arg("--json"),
        "bake",
    )?;
    let check = child_json::<CheckSummary>(
        Command::new(exe)
            .arg("check")
            .arg(file)
            .arg("--scene")
            .arg(scene)
            .args(["--pairs", &pairs.to_string()])
            .arg("--json"),
        "check",
    );
    let _ = std::fs::remove_file(file);
    let check = check?;
    Ok(Measured {
        faces: bake.triangles,
        charts: bake.charts.into(),
        maps: bake.defined_texels,
        runs: bake.runs,
        uncompressed: bake.uncompressed_bytes,
        gpu: bake.gpu_bytes,
        file: bake.file_bytes,
        seconds: bake.total_seconds,
        peak_rss: bake.peak_rss_bytes,
        agreement: check.exchanging_agreement,
        agreement_all: check.agreement,
        exchanging_pairs: check.exchanging_pairs,
        false_visible: check.exchanging_false_visible_rate,
        false_occluded: check.exchanging_false_occluded_rate,
    })
}

/// Runs a child `cssm` command and reads its JSON summary ([`crate::summary`]); a failure gives
/// its last error line.
fn child_json<T: serde::de::DeserializeOwned>(cmd: &mut Command, what: &str) -> Result<T, String> {
    let out = cmd
        .output()
        .map_err(|e| format!("cannot run {:?}: {e}", cmd.get_program()))?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let last = stderr
            .lines()
            .rev()
            .find(|l| l.starts_with("error"))
            .or_else(|| stderr.lines().last())
            .unwrap_or("no message");
        return Err(format!("{what} failed ({}): {last}", out.status));
    }
    // The summary is the last line (a library might print above it).
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .rev()
        .find(|l| l.starts_with('{'))
        .ok_or_else(|| format!("{what} --json printed no JSON object"))?;
    serde_json::from_str(line).map_err(|e| format!("{what} --json: {e}"))
}
