//! `cssm report` and `cssm diagnose` end to end: the compression and error reports, small, and
//! the options they refuse.

use super::*;

/// `cssm diagnose` runs the lab's diagnostics on a baked file (their figures are the lab's
/// tests'), and a file it cannot read is an error that names it, not a panic.
#[test]
fn diagnose_runs_on_a_baked_file_and_names_a_bad_one() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("cornell.cssm");
    let o = bake_small(&cornell(), &file);
    assert!(o.status.success(), "{}", stderr(&o));
    let file = file.to_str().unwrap();
    let o = cssm(&["diagnose", "filters", file, "--pairs", "2000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("exchanging pairs with texels at both ends"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let missing = dir.path().join("missing.cssm");
    let o = cssm(&["diagnose", "ends", missing.to_str().unwrap()]);
    assert_fails(&o, "missing.cssm", &dir.path().join("none"));
}

/// The compression report, small (Cornell box, atlas 32 and 64, cube 8): the files are written,
/// the Markdown tables have their headers and one line per planned row, the CSV has every column
/// on every row, and the ratio grows with the atlas resolution for every traversal (Table 2) and
/// variant (Table 3).
#[test]
fn compression_report_small() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = cssm(&[
        "report",
        "compression",
        "--out",
        out,
        "--atlas",
        "32,64",
        "--cube",
        "8",
        "--scene",
        "cornell",
        "--pairs",
        "20000",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let md = std::fs::read_to_string(dir.path().join("compression.md")).unwrap();
    let csv = std::fs::read_to_string(dir.path().join("compression.csv")).unwrap();
    let svg = std::fs::read_to_string(dir.path().join("compression.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("polyline"), "{svg}");
    for needle in [
        "## Table 2",
        "## Table 3",
        "## Beyond the paper",
        "## Targets",
        "| atlas | cube | traversal | depth maps | runs | ratio | paper |",
        "| scene | faces (paper) | atlas | cube | variant |",
        "Which wins",
        "commit `",
        "cores",
    ] {
        assert!(
            md.contains(needle),
            "compression.md lacks {needle:?}:\n{md}"
        );
    }
    // Markdown table rows: 2 atlases x 5 traversals, 2 atlases x 2 variants, every option.
    let options = cssm::report::OPTIONS.len();
    let table_rows = |header: &str| {
        let start = md.find(header).unwrap();
        md[start..]
            .lines()
            .skip(2)
            .take_while(|l| l.starts_with('|'))
            .count()
    };
    assert_eq!(table_rows("| atlas | cube | traversal"), 10, "{md}");
    assert_eq!(table_rows("| scene | faces"), 4, "{md}");
    assert_eq!(table_rows("| option |"), options, "{md}");

    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 10 + 4 + options);
    for r in &rows {
        assert_eq!(r.len(), header.len(), "{r:?}");
        assert_eq!(r[col("status")], "ok", "{r:?}");
        assert!(r[col("agreement")].parse::<f64>().unwrap() > 0.9, "{r:?}");
    }
    let ratio = |table: &str, variant: &str, atlas: &str| -> f64 {
        rows.iter()
            .find(|r| {
                r[col("table")] == table && r[col("variant")] == variant && r[col("atlas")] == atlas
            })
            .unwrap_or_else(|| panic!("no row {table} {variant} {atlas}"))[col("ratio")]
        .parse()
        .unwrap()
    };
    for t in ["greedy", "zigzag", "spiral", "hilbert", "piloted"] {
        assert!(
            ratio("table2", t, "64") > ratio("table2", t, "32"),
            "{t}: {csv}"
        );
    }
    for v in ["paper", "best"] {
        assert!(
            ratio("table3", v, "64") > ratio("table3", v, "32"),
            "{v}: {csv}"
        );
        // The Options rows with Table 3's settings take an earlier row's bake: Table 3's, or
        // at this cube size Table 2's spiral row, which is the paper's method too.
        let option = rows
            .iter()
            .find(|r| r[col("table")] == "options" && r[col("variant")] == v)
            .unwrap();
        assert_eq!(
            option[col("ratio")].parse::<f64>().unwrap(),
            ratio("table3", v, "64")
        );
        let earlier = match v {
            "paper" => "table2 cornell atlas 64 cube 8 spiral",
            _ => "table3 cornell atlas 64 cube 8 best",
        };
        assert_eq!(option[col("same_bake_as")], earlier, "{option:?}");
    }
    assert!(md.contains("not baked twice"), "{md}");
    // The 98% accuracy target counts every Cornell box bake once, and a row below it is set
    // beside the paper's method at the same atlas and cube (at cube 8 every row is below).
    let baked: Vec<&Vec<&str>> = rows
        .iter()
        .filter(|r| r[col("scene")] == "cornell" && r[col("same_bake_as")].is_empty())
        .collect();
    let at_least = baked
        .iter()
        .filter(|r| r[col("agreement")].parse::<f64>().unwrap() >= 0.98)
        .count();
    let line = format!(
        "- Agreement at least 98% on the Cornell box: {at_least} of {} rows",
        baked.len()
    );
    assert!(md.contains(&line), "{line}\n{md}");
    if at_least < baked.len() {
        assert!(
            md.contains("At atlas 32, cube 8, the paper's own lossless method agrees"),
            "{md}"
        );
    }
}

#[test]
fn compression_report_refuses_bad_options() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope");
    let o = cssm(&[
        "report",
        "compression",
        "--quick",
        "--out",
        missing.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("nope"), "{}", stderr(&o));
    let o = cssm(&[
        "report",
        "compression",
        "--out",
        dir.path().to_str().unwrap(),
        "--atlas",
        "16",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--atlas 16"), "{}", stderr(&o));
    // A scenes directory without the third-party scenes: their rows are listed as not run.
    let o = cssm(&[
        "report",
        "compression",
        "--out",
        dir.path().to_str().unwrap(),
        "--tables",
        "table3",
        "--scene",
        "heads,church",
        "--atlas",
        "32",
        "--cube",
        "8",
        "--scenes",
        missing.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let md = std::fs::read_to_string(dir.path().join("compression.md")).unwrap();
    assert!(md.contains("## Rows that did not run"), "{md}");
    assert!(
        md.contains("nope/teapot") && md.contains("sibenik not found"),
        "{md}"
    );
}

/// Reads `error.csv` into (scene, method) -> column -> value.
fn error_csv(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    lines
        .map(|line| {
            // Quoted fields (specs with commas, the device) hold no quotes here.
            let mut fields = Vec::new();
            let mut rest = line;
            while !rest.is_empty() || fields.len() < header.len() {
                if let Some(stripped) = rest.strip_prefix('"') {
                    let end = stripped.find('"').unwrap();
                    fields.push(stripped[..end].to_string());
                    rest = stripped[end + 1..].strip_prefix(',').unwrap_or("");
                } else {
                    let (field, tail) = rest.split_once(',').unwrap_or((rest, ""));
                    fields.push(field.to_string());
                    rest = tail;
                }
                if fields.len() == header.len() {
                    break;
                }
            }
            assert_eq!(fields.len(), header.len(), "{line}");
            header.iter().cloned().zip(fields).collect()
        })
        .collect()
}

/// `cssm report error` end to end, tiny (16x12, 16 paths per pixel) on the built-in scenes: the
/// files are written; `direct` has no indirect light (relative RMSE 1, bias -1); the path
/// tracer as a method, with other seeds than the reference, is within the reference's noise
/// (about sqrt(2) times its noise floor); a CSSM method gets its .cssm baked in memory, and
/// `--reference-cache` reuses the reference.
#[test]
fn error_report_small() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report");
    let o = cssm(&[
        "report",
        "error",
        "--method",
        "direct",
        "--method",
        "reference",
        "--size",
        "16x12",
        "--samples",
        "16",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("| cornell-box | direct |"), "{stdout}");
    for scene in ["cornell-box", "cornell-glossy"] {
        for file in [
            "reference.png",
            "reference.exr",
            "reference.json",
            "direct.png",
            "reference-method.png",
            "strip.png",
        ] {
            assert!(
                out.join(format!("{scene}-{file}")).is_file(),
                "{scene}-{file}"
            );
        }
        let strip = image::open(out.join(format!("{scene}-strip.png"))).unwrap();
        assert_eq!((strip.width(), strip.height()), (3 * 16 + 2 * 2, 12));
    }
    let md = std::fs::read_to_string(out.join("error.md")).unwrap();
    assert!(md.contains("| scene | method | relative RMSE |"), "{md}");
    let rows = error_csv(&out.join("error.csv"));
    assert_eq!(rows.len(), 6, "a noise floor and two variants per scene");
    let number = |scene: &str, method: &str, column: &str| -> f64 {
        let row = rows
            .iter()
            .find(|r| r["scene"] == scene && r["method"] == method)
            .unwrap_or_else(|| panic!("no row {scene} {method}"));
        row[column]
            .parse()
            .unwrap_or_else(|_| panic!("{scene} {method} {column}: '{}'", row[column]))
    };
    for scene in ["cornell-box", "cornell-glossy"] {
        assert!((number(scene, "direct", "relative_rmse") - 1.0).abs() < 1e-9);
        assert!((number(scene, "direct", "bias") + 1.0).abs() < 1e-9);
        let floor = number(scene, "reference-noise-floor", "relative_rmse");
        let rmse = number(scene, "reference", "relative_rmse");
        assert!(floor > 0.0, "{scene}: {floor}");
        assert!(
            rmse > 0.7 * floor && rmse < 2.5 * floor,
            "{scene}: reference as a method {rmse}, noise floor {floor}"
        );
        assert!(number(scene, "reference", "bias").abs() < 0.5);
        assert!(number(scene, "reference", "mean_flip") < number(scene, "direct", "mean_flip"));
    }

    // A CSSM method, baked in memory; the reference from the cache.
    let o = cssm(&[
        "report",
        "error",
        "--scene",
        cornell().to_str().unwrap(),
        "--method",
        "lightcuts:bounces=1",
        "--size",
        "16x12",
        "--samples",
        "16",
        "--atlas",
        "32",
        "--cube",
        "8",
        "--reference-cache",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("reusing"), "{}", stderr(&o));
    assert!(out.join("cornell-box-lightcuts-bounces-1.png").is_file());
    let rows = error_csv(&out.join("error.csv"));
    let lightcuts = rows
        .iter()
        .find(|r| r["method"] == "lightcuts:bounces=1")
        .unwrap();
    let rmse: f64 = lightcuts["relative_rmse"].parse().unwrap();
    assert!(rmse > 0.0 && rmse < 1.0, "{rmse}");
    assert!(!lightcuts["device"].is_empty());
}

#[test]
fn error_report_refuses_bad_methods_and_out() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report");
    for (spec, needles) in [
        ("radiosity", vec!["--method radiosity", "unknown method"]),
        (
            "lightcuts:colour=red",
            vec!["--method lightcuts:colour=red", "no option 'colour'"],
        ),
        (
            "lightcuts:bounces=99",
            vec!["--method lightcuts:bounces=99", "out of range"],
        ),
        (
            "lightcuts:bounces",
            vec!["--method lightcuts:bounces", "OPTION=VALUE"],
        ),
    ] {
        let o = cssm(&[
            "report",
            "error",
            "--method",
            spec,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{spec}: {}", stderr(&o));
        for needle in needles {
            assert!(stderr(&o).contains(needle), "{spec}: {}", stderr(&o));
        }
        assert!(!out.exists(), "{spec}: nothing is written");
    }
    let o = cssm(&["report", "error", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "--method is required");

    let file = dir.path().join("notes.txt");
    std::fs::write(&file, "keep me").unwrap();
    let o = cssm(&[
        "report",
        "error",
        "--method",
        "direct",
        "--size",
        "16x12",
        "--samples",
        "4",
        "--out",
        file.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("not a directory"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep me");
}
