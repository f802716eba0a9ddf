//! `compression.md`: the report's Markdown, its Tables 2 and 3 beside the paper's figures, the
//! Options table with which option wins, the targets and times ([`super::targets`]) and the
//! rows that did not run.

use std::fmt::Write as _;

use super::targets::{targets, times};
use super::{SAME_ACCURACY_POINTS, agree, bytes, rows, seconds};
use crate::report::{BEST, PAPER, PaperFigures, Report, Row, TableId, Variant, paper};

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
            PAPER.about, BEST.about
        );
        for row in rows(r, TableId::Table3) {
            let p = &row.plan;
            let pr = match p.paper {
                PaperFigures::Table3(t) => Some(t),
                _ => None,
            };
            let faces_paper = p.scene.paper_faces();
            let pv =
                |f: &dyn Fn(&paper::Table3Row) -> String| pr.as_ref().map_or("-".to_string(), f);
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
