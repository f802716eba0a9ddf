//! The summaries' JSON: the keys `cssm report compression` reads, reading back equal, and the
//! bytes the commands printed before these types.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::{BakeSummary, CheckSummary, InspectSummary, json_line};
use cssm_bake::{self as bake, check::Agreement};

/// Reads `value`'s JSON back and checks that it says the same: every key and integer
/// exactly, every float to the last bit but one (serde_json parses floats fast, not always
/// correctly rounded: 0.9473684210526315 reads as ...316).
fn read_back<T: Serialize + serde::de::DeserializeOwned>(value: &T) -> T {
    let back: T = serde_json::from_str(&json_line(value)).unwrap();
    let (a, b) = (
        serde_json::to_value(value).unwrap(),
        serde_json::to_value(&back).unwrap(),
    );
    let (a, b) = (a.as_object().unwrap(), b.as_object().unwrap());
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (key, x) in a {
        match (x.as_f64(), &b[key]) {
            (Some(x), y) if y.is_f64() => {
                let y = y.as_f64().unwrap();
                assert!(
                    (x - y).abs() <= 2.0 * f64::EPSILON * x.abs(),
                    "{key}: {x} {y}"
                );
            }
            (_, y) => assert_eq!(x, y, "{key}"),
        }
    }
    back
}

fn keys(json: &str) -> Vec<String> {
    let value: serde_json::Value = serde_json::from_str(json).unwrap();
    value.as_object().unwrap().keys().cloned().collect()
}

fn bake_summary() -> BakeSummary {
    BakeSummary {
        scene: "cornell-box".into(),
        output: "/tmp/x.cssm".into(),
        triangles: 34,
        atlas_resolution: 32,
        cube_resolution: 8,
        traversal: "hilbert".into(),
        chart_order: "nearest".into(),
        run_value: "middle".into(),
        merge_short_runs: 0,
        second_layer: "any".into(),
        pixel_grid: "staggered".into(),
        cube_frame: "turned".into(),
        file_coding: "packed".into(),
        charts: 30,
        defined_texels: 500,
        rays: 190_000,
        runs: 9_000,
        uncompressed_bytes: 384_000,
        gpu_bytes: 40_000,
        file_bytes: 20_001,
        ratio_gpu: 9.6,
        ratio_file: 384_000.0 / 20_001.0,
        csms: 0,
        csm_gpu_bytes: 0,
        csm_seconds: 0.0,
        atlas_seconds: 0.01,
        traversal_seconds: 0.001,
        maps_seconds: 0.1,
        hierarchy_seconds: 0.0001,
        total_seconds: 0.2,
        rays_per_second: 1.9e6,
        threads: 2,
        gpu: None,
        peak_rss_bytes: Some(12 << 20),
    }
}

/// `cssm report compression` reads these keys of `cssm bake --json` and `cssm check --json`
/// (`report::bake_and_check`); every summary reads back equal from its JSON.
#[test]
fn summaries_round_trip_through_json_with_the_keys_the_report_reads() {
    let bake = bake_summary();
    let json = bake.to_json();
    assert_eq!(
        keys(&json),
        [
            "atlas_resolution",
            "atlas_seconds",
            "chart_order",
            "charts",
            "cube_frame",
            "cube_resolution",
            "defined_texels",
            "file_bytes",
            "file_coding",
            "gpu_bytes",
            "hierarchy_seconds",
            "maps_seconds",
            "merge_short_runs",
            "output",
            "peak_rss_bytes",
            "pixel_grid",
            "ratio_file",
            "ratio_gpu",
            "rays",
            "rays_per_second",
            "run_value",
            "runs",
            "scene",
            "second_layer",
            "threads",
            "total_seconds",
            "traversal",
            "traversal_seconds",
            "triangles",
            "uncompressed_bytes",
        ]
    );
    for key in [
        "triangles",
        "charts",
        "defined_texels",
        "runs",
        "uncompressed_bytes",
        "gpu_bytes",
        "file_bytes",
        "total_seconds",
        "peak_rss_bytes",
    ] {
        assert!(keys(&json).iter().any(|k| k == key), "{key}");
    }
    read_back(&bake);
    // Where the system reports no peak memory the key is null, and reads back as None.
    let no_rss = BakeSummary {
        peak_rss_bytes: None,
        ..bake
    };
    assert!(no_rss.to_json().contains("\"peak_rss_bytes\":null"));
    assert_eq!(read_back(&no_rss).peak_rss_bytes, None);

    let m = bake::check::Measurement {
        all: Agreement {
            visible_visible: 50,
            visible_occluded: 2,
            occluded_visible: 3,
            occluded_occluded: 40,
            unmapped: 5,
        },
        exchanging: Agreement {
            visible_visible: 30,
            visible_occluded: 1,
            occluded_visible: 1,
            occluded_occluded: 20,
            unmapped: 2,
        },
        causes: bake::check::Causes {
            atlas: 1,
            near: 0,
            cube: 1,
            filter: 0,
        },
    };
    let check = CheckSummary::new(Path::new("x.cssm"), &m, 0.25);
    let json = check.to_json();
    assert_eq!(
        keys(&json),
        [
            "agreement",
            "causes_atlas",
            "causes_cube",
            "causes_filter",
            "causes_near",
            "exchanging_agreement",
            "exchanging_false_occluded_rate",
            "exchanging_false_visible_rate",
            "exchanging_pairs",
            "false_occluded_rate",
            "false_visible_rate",
            "occluded_occluded",
            "occluded_visible",
            "pairs",
            "seconds",
            "unmapped",
            "visible_occluded",
            "visible_visible",
        ]
    );
    let back = read_back(&check);
    assert_eq!(
        (back.file.as_os_str(), back.exchanging),
        ("".as_ref(), None)
    );
    assert_eq!(back.all(), m.all);
    assert_eq!(back.exchanging_pairs, 52);
    // The text tells both confusion matrices; read back from the JSON, which has only the
    // exchanging pairs' figures, the same figures in one line.
    let full = check.to_string();
    assert!(full.contains(&m.all.to_string()), "{full}");
    assert!(full.contains(&m.exchanging.to_string()), "{full}");
    assert!(full.ends_with("(5 pairs had no texel for either point and were skipped)"));
    assert!(
        full.contains("atlas 1.923% (--atlas), near distance 0.000% (--near), cube map 1.923%"),
        "{full}"
    );
    let text = back.to_string();
    let last = m.exchanging.to_string().lines().last().unwrap().to_string();
    assert!(
        text.contains(&format!(":\n{last}\n")),
        "{text}\n---\n{last}"
    );
}

/// The bytes are those of the `serde_json::json!` object `--json` printed before these
/// types: keys sorted, `f32` fields as the `f64` they widen to.
#[test]
fn json_is_the_bytes_the_commands_always_printed() {
    let inspect = InspectSummary {
        path: PathBuf::from("x.cssm"),
        format_version: 2,
        scene: "cornell-box".into(),
        scene_dir: "/scenes/cornell-box".into(),
        scene_hash: "ab".repeat(32),
        triangles: 34,
        atlas_resolution: 32,
        cube_resolution: 8,
        near: 1.1056,
        far: 552.8,
        traversal: "hilbert".into(),
        pixel_grid: "centred".into(),
        cube_frame: "world".into(),
        defined_texels: 500,
        runs: 9_000,
        uncompressed_bytes: 384_000,
        gpu_bytes: 40_000,
        file_bytes: 20_001,
        ratio_gpu: 9.6,
        ratio_file: 384_000.0 / 20_001.0,
        csms: 0,
        csm_gpu_bytes: 0,
    };
    let i = &inspect;
    let old = serde_json::json!({
        "format_version": i.format_version,
        "scene": i.scene,
        "scene_dir": i.scene_dir,
        "scene_hash": i.scene_hash,
        "triangles": i.triangles,
        "atlas_resolution": i.atlas_resolution,
        "cube_resolution": i.cube_resolution,
        "near": i.near,
        "far": i.far,
        "traversal": i.traversal,
        "pixel_grid": i.pixel_grid,
        "cube_frame": i.cube_frame,
        "defined_texels": i.defined_texels,
        "runs": i.runs,
        "uncompressed_bytes": i.uncompressed_bytes,
        "gpu_bytes": i.gpu_bytes,
        "file_bytes": i.file_bytes,
        "ratio_gpu": i.ratio_gpu,
        "ratio_file": i.ratio_file,
    });
    assert_eq!(inspect.to_json(), old.to_string());
    let back = read_back(&inspect);
    assert_eq!(back.near, inspect.near, "an f32 reads back as itself");
    assert_eq!(back.path, PathBuf::new());
    assert!(
        inspect
            .to_string()
            .starts_with("x.cssm: CSSM format version 2\n")
    );
    assert!(inspect.to_string().contains("near 1.1056, far 552.8000"));
}
