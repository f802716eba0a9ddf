//! The report's files: `compression.md` (tables, winners, targets), `compression.csv` (one line
//! per row, every figure) and `compression.svg` (ratio against atlas resolution). Each is
//! written atomically (temporary file, then rename), so a failed run leaves the old ones.

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;

use super::{PAPER, PaperFigures, Report, Row, SceneId, TableId, Variant};
use cssm_formats::Traversal;

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

/// The report as Markdown.
pub fn markdown(r: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Compression ratios: the paper's Tables 2 and 3, and beyond\n\n\
         Made by `{}` at commit `{}` on {} (release build). Every figure below was measured by \
         that command; the paper's figures (Ritschel et al. 2008, §5) are quoted beside them.\n",
        r.command, r.commit, r.machine
    );
    let _ = writeln!(
        s,
        "How each row is measured: one `cssm bake --json` child process (bake time from its start \
         to the file written; *peak memory* is that process's own peak resident set, `VmHWM`, \
         read just before it exits, so rows do not share a peak), then `cssm check --json` on the \
         file: agreement with exact ray casts on {} random surface point pairs (seed 1, the same \
         pairs for every row of a scene). **Agreement** is over the pairs that exchange light \
         (each point in front of the other's surface, so both cosines of the transfer are \
         positive: the only visibility an image uses); in brackets, over every pair drawn. The paper's \
         method also answers for pairs facing away; the *facing* and *exchange* layers are exact \
         only for pairs that exchange light. **Ratio** = uncompressed (2 bytes per cube-map pixel) / \
         GPU-resident run data (offsets + runs, what the runtime queries directly), as in the \
         paper; the file (zstd) ratio is a column beside it. Raw figures: `compression.csv`; \
         chart: `compression.svg`.\n",
        r.pairs
    );
    if let Some(h) = &r.heads {
        let _ = writeln!(s, "Cornell Heads scene: {h}.\n");
    }
    if let Some(c) = &r.church {
        let _ = writeln!(s, "Cornell Church at 3,700 faces: {c}.\n");
    }

    // Table 2.
    if rows(r, TableId::Table2).next().is_some() {
        let _ = writeln!(
            s,
            "## Table 2: traversals (Cornell box)\n\n\
             | atlas | cube | traversal | depth maps | runs | ratio | paper | x paper | file ratio | agreement (all pairs) | time |\n\
             |---|---|---|---|---|---|---|---|---|---|---|"
        );
        for row in rows(r, TableId::Table2) {
            let p = &row.plan;
            let paper = p.paper.ratio();
            match &row.outcome {
                Ok(m) => {
                    let _ = writeln!(
                        s,
                        "| {} | {} | {} | {} | {} | **{:.1} : 1** | {} | {} | {:.1} : 1 | {} | {} |",
                        p.atlas,
                        p.cube,
                        p.variant.traversal,
                        m.maps,
                        m.runs,
                        m.ratio(),
                        paper.map_or("-".into(), |x| format!("{x:.1} : 1")),
                        paper.map_or("-".into(), |x| format!("{:.2}", m.ratio() / x)),
                        m.file_ratio(),
                        agree(m),
                        seconds(m.seconds)
                    );
                }
                Err(e) => {
                    let _ = writeln!(
                        s,
                        "| {} | {} | {} | {e} | | | | | | | |",
                        p.atlas, p.cube, p.variant.traversal
                    );
                }
            }
        }
        let _ = writeln!(
            s,
            "\nThe paper's Table 2 has no Hilbert or Piloted column (§3.2.3 rules the CSM's Hilbert \
             pattern out for arbitrary chart shapes); their rows here are ours alone. Hilbert: the \
             generalised Hilbert curve over each chart's bounding rectangle; Piloted: per chart the \
             Hilbert or the Spiral order, whichever a pilot bake of the chart at cube 8 compresses \
             into fewer runs.\n"
        );
    }

    // Table 3.
    if rows(r, TableId::Table3).next().is_some() {
        let _ = writeln!(
            s,
            "## Table 3: scenes and atlas resolutions\n\n\
             Variants: **paper** = {}; **best** = {}.\n\n\
             | scene | faces (paper) | atlas | cube | variant | depth maps (paper) | uncompressed (paper) | in memory (paper compressed) | on disk | ratio (paper) | x paper | file ratio | bake time (paper) | peak memory | agreement (all pairs) |\n\
             |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
            PAPER.about,
            super::BEST.about
        );
        for row in rows(r, TableId::Table3) {
            let p = &row.plan;
            let pr = match p.paper {
                PaperFigures::Table3(t) => Some(t),
                _ => None,
            };
            let faces_paper = p.scene.paper_faces();
            let pv = |f: &dyn Fn(&super::paper::Table3Row) -> String| {
                pr.as_ref().map_or("-".to_string(), f)
            };
            match &row.outcome {
                Ok(m) => {
                    let _ = writeln!(
                        s,
                        "| {} | {} ({faces_paper}) | {} | {} | {} | {} ({}) | {} ({}) | {} ({}) | {} | **{:.1} : 1** ({}) | {} | {:.1} : 1 | {} ({}) | {} | {} |",
                        p.scene.title(),
                        m.faces,
                        p.atlas,
                        p.cube,
                        p.variant.name,
                        m.maps,
                        pv(&|t| t.maps.to_string()),
                        bytes(m.uncompressed),
                        pv(&|t| t.uncompressed.to_string()),
                        bytes(m.gpu),
                        pv(&|t| t.compressed.to_string()),
                        bytes(m.file),
                        m.ratio(),
                        pv(&|t| format!("{:.1}", t.ratio)),
                        pr.map_or("-".into(), |t| format!("{:.2}", m.ratio() / t.ratio)),
                        m.file_ratio(),
                        seconds(m.seconds),
                        pv(&|t| t.time.to_string()),
                        m.peak_rss.map_or("-".into(), bytes),
                        agree(m)
                    );
                }
                Err(e) => {
                    let _ = writeln!(
                        s,
                        "| {} | ({faces_paper}) | {} | {} | {} | {e} | | | | | | | | | |",
                        p.scene.title(),
                        p.atlas,
                        p.cube,
                        p.variant.name
                    );
                }
            }
        }
        let _ = writeln!(
            s,
            "\nThe paper's times are for a 2008 GPU (GeForce 8800); ours for the CPU named above. \
             The paper's church had 3,700 faces; the Sibenik cathedral that stands in for it has \
             about 73,500 and thousands of small atlas charts, so it has a second set of rows \
             simplified to 3,700 faces. Even simplified it has about 1,100 charts, three faces each \
             on average, so a traversal leaves a chart every few texels (the paper used 3ds Max's \
             atlas). xatlas splits the simplified mesh into 338 pieces before it charts them, \
             141 of them single faces: edges shared by three or more faces, faces wound against \
             their neighbours, small detached mouldings. Letting charts bend past xatlas' 60 \
             degree limit only takes 1,100 charts to 1,070 (measured on this scene). The \
             paper's church row at atlas 512 used cube 6x32x32 (its footnote 1), and so does ours.\n"
        );
    }

    // Options.
    let options: Vec<&Row> = rows(r, TableId::Options).collect();
    if !options.is_empty() {
        let base = options
            .iter()
            .find(|row| row.plan.variant == PAPER)
            .and_then(|row| row.outcome.as_ref().ok());
        let p0 = &options[0].plan;
        let _ = writeln!(
            s,
            "## Beyond the paper: one option per row (Cornell box, atlas {}, cube {})\n\n\
             Each row changes one thing against the paper's method (first row). \"Same accuracy\" \
             means agreement within {SAME_ACCURACY_POINTS} percentage points of it.\n\n\
             | option | what it changes | runs | ratio | vs paper's method | file ratio | agreement (all pairs) | change in agreement | time |\n\
             |---|---|---|---|---|---|---|---|---|",
            p0.atlas, p0.cube
        );
        for row in &options {
            let v = &row.plan.variant;
            match (&row.outcome, base) {
                (Ok(m), Some(b)) => {
                    let _ = writeln!(
                        s,
                        "| {} | {} | {} | {:.1} : 1 | {:+.1}% | {:.1} : 1 | {} | {:+.2} pt | {} |",
                        v.name,
                        v.about,
                        m.runs,
                        m.ratio(),
                        100.0 * (m.ratio() / b.ratio() - 1.0),
                        m.file_ratio(),
                        agree(m),
                        100.0 * (m.agreement - b.agreement),
                        seconds(m.seconds)
                    );
                }
                (Ok(m), None) => {
                    let _ = writeln!(
                        s,
                        "| {} | {} | {} | {:.1} : 1 | - | {:.1} : 1 | {} | - | {} |",
                        v.name,
                        v.about,
                        m.runs,
                        m.ratio(),
                        m.file_ratio(),
                        agree(m),
                        seconds(m.seconds)
                    );
                }
                (Err(e), _) => {
                    let _ = writeln!(s, "| {} | {} | {e} | | | | | | |", v.name, v.about);
                }
            }
        }
        let reused: Vec<String> = options
            .iter()
            .filter_map(|row| {
                let same = r.rows.get(row.same_as?)?;
                Some(format!(
                    "`{}` is {}",
                    row.plan.variant.name,
                    same.plan.label()
                ))
            })
            .collect();
        if !reused.is_empty() {
            let _ = writeln!(
                s,
                "\nRows with an earlier row's settings take its bake, not baked twice: {}.",
                reused.join("; ")
            );
        }
        let _ = writeln!(s, "\n{}", winners(&options));
    }

    let _ = writeln!(s, "## Targets\n\n{}", targets(r));
    let _ = writeln!(s, "## Time per table\n\n{}", times(r));
    let missing: Vec<&Row> = r.rows.iter().filter(|row| row.outcome.is_err()).collect();
    let _ = writeln!(s, "## Rows that did not run\n");
    if missing.is_empty() {
        let _ = writeln!(s, "None: every planned row ran.");
    } else {
        for row in missing {
            let p = &row.plan;
            let _ = writeln!(
                s,
                "- {} {} atlas {} cube {} {}: {}",
                p.table_name(),
                p.scene.title(),
                p.atlas,
                p.cube,
                p.variant.name,
                row.outcome.as_ref().err().map_or("", |e| e.as_str())
            );
        }
    }
    s
}

/// Which options win, from the Options rows.
fn winners(options: &[&Row]) -> String {
    let Some(base) = options
        .iter()
        .find(|row| row.plan.variant == PAPER)
        .and_then(|row| row.outcome.as_ref().ok())
    else {
        return "The baseline row did not run, so no option can be judged.\n".into();
    };
    let mut s = String::from("Which wins:\n\n");
    for row in options {
        let Ok(m) = &row.outcome else { continue };
        let v = &row.plan.variant;
        if v == &PAPER {
            continue;
        }
        let gain = 100.0 * (m.ratio() / base.ratio() - 1.0);
        let dacc = 100.0 * (m.agreement - base.agreement);
        // The paper's method in everything but the file coding (and the name)?
        let file_only = Variant {
            name: PAPER.name,
            about: PAPER.about,
            file_coding: PAPER.file_coding,
            ..*v
        } == PAPER;
        if file_only {
            // A file-only option: the GPU data must be the same; judge the file.
            let fgain = 100.0 * (m.file_ratio() / base.file_ratio() - 1.0);
            let _ = writeln!(
                s,
                "- **{}** ({}): file ratio {:.1} -> {:.1} : 1 ({fgain:+.1}%), the same {} runs in \
                 memory ({}): {}.",
                v.name,
                v.about,
                base.file_ratio(),
                m.file_ratio(),
                m.runs,
                if m.runs == base.runs && m.gpu == base.gpu {
                    "identical"
                } else {
                    "DIFFERENT"
                },
                if fgain > 0.0 { "wins" } else { "does not win" }
            );
            continue;
        }
        let verdict = if gain > 0.0 && dacc >= -SAME_ACCURACY_POINTS {
            "wins at the same or better accuracy"
        } else if gain > 0.0 {
            "compresses better but costs accuracy"
        } else {
            "does not compress better"
        };
        let _ = writeln!(
            s,
            "- **{}** ({}): ratio {gain:+.1}%, agreement {dacc:+.2} pt: {verdict}.",
            v.name, v.about
        );
    }
    s
}

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
fn targets(r: &Report) -> String {
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
fn times(r: &Report) -> String {
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

fn colour(t: Traversal) -> RGBColor {
    match t {
        Traversal::Greedy => RGBColor(0x1f, 0x77, 0xb4),
        Traversal::Zigzag => RGBColor(0xff, 0x7f, 0x0e),
        Traversal::Spiral => RGBColor(0x2c, 0xa0, 0x2c),
        Traversal::Hilbert => RGBColor(0xd6, 0x27, 0x28),
        Traversal::Piloted => RGBColor(0x94, 0x67, 0xbd),
    }
}

/// The chart: ratio against atlas resolution (log2 axis), one line per traversal (Table 2, solid:
/// measured, dashed: the paper), and Table 3's scenes (paper method and best options).
pub fn svg(r: &Report) -> Result<String, String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (1100, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (left, right) = root.split_horizontally(550);
        let t2: Vec<&Row> = rows(r, TableId::Table2).collect();
        let mut lines: Vec<Line> = Vec::new();
        for t in Traversal::ALL {
            let ours: Vec<(f64, f64)> = t2
                .iter()
                .filter(|row| row.plan.variant.traversal == t)
                .filter_map(|row| {
                    row.outcome
                        .as_ref()
                        .ok()
                        .map(|m| (row.plan.atlas as f64, m.ratio()))
                })
                .collect();
            let paper: Vec<(f64, f64)> = super::paper::TABLE2
                .iter()
                .filter(|p| p.1 == t)
                .map(|p| (p.0 as f64, p.2))
                .collect();
            let same_cube = t2
                .iter()
                .all(|row| row.plan.cube == super::paper::TABLE2_CUBE);
            if !ours.is_empty() {
                lines.push((format!("{t} (ours)"), colour(t), false, ours));
                if !paper.is_empty() && same_cube {
                    lines.push((format!("{t} (paper's Table 2)"), colour(t), true, paper));
                }
            }
        }
        let cube2 = t2.first().map_or(32, |row| row.plan.cube);
        panel(
            &left,
            &format!("Table 2: Cornell box, cube 6x{cube2}x{cube2}"),
            &lines,
        )?;

        let mut lines3 = Vec::new();
        let palette = [
            RGBColor(0x2c, 0xa0, 0x2c),
            RGBColor(0x94, 0x67, 0xbd),
            RGBColor(0x8c, 0x56, 0x4b),
            RGBColor(0xd6, 0x27, 0x28),
        ];
        for (scene, c) in SceneId::ALL.into_iter().zip(palette) {
            for v in [PAPER, super::BEST] {
                let pts: Vec<(f64, f64)> = rows(r, TableId::Table3)
                    .filter(|row| row.plan.scene == scene && row.plan.variant == v)
                    .filter_map(|row| {
                        row.outcome
                            .as_ref()
                            .ok()
                            .map(|m| (row.plan.atlas as f64, m.ratio()))
                    })
                    .collect();
                if !pts.is_empty() {
                    // The paper's method in a lighter shade of the scene's colour.
                    let light = |x: u8| x + ((255 - x) as f32 * 0.5) as u8;
                    let rgb = if v == PAPER {
                        RGBColor(light(c.0), light(c.1), light(c.2))
                    } else {
                        c
                    };
                    let what = if v == PAPER { "paper's method" } else { v.name };
                    lines3.push((format!("{}, {what} (ours)", scene.name()), rgb, false, pts));
                }
            }
            if rows(r, TableId::Table3).any(|row| {
                row.plan.scene == scene
                    && row.outcome.is_ok()
                    && matches!(row.plan.paper, PaperFigures::Table3(_))
            }) {
                let paper: Vec<(f64, f64)> = scene
                    .paper_rows()
                    .iter()
                    .map(|p| (p.atlas as f64, p.ratio))
                    .collect();
                lines3.push((
                    format!("{} (paper's Table 3)", scene.name()),
                    c,
                    true,
                    paper,
                ));
            }
        }
        let title3 = match rows(r, TableId::Table3).next().map(|row| row.plan.cube) {
            Some(c) if rows(r, TableId::Table3).all(|row| row.plan.cube == c) => {
                format!("Table 3: cube 6x{c}x{c}")
            }
            _ => "Table 3: cube 6x64x64 (church 512: 6x32x32)".to_string(),
        };
        panel(&right, &title3, &lines3)?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(out)
}

/// A line of a panel: legend name, colour, dashed (the paper's figures), points (atlas, ratio).
type Line = (String, RGBColor, bool, Vec<(f64, f64)>);

/// One panel: atlas resolution on a log2 axis (labelled 32, 64, ...), ratio axis, lines with a
/// legend.
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    lines: &[Line],
) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let xs = lines.iter().flat_map(|l| l.3.iter().map(|p| p.0.log2()));
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let (x0, x1) = if x0.is_finite() {
        (x0, x1.max(x0 + 1.0))
    } else {
        (5.0, 7.0)
    };
    let y1 = lines
        .iter()
        .flat_map(|l| l.3.iter().map(|p| p.1))
        .fold(1.0f64, f64::max)
        * 1.1;
    let mut chart = ChartBuilder::on(area)
        .caption(
            if lines.is_empty() {
                format!("{title}: no rows")
            } else {
                title.to_string()
            },
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0 - 0.25..x1 + 0.25, 0.0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("atlas resolution (texels per side, log scale)")
        .y_desc("ratio (uncompressed / GPU-resident)")
        .x_labels(((x1 - x0) as usize + 1) * 2 + 1)
        .x_label_formatter(&|x| {
            // Label only the powers of two.
            if (x - x.round()).abs() < 1e-6 {
                format!("{}", 2f64.powf(x.round()))
            } else {
                String::new()
            }
        })
        .light_line_style(WHITE)
        .draw()
        .map_err(err)?;
    for (name, c, dashed, pts) in lines {
        let c = *c;
        let pts: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (x.log2(), y)).collect();
        if *dashed {
            chart
                .draw_series(DashedLineSeries::new(
                    pts.iter().copied(),
                    6,
                    4,
                    c.stroke_width(2),
                ))
                .map_err(err)?
                .label(name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 8, y)], c.stroke_width(2))
                });
        } else {
            chart
                .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))
                .map_err(err)?
                .label(name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2))
                });
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                .map_err(err)?;
        }
    }
    if lines.is_empty() {
        return Ok(());
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    Ok(())
}
