//! `compression.csv`: every row of the report, one line each with every figure.

use std::fmt::Write as _;

use crate::report::Report;

/// Every row as CSV (one header line).
pub fn csv(r: &Report) -> String {
    let mut s = String::from(
        "table,scene,atlas,cube,variant,traversal,chart_order,run_value,merge_short_runs,file_coding,second_layer,status,faces,charts,maps,runs,uncompressed_bytes,gpu_bytes,file_bytes,ratio,file_ratio,bake_seconds,wall_seconds,peak_rss_bytes,agreement,false_visible_rate,false_occluded_rate,agreement_all_pairs,exchanging_pairs,paper_ratio,same_bake_as\n",
    );
    for row in &r.rows {
        let p = &row.plan;
        let v = &p.variant;
        let _ = write!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},",
            p.table_name(),
            p.scene.name(),
            p.atlas,
            p.cube,
            v.name,
            v.traversal,
            v.chart_order,
            v.run_value,
            v.merge_short_runs,
            v.file_coding,
            v.second_layer
        );
        match &row.outcome {
            Ok(m) => {
                let _ = write!(
                    s,
                    "ok,{},{},{},{},{},{},{},{:.4},{:.4},{:.3},{:.3},{},{:.5},{:.5},{:.5},{:.5},{},",
                    m.faces,
                    m.charts,
                    m.maps,
                    m.runs,
                    m.uncompressed,
                    m.gpu,
                    m.file,
                    m.ratio(),
                    m.file_ratio(),
                    m.seconds,
                    row.wall_seconds,
                    m.peak_rss.map_or(String::new(), |b| b.to_string()),
                    m.agreement,
                    m.false_visible,
                    m.false_occluded,
                    m.agreement_all,
                    m.exchanging_pairs
                );
            }
            Err(e) => {
                let _ = write!(s, "\"{}\",,,,,,,,,,,,,,,,,,", e.replace('"', "'"));
            }
        }
        let _ = writeln!(
            s,
            "{},{}",
            p.paper.ratio().map_or(String::new(), |x| x.to_string()),
            row.same_as
                .and_then(|i| r.rows.get(i))
                .map_or(String::new(), |same| same.plan.label())
        );
    }
    s
}
