//! `cssm compare` end to end: the page, opened in a headless Chromium, and the input it refuses.

use super::*;

/// Debian's Chromium (`apt-get install chromium`; `scripts/test.sh` installs it where it is
/// missing), or the browser `CSSM_CHROMIUM` names.
fn chromium() -> PathBuf {
    if let Some(path) = std::env::var_os("CSSM_CHROMIUM") {
        return path.into();
    }
    for name in ["chromium", "chromium-browser", "google-chrome"] {
        let found = std::env::var_os("PATH")
            .into_iter()
            .flat_map(|p| std::env::split_paths(&p).collect::<Vec<_>>())
            .map(|dir| dir.join(name))
            .find(|p| p.is_file());
        if let Some(path) = found {
            return path;
        }
    }
    panic!(
        "no Chromium to test the page in: install Debian's `chromium` (scripts/test.sh does) or \
         set CSSM_CHROMIUM to a Chromium binary"
    );
}

/// Headless Chromium with the flags this machine's closed network needs, a fresh profile in
/// `profile`, and `args`.
fn headless(profile: &Path, args: &[&str]) -> Output {
    Command::new(chromium())
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--hide-scrollbars",
            "--virtual-time-budget=15000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .output()
        .expect("run chromium")
}

fn file_url(path: &Path) -> String {
    format!("file://{}", path.canonicalize().unwrap().display())
}

/// Loads the page in a frame of its own harness page, once everything has loaded: how many
/// images, which did not load, and whether a click on the "indirect RMSE" header sorts the
/// table ascending and a second click descending.
const HARNESS: &str = r#"<!DOCTYPE html><html><body><pre id="result">pending</pre>
<iframe id="page" src="PAGE" style="width:1400px;height:3000px"></iframe>
<script>
window.addEventListener('load', function () {
  var out = document.getElementById('result');
  try {
    var doc = document.getElementById('page').contentDocument;
    var images = Array.prototype.slice.call(doc.images);
    var broken = images.filter(function (i) { return !(i.complete && i.naturalWidth > 0); })
      .map(function (i) { return i.getAttribute('src'); });
    var column = function () {
      return Array.prototype.slice.call(doc.querySelectorAll('#figures tbody tr'))
        .map(function (tr) { return tr.cells[2].getAttribute('data-value'); })
        .filter(function (v) { return v !== null && v !== ''; }).map(parseFloat);
    };
    var header = doc.querySelectorAll('#figures th')[2];
    header.click();
    var up = column();
    header.click();
    var down = column();
    // A failed method's row, as the page writes one (the names, then one cell saying why),
    // sorts last by any column.
    var failed = doc.createElement('tr');
    failed.innerHTML = '<td>s</td><td>m</td><td data-value="" colspan="12">failed</td>';
    doc.querySelector('#figures tbody').appendChild(failed);
    var headers = doc.querySelectorAll('#figures th');
    headers[headers.length - 2].click();
    var rows = doc.querySelectorAll('#figures tbody tr');
    var failedLast = rows[rows.length - 1] === failed;
    out.textContent = 'RESULT ' + JSON.stringify({images: images.length, broken: broken,
      rows: up.length,
      ascending: up.every(function (v, i) { return i === 0 || up[i - 1] <= v; }),
      descending: down.every(function (v, i) { return i === 0 || down[i - 1] >= v; }),
      failedLast: failedLast});
  } catch (e) {
    out.textContent = 'RESULT ' + JSON.stringify({error: String(e)});
  }
});
</script></body></html>
"#;

/// `cssm compare` of the built-in scenes, small (64x48, 16 paths per pixel, a .cssm at atlas
/// 32, cube 8, shadow maps of 256), into `out`, with `extra` flags.
fn small_compare(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "compare",
        "--size",
        "64x48",
        "--samples",
        "16",
        "--atlas",
        "32",
        "--cube",
        "8",
        "--shadow-resolution",
        "256",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    cssm(&args)
}

/// `cssm compare` end to end: every method of the table on the two built-in scenes at 64x48,
/// the page's files and figures; the page in a real browser (headless Chromium: no console
/// message, every image loads, the table sorts), with a screenshot kept in
/// `target/tmp/compare-page.png`; the reference cache.
#[test]
fn compare_every_method_and_open_the_page_in_a_browser() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("page");
    let o = small_compare(&out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    for file in [
        "index.html",
        "chart.svg",
        "compare.csv",
        "compare.json",
        "compare.md",
    ] {
        assert!(out.join(file).is_file(), "{file}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("compare.json")).unwrap()).unwrap();
    let scenes = json["scenes"].as_array().unwrap();
    assert_eq!(scenes.len(), 2);
    // Every GPU method of the table, on both scenes, without naming them here.
    let gpu_methods: Vec<&str> = cssm::runtime::METHODS
        .iter()
        .filter(|m| m.on_gpu())
        .map(|m| m.name)
        .collect();
    let number = |v: &serde_json::Value| v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"));
    for scene in scenes {
        let name = scene["name"].as_str().unwrap();
        let methods = scene["methods"].as_array().unwrap();
        let specs: Vec<&str> = methods
            .iter()
            .map(|m| m["spec"].as_str().unwrap())
            .collect();
        assert_eq!(specs, gpu_methods, "{name}");
        for component in ["full", "indirect"] {
            let reference = &scene["reference"][component];
            assert!(
                number(&reference["noise_floor"]) > 0.0,
                "{name} {component}"
            );
            assert!(out.join(reference["image"].as_str().unwrap()).is_file());
        }
        for m in methods {
            let spec = m["spec"].as_str().unwrap();
            let x = &m["measured"];
            assert!(x.is_object(), "{name} {spec}: {m}");
            for component in ["full", "indirect"] {
                let f = &x["figures"][component];
                let (raw, clean) = (
                    number(&f["relative_rmse"]),
                    number(&f["relative_rmse_without_noise"]),
                );
                // The reference's noise only ever comes out.
                assert!(
                    clean <= raw && clean >= 0.0,
                    "{name} {spec} {component}: {f}"
                );
                assert!(number(&f["noise_share"]) > 0.0, "{name} {spec} {component}");
            }
            for image in ["full", "indirect", "indirect_error"] {
                let path = out.join(x["images"][image].as_str().unwrap());
                let png = image::open(&path).unwrap();
                assert_eq!((png.width(), png.height()), (64, 48), "{}", path.display());
            }
            assert!(number(&x["memory_bytes"]) > 0.0, "{name} {spec}");
            let passes = x["passes"].as_array().unwrap();
            assert!(
                passes.iter().any(|p| p["name"] == "gbuffer"),
                "{name} {spec}: {passes:?}"
            );
        }
        // `direct` has no indirect light: all of the reference's is missing.
        let direct = &methods[0]["measured"]["figures"]["indirect"];
        assert!((number(&direct["relative_rmse"]) - 1.0).abs() < 1e-9);
        assert!((number(&direct["bias"]) + 1.0).abs() < 1e-9);
    }
    let md = std::fs::read_to_string(out.join("compare.md")).unwrap();
    assert!(md.contains("## cornell-glossy"), "{md}");
    let svg = std::fs::read_to_string(out.join("chart.svg")).unwrap();
    for method in &gpu_methods {
        assert!(
            svg.contains(&format!(">\n{method}\n</text>")),
            "{method} in the chart's legend"
        );
    }

    // The page as a person opens it, in a real browser. Every console message fails the test
    // (the page logs nothing; an uncaught error or a failed script shows as one).
    let harness = dir.path().join("harness.html");
    std::fs::write(
        &harness,
        HARNESS.replace("PAGE", &file_url(&out.join("index.html"))),
    )
    .unwrap();
    let o = headless(
        &dir.path().join("profile"),
        &[
            "--allow-file-access-from-files",
            "--enable-logging=stderr",
            "--v=0",
            "--dump-dom",
            &file_url(&harness),
        ],
    );
    assert!(o.status.success(), "chromium: {}", stderr(&o));
    let dom = String::from_utf8_lossy(&o.stdout);
    let log = stderr(&o);
    let console: Vec<&str> = log
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(|l| l.trim())
        .collect::<Vec<_>>();
    assert!(console.is_empty(), "console messages: {console:#?}");
    let result = dom
        .split("RESULT ")
        .nth(1)
        .and_then(|r| r.split("</pre>").next())
        .unwrap_or_else(|| panic!("the harness wrote no result: {dom}"));
    let result: serde_json::Value = serde_json::from_str(&result.replace("&quot;", "\""))
        .unwrap_or_else(|e| panic!("{e}: {result}"));
    assert!(result.get("error").is_none(), "{result}");
    assert_eq!(result["broken"], serde_json::json!([]), "{result}");
    // Per scene the two references and three images a method, and the chart.
    let n = gpu_methods.len() as u64;
    assert_eq!(result["images"], 2 * (2 + 3 * n) + 1, "{result}");
    assert_eq!(result["rows"], 2 * n, "{result}");
    assert_eq!(result["ascending"], true, "{result}");
    assert_eq!(result["descending"], true, "{result}");
    assert_eq!(result["failedLast"], true, "{result}");

    // A screenshot of the page, kept for a person to look at.
    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("compare-page.png");
    let _ = std::fs::remove_file(&shot);
    let o = headless(
        &dir.path().join("profile-shot"),
        &[
            "--window-size=1400,3000",
            &format!("--screenshot={}", shot.display()),
            &file_url(&out.join("index.html")),
        ],
    );
    assert!(o.status.success(), "chromium: {}", stderr(&o));
    let png = image::open(&shot).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (1400, 3000));
    let distinct: std::collections::HashSet<[u8; 3]> = png.pixels().map(|p| p.0).collect();
    assert!(
        distinct.len() > 100,
        "a page, not a blank: {} colours",
        distinct.len()
    );

    // Again with one method: the references come from the cache.
    let o = small_compare(&out, &["--methods", "direct"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(stderr(&o).matches("reusing").count(), 4, "{}", stderr(&o));
}

#[test]
fn compare_refuses_bad_input_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("page");
    for (args, needle) in [
        (
            vec!["--methods", "rsm,radiosity"],
            "unknown method 'radiosity'",
        ),
        (vec!["--methods", "rsm:colour=red"], "no option 'colour'"),
        (vec!["--methods", "rsm,rsm"], "given twice"),
        (vec!["--methods", ","], "no method given"),
        (vec!["--size", "0x48"], "image size 0x48"),
        (vec!["--exposure", "NaN"], "--exposure"),
        (vec!["--frames", "0"], "--frames"),
        (vec!["--samples", "0"], "samples"),
        (vec!["--bounces", "0"], "cannot be compared"),
        (
            vec![dir.path().join("nowhere").to_str().unwrap()],
            "nowhere",
        ),
    ] {
        let mut all = vec!["compare", "--out", out.to_str().unwrap()];
        all.extend(&args);
        let o = cssm(&all);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{args:?}: {}", stderr(&o));
        assert!(!out.exists(), "{args:?}: nothing is written");
    }
    // A scene named to climb out of OUT writes only inside it.
    let scene = dir.path().join("scene");
    std::fs::create_dir_all(&scene).unwrap();
    for file in ["cornell-box.obj", "cornell-box.mtl"] {
        std::fs::copy(cornell().join(file), scene.join(file)).unwrap();
    }
    let toml = std::fs::read_to_string(cornell().join("scene.toml")).unwrap();
    write(
        &scene,
        "scene.toml",
        &toml.replace("name = \"cornell-box\"", "name = \"../../escaped\""),
    );
    let o = small_compare(&out, &[scene.to_str().unwrap(), "--methods", "direct"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!dir.path().join("escaped").exists() && !out.join("../escaped").exists());
    assert!(out.join("images/_.._escaped/direct-full.png").is_file());
    std::fs::remove_dir_all(&out).unwrap();

    let file = dir.path().join("notes.txt");
    std::fs::write(&file, "keep me").unwrap();
    let o = cssm(&[
        "compare",
        "--methods",
        "direct",
        "--out",
        file.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("not a directory"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep me");
}
