//! The Markdown's "Targets" (the targets checked against the measured rows: the paper's
//! ratios, twice them on the Cornell box, agreement at least 98%, peak memory, time) and its
//! "Time per table".

use std::fmt::Write as _;

use super::{bytes, pct, rows, seconds};
use crate::report::{PAPER, Report, Row, SceneId, TableId};

/// The accuracy target, "at least 98% on the Cornell box", over every Cornell box row
/// baked (rows that reuse an earlier row's bake are counted once). A row below it is set beside
/// the paper's own lossless method at the same atlas and cube, which shows whether the loss
/// comes from the resolution (of the atlas and of the cube maps) or from the compression.
fn cornell_agreement(r: &Report) -> String {
    let baked = |row: &&Row| row.plan.scene == SceneId::Cornell && row.same_as.is_none();
    let measured: Vec<(&Row, f64)> = r
        .rows
        .iter()
        .filter(baked)
        .filter_map(|row| row.outcome.as_ref().ok().map(|m| (row, m.agreement)))
        .collect();
    let name = |row: &Row| {
        format!(
            "{} atlas {} cube {} {}",
            row.plan.table_name(),
            row.plan.atlas,
            row.plan.cube,
            row.plan.variant.name
        )
    };
    let below: Vec<&(&Row, f64)> = measured.iter().filter(|(_, a)| *a < 0.98).collect();
    let mut s = format!(
        "- Agreement at least 98% on the Cornell box: {} of {} rows",
        measured.len() - below.len(),
        measured.len()
    );
    if below.is_empty() {
        s.push('.');
        return s;
    }
    let listed: Vec<String> = below
        .iter()
        .map(|(row, a)| format!("{} ({})", name(row), pct(*a)))
        .collect();
    let _ = write!(s, "; below: {}.", listed.join(", "));
    // The paper's method at each (atlas, cube) with a row below the line.
    let mut grids: Vec<(u32, u32)> = below
        .iter()
        .map(|(row, _)| (row.plan.atlas, row.plan.cube))
        .collect();
    grids.sort_unstable();
    grids.dedup();
    for (atlas, cube) in grids {
        let paper = measured.iter().find(|(row, _)| {
            row.plan.atlas == atlas && row.plan.cube == cube && row.plan.variant.same_bake(&PAPER)
        });
        let _ = match paper {
            Some((_, a)) if *a < 0.98 => write!(
                s,
                " At atlas {atlas}, cube {cube}, the paper's own lossless method agrees {} too: the \
                 loss comes from the resolution (one depth map per texel, one depth per cube-map \
                 pixel), not from the compression.",
                pct(*a)
            ),
            Some((_, a)) => write!(
                s,
                " At atlas {atlas}, cube {cube}, the paper's own method agrees {}.",
                pct(*a)
            ),
            None => write!(
                s,
                " No row of the paper's method ran at atlas {atlas}, cube {cube}."
            ),
        };
    }
    s
}

/// The targets, checked against the measured rows.
pub(super) fn targets(r: &Report) -> String {
    let mut s = String::new();
    let mut below = Vec::new();
    let mut checked = 0;
    for row in &r.rows {
        let (Ok(m), Some(paper)) = (&row.outcome, row.plan.paper.ratio()) else {
            continue;
        };
        checked += 1;
        if m.ratio() < paper {
            below.push(format!(
                "{} {} atlas {} {} ({:.1} < {paper:.1})",
                row.plan.table_name(),
                row.plan.scene.name(),
                row.plan.atlas,
                row.plan.variant.name,
                m.ratio()
            ));
        }
    }
    let _ = writeln!(
        s,
        "- Every row's ratio at least the paper's: {} of {checked} rows with a paper figure reach it{}.",
        checked - below.len(),
        if below.is_empty() {
            String::new()
        } else {
            format!("; below: {}", below.join(", "))
        }
    );
    for row in rows(r, TableId::Table3) {
        let p = &row.plan;
        if p.scene != SceneId::Cornell || p.cube != 64 || p.atlas < 128 {
            continue;
        }
        let (Ok(m), Some(paper)) = (&row.outcome, p.paper.ratio()) else {
            continue;
        };
        let met = m.ratio() >= 2.0 * paper && m.agreement >= 0.98;
        let _ = writeln!(
            s,
            "- Cornell box, cube 64, atlas {}, {}: {:.1} : 1 against 2 x {paper:.1} = {:.1}, agreement {}: {}.",
            p.atlas,
            p.variant.name,
            m.ratio(),
            2.0 * paper,
            pct(m.agreement),
            if met { "met" } else { "missed" }
        );
    }
    let _ = writeln!(s, "{}", cornell_agreement(r));
    for row in r.rows.iter().filter(|row| row.plan.atlas == 512) {
        if let Ok(m) = &row.outcome {
            let _ = writeln!(
                s,
                "- Atlas 512, {} {}: peak memory {} ({} 2 GiB).",
                row.plan.scene.name(),
                row.plan.variant.name,
                m.peak_rss.map_or("not reported".into(), bytes),
                match m.peak_rss {
                    Some(b) if b < 2 << 30 => "under",
                    Some(_) => "NOT under",
                    None => "?",
                }
            );
        }
    }
    let mut cornell: Vec<&Row> = r
        .rows
        .iter()
        .filter(|row| row.plan.scene == SceneId::Cornell)
        .collect();
    let total: f64 = cornell.iter().map(|row| row.wall_seconds).sum();
    let _ = write!(
        s,
        "- Every Cornell box row (all tables), bake and check: {} in all ({} 15 min)",
        seconds(total),
        if total < 900.0 { "under" } else { "NOT under" }
    );
    // Over the limit: name the longest rows that push it over, and the time of the rest.
    cornell.sort_by(|a, b| b.wall_seconds.total_cmp(&a.wall_seconds));
    let mut rest = total;
    let mut longer = Vec::new();
    for row in cornell {
        if rest < 900.0 {
            break;
        }
        rest -= row.wall_seconds;
        longer.push(format!(
            "{} atlas {} {} ({})",
            row.plan.table_name(),
            row.plan.atlas,
            row.plan.variant.name,
            seconds(row.wall_seconds)
        ));
    }
    if longer.is_empty() {
        let _ = writeln!(s, ".");
    } else {
        let _ = writeln!(
            s,
            ": the rows that need longer are {}; every other row together takes {}.",
            longer.join(", "),
            seconds(rest)
        );
    }
    s
}

/// Wall time per table and scene, and the longest rows.
pub(super) fn times(r: &Report) -> String {
    let mut s = String::from(
        "| table | scene | rows | wall time (bakes and checks) | longest row |\n|---|---|---|---|---|\n",
    );
    let mut groups: Vec<(&str, SceneId)> = Vec::new();
    for row in &r.rows {
        let key = (row.plan.table_name(), row.plan.scene);
        if !groups.contains(&key) {
            groups.push(key);
        }
    }
    for (table, scene) in groups {
        let g: Vec<&Row> = r
            .rows
            .iter()
            .filter(|row| row.plan.table_name() == table && row.plan.scene == scene)
            .collect();
        let total: f64 = g.iter().map(|row| row.wall_seconds).sum();
        let longest = g
            .iter()
            .max_by(|a, b| a.wall_seconds.total_cmp(&b.wall_seconds))
            .map(|row| {
                format!(
                    "atlas {} cube {} {}: {}",
                    row.plan.atlas,
                    row.plan.cube,
                    row.plan.variant.name,
                    seconds(row.wall_seconds)
                )
            })
            .unwrap_or_default();
        let reused = g.iter().filter(|row| row.same_as.is_some()).count();
        let _ = writeln!(
            s,
            "| {table} | {} | {}{} | {} | {longest} |",
            scene.name(),
            g.len(),
            if reused > 0 {
                format!(" ({reused} reuse earlier bakes)")
            } else {
                String::new()
            },
            seconds(total)
        );
    }
    s
}
