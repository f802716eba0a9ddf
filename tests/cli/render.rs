//! `cssm render` end to end: the files it writes, its statistics, the arguments it refuses,
//! the automatic exposure and bounces, the in-memory bake's atlas.

use super::*;

#[test]
fn render_writes_png_and_exr_of_the_requested_size() {
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("direct.png");
    let exr = tmp.path().join("direct.exr");
    let o = cssm(&[
        "render",
        cornell().to_str().unwrap(),
        "--size",
        "96x64",
        "--out",
        png.to_str().unwrap(),
        "--exr",
        exr.to_str().unwrap(),
        "--timings",
        "--shadow-resolution",
        "512",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("GPU time per pass") || stdout.contains("not supported"),
        "{stdout}"
    );
    let image = image::open(&png).expect("PNG readable").to_rgba8();
    assert_eq!(image.dimensions(), (96, 64));
    // Lit surfaces and unlit background: not a blank image.
    let max = image.pixels().map(|p| p.0[0].max(p.0[1]).max(p.0[2])).max();
    let min = image.pixels().map(|p| p.0[0].max(p.0[1]).max(p.0[2])).min();
    assert!(max > Some(100) && min < Some(10), "{max:?} {min:?}");
    let radiance = image::open(&exr).expect("EXR readable").to_rgba32f();
    assert_eq!(radiance.dimensions(), (96, 64));
}

/// `--stats` counts the final gather and the radiosity gather with their CPU twins and prints
/// their work and the cost model's prediction; a method without a counted pass says so.
#[test]
fn render_stats_count_the_final_gather() {
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("stats.png");
    // The Cornell box at 32x24 with `method`'s stats: what it printed.
    let stats = |method: &str| {
        let o = cssm(&[
            "render",
            cornell().to_str().unwrap(),
            "--method",
            method,
            "--size",
            "32x24",
            "--shadow-resolution",
            "256",
            "--stats",
            "--out",
            png.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let stdout = stats("lightcuts");
    for needle in [
        "final gather of lightcuts at 32x24",
        "nodes visited per receiver: mean",
        "CSSM taps per query",
        "lane efficiency",
        "predicted GPU ms",
    ] {
        assert!(stdout.contains(needle), "{needle} missing from:\n{stdout}");
    }
    // Something was counted: a pixel visits nodes and queries some.
    let visited: f64 = stdout
        .split("nodes visited per receiver: mean ")
        .nth(1)
        .and_then(|rest| rest.split(',').next())
        .and_then(|mean| mean.trim().parse().ok())
        .expect("a mean");
    assert!(visited > 1.0, "{stdout}");
    let stdout = stats("lightmap");
    assert!(
        stdout.contains(
            "radiosity gather of lightmap, its first of up to 8 (until converged) bounce(s)"
        ) && stdout.contains("threads 2715"),
        "{stdout}"
    );
    assert!(stats("direct").contains("no pass of direct is counted yet"));
}

#[test]
fn render_rejects_bad_arguments() {
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("x.png");
    for (args, needle) in [
        (vec!["--size", "0x10"], "each side"),
        (vec!["--size", "640"], "WIDTHxHEIGHT"),
        (vec!["--method", "radiosity"], "unknown method"),
        (vec!["--shadow-resolution", "3"], "out of range"),
        (
            vec!["--method", "lightcuts", "--bounces", "9"],
            "out of range",
        ),
        (
            vec!["--method", "hrc", "--threshold=-1"],
            "must be a number",
        ),
        (vec!["--frames", "0"], "out of range"),
        (vec!["--component", "glossy"], "unknown component"),
        (
            vec!["--method", "reference", "--samples", "0"],
            "out of range",
        ),
        (
            vec!["--method", "lightmap", "--cssm", "/nonexistent/box.cssm"],
            "/nonexistent/box.cssm",
        ),
        (
            vec!["--method", "lightcuts", "--stats", "--animate"],
            "leave out --animate",
        ),
    ] {
        let mut all = vec!["render", "--out", png.to_str().unwrap()];
        all.extend(args);
        let o = cssm(&all);
        assert_eq!(o.status.code(), Some(2), "{all:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{all:?}: {}", stderr(&o));
        assert!(!png.exists());
    }
    let o = cssm(&[
        "render",
        "/nonexistent/scene",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("/nonexistent/scene"), "{}", stderr(&o));
}

/// Without `--exposure`, `cssm render` meters the image (the lit pixels' log-average luminance
/// at middle grey) and says which exposure it took; that exposure given back fixes the same
/// image; a fixed one is taken as given.
#[test]
fn render_exposes_automatically_unless_told() {
    let tmp = tempfile::tempdir().unwrap();
    let png = |name: &str| tmp.path().join(name);
    let scene = cornell();
    let render = |out: &std::path::Path, extra: &[&str]| {
        let mut args = vec![
            "render",
            scene.to_str().unwrap(),
            "--size",
            "64x48",
            "--shadow-resolution",
            "256",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        let o = cssm(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    let mean = |path: &std::path::Path| {
        let image = image::open(path).unwrap().to_luma8();
        image.pixels().map(|p| p.0[0] as f64).sum::<f64>() / image.pixels().len() as f64
    };
    let said = render(&png("auto.png"), &[]);
    let stops: String = said
        .split("--exposure ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("no exposure said: {said}"))
        .into();
    assert!(said.contains("exposure: automatic"), "{said}");
    let dark = render(&png("dark.png"), &["--exposure", "-8"]);
    assert!(!dark.contains("automatic"), "{dark}");
    let fixed = render(&png("fixed.png"), &["--exposure", &stops]);
    assert!(!fixed.contains("automatic"), "{fixed}");
    let (auto, dark, fixed) = (
        mean(&png("auto.png")),
        mean(&png("dark.png")),
        mean(&png("fixed.png")),
    );
    // Lit walls around middle grey on a black surround: neither dark nor washed out.
    assert!((40.0..170.0).contains(&auto), "{auto}");
    assert!(dark < 0.25 * auto, "{dark} {auto}");
    // The exposure said (rounded to hundredths of a stop) gives the same image.
    assert!((fixed - auto).abs() < 1.0, "{fixed} {auto}");
}

/// With no `--cssm`, `cssm render` bakes in memory at atlas 64, or at the smallest page from
/// there up that holds the scene's charts: 1,600 loose triangles do not fit 64², and the
/// render says so and goes on at 128 (the Sibenik's 6,913 charts failed the render at 64).
#[test]
fn render_bakes_at_an_atlas_that_holds_the_charts() {
    let dir = tempfile::tempdir().unwrap();
    let mut obj = String::new();
    for i in 0..40 {
        for j in 0..40 {
            let (x, z) = (i as f32, j as f32);
            obj += &format!("v {x} 0 {z}\nv {} 0 {z}\nv {x} 0 {}\n", x + 0.5, z + 0.5);
            let k = 3 * (40 * i + j) + 1;
            obj += &format!("f {k} {} {}\n", k + 2, k + 1);
        }
    }
    write(dir.path(), "loose.obj", &obj);
    let png = dir.path().join("loose.png");
    let o = cssm(&[
        "render",
        dir.path().join("loose.obj").to_str().unwrap(),
        "--method",
        "lightmap",
        "--bounces",
        "1",
        "--size",
        "8x6",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("do not fit atlas 64: baking at atlas 128"),
        "{}",
        stderr(&o)
    );
    assert!(png.is_file());
}

/// The path tracer's bounces run until converged unless `--bounces` fixes them, and it says
/// how many it kept (the Cornell box: about six at 1%).
#[test]
fn reference_says_the_bounces_it_kept_unless_told() {
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("reference.png");
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render",
            "--method",
            "reference",
            "--samples",
            "4",
            "--size",
            "16x12",
            "--out",
            png.to_str().unwrap(),
        ];
        args.extend(extra);
        let o = cssm(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    let said = render(&[]);
    let kept: u32 = said
        .split("bounces: automatic, ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no bounces said: {said}"));
    assert!((3..=8).contains(&kept), "{said}");
    assert!(
        said.contains(&format!("--bounces {kept} fixes it")),
        "{said}"
    );
    assert!(!render(&["--bounces", "2"]).contains("bounces: automatic"));
}
