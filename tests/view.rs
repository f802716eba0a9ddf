//! `cssm view` end to end: a real window under Xvfb (Mesa's lavapipe presenting to it), whose
//! `--screenshot` must be pixel for pixel what `cssm render` writes for the same scene,
//! camera, light, method, size and frame count (the window renders into the same offscreen
//! image and reads it back: there is no reason for any difference, so none is tolerated); and
//! the clear error without a display.
//!
//! The window tests need `xvfb-run` (`apt-get install xvfb xauth`; `.ci/run` installs them)
//! and fail without it rather than pass without testing anything.

mod common;

use common::{cornell, stderr};
use std::{
    path::{Path, PathBuf},
    process::{Command, Output},
};

fn cssm_command() -> Command {
    Command::new(env!("CARGO_BIN_EXE_cssm"))
}

/// Runs `command` to its end, or kills it after two minutes and fails (a window that never
/// writes its screenshot would otherwise hang the test suite).
fn run(mut command: Command) -> Output {
    use std::process::Stdio;
    let mut child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run cssm");
    let start = std::time::Instant::now();
    while child.try_wait().expect("wait for cssm").is_none() {
        if start.elapsed() > std::time::Duration::from_secs(120) {
            let _ = child.kill();
            let out = child.wait_with_output().expect("wait for cssm");
            panic!(
                "{command:?} did not end within 2 minutes: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().expect("wait for cssm")
}

/// `xvfb-run` on PATH, or a failure that says how to install it.
fn xvfb_run() -> Command {
    let found = std::env::var_os("PATH")
        .map(|paths| std::env::split_paths(&paths).any(|dir| dir.join("xvfb-run").is_file()))
        .unwrap_or(false);
    assert!(
        found,
        "the cssm view tests need xvfb-run (a virtual X display): apt-get install xvfb xauth"
    );
    let mut command = Command::new("xvfb-run");
    // -a: a free display number, so that tests running at once do not collide.
    command.arg("-a").arg(env!("CARGO_BIN_EXE_cssm"));
    command
}

/// The decoded RGBA pixels of a PNG.
fn pixels(path: &Path) -> image::RgbaImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgba8()
}

/// `cssm view ... --screenshot` under Xvfb against `cssm render ...` with the same `args`.
fn window_matches_render(dir: &Path, args: &[&str], frames: &str, size: (u32, u32)) {
    let shot = dir.join("view.png");
    let rendered = dir.join("render.png");
    let mut view = xvfb_run();
    view.arg("view")
        .args(args)
        .args(["--frames", frames, "--screenshot"])
        .arg(&shot);
    let out = run(view);
    assert!(out.status.success(), "cssm view: {}", stderr(&out));
    // The image came from the window's loop, not from an offscreen fallback.
    assert!(stderr(&out).contains("viewing "), "{}", stderr(&out));
    let mut render = cssm_command();
    // The window's exposure is fixed (0 unless given); `cssm render` meters its own unless told.
    let fixed = if args.iter().any(|a| a.starts_with("--exposure")) {
        &[][..]
    } else {
        &["--exposure", "0"][..]
    };
    render
        .arg("render")
        .args(args)
        .args(fixed)
        .args(["--frames", frames, "--out"])
        .arg(&rendered);
    let out = run(render);
    assert!(out.status.success(), "cssm render: {}", stderr(&out));
    let (a, b) = (pixels(&shot), pixels(&rendered));
    assert_eq!(a.dimensions(), b.dimensions());
    assert_eq!(a.dimensions(), size);
    // An all-black pair would match without testing anything.
    assert!(
        a.pixels().any(|p| p.0[..3].iter().any(|&c| c > 16)),
        "the screenshot is black"
    );
    let differ = a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
    assert_eq!(
        differ,
        0,
        "{differ} of {} pixels differ between cssm view's screenshot and cssm render ({args:?})",
        a.len() / 4
    );
}

#[test]
fn view_screenshot_of_direct_light_is_cssm_renders_image() {
    let dir = tempfile::tempdir().unwrap();
    let scene = cornell();
    window_matches_render(
        dir.path(),
        &[
            scene.to_str().unwrap(),
            "--method",
            "direct",
            "--size",
            "64x48",
        ],
        "1",
        (64, 48),
    );
}

#[test]
fn view_screenshot_of_a_cssm_method_is_cssm_renders_image() {
    let dir = tempfile::tempdir().unwrap();
    let scene = cornell();
    let cssm = dir.path().join("cornell.cssm");
    let mut bake = cssm_command();
    bake.arg("bake")
        .arg(&scene)
        .arg("-o")
        .arg(&cssm)
        .args(["--atlas", "32", "--cube", "8"]);
    let out = run(bake);
    assert!(out.status.success(), "cssm bake: {}", stderr(&out));
    window_matches_render(
        dir.path(),
        &[
            scene.to_str().unwrap(),
            "--cssm",
            cssm.to_str().unwrap(),
            "--method",
            "lightmap",
            "--bounces",
            "2",
            "--size",
            "64x48",
        ],
        "2",
        (64, 48),
    );
}

/// `--camera` and `--light` place the window's camera and light as they place `cssm render`'s.
#[test]
fn view_with_a_camera_and_light_given_is_cssm_renders_image() {
    let dir = tempfile::tempdir().unwrap();
    let scene = cornell();
    let args = [
        scene.to_str().unwrap(),
        "--method",
        "direct",
        "--size",
        "64x48",
        "--camera=400,300,-700,278,273,0",
        "--light=278,540,279.5,0.2,-1,0",
    ];
    window_matches_render(dir.path(), &args, "1", (64, 48));
    // And they did place them: the scene's own camera and light render another image.
    let moved = pixels(&dir.path().join("view.png"));
    let unmoved = render_with(
        &scene,
        &["--method", "direct", "--size", "64x48"].map(String::from),
        dir.path(),
        "unmoved.png",
        false,
    );
    assert!(differing_pixels(&moved, &pixels(&unmoved)) > 0);
}

/// More frames than an interactive window accumulates before it rests (1024): the script still
/// gets its screenshot, of exactly that many frames.
#[test]
fn view_screenshot_after_more_frames_than_a_window_accumulates() {
    let dir = tempfile::tempdir().unwrap();
    let scene = cornell();
    window_matches_render(
        dir.path(),
        &[
            scene.to_str().unwrap(),
            "--method",
            "direct",
            "--size",
            "16x12",
        ],
        "1100",
        (16, 12),
    );
}

#[test]
fn view_without_a_display_says_so_and_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("never.png");
    let mut view = cssm_command();
    view.env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("WAYLAND_SOCKET")
        .args([
            "view",
            "--method",
            "direct",
            "--size",
            "64x48",
            "--screenshot",
        ])
        .arg(&shot);
    let out = run(view);
    let text = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{text}");
    assert!(
        text.contains("cssm view: cannot open a window") && text.contains("Xvfb"),
        "{text}"
    );
    assert!(!text.contains("panicked"), "{text}");
    assert!(!shot.exists());
}

#[test]
fn view_refuses_a_cpu_method_and_frames_without_a_screenshot() {
    let out = run({
        let mut c = cssm_command();
        c.args(["view", "--method", "reference"]);
        c
    });
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("cssm render --method reference"));
    let out = run({
        let mut c = cssm_command();
        c.args(["view", "--frames", "4"]);
        c
    });
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("--screenshot"), "{}", stderr(&out));
}

/// The `cssm render` flags `cssm view` printed for its screenshot `shot`, without the output
/// flag that names `shot` itself.
fn printed_render_flags(stderr: &str, shot: &Path) -> Vec<String> {
    let prefix = format!("render flags for {}: ", shot.display());
    let line = stderr
        .lines()
        .find_map(|l| l.strip_prefix(&prefix))
        .unwrap_or_else(|| panic!("no '{prefix}' line in:\n{stderr}"));
    let mut flags: Vec<String> = line.split_whitespace().map(str::to_string).collect();
    // The last two are `--out SHOT` or `--exr SHOT`.
    assert_eq!(flags.pop().as_deref(), shot.to_str(), "{line}");
    let output = flags.pop().unwrap();
    assert!(output == "--out" || output == "--exr", "{line}");
    flags
}

/// `cssm render` of `scene` with `flags` into `out` (a PNG, or with `exr` also an EXR there).
fn render_with(scene: &Path, flags: &[String], dir: &Path, out: &str, exr: bool) -> PathBuf {
    let mut render = cssm_command();
    render.arg("render").arg(scene).args(flags);
    let path = dir.join(out);
    if exr {
        render.arg("--out").arg(dir.join(format!("{out}.png")));
        render.arg("--exr").arg(&path);
    } else {
        render.arg("--out").arg(&path);
    }
    let out = run(render);
    assert!(out.status.success(), "cssm render: {}", stderr(&out));
    path
}

fn differing_pixels(a: &image::RgbaImage, b: &image::RgbaImage) -> usize {
    assert_eq!(a.dimensions(), b.dimensions());
    a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count()
}

/// A script drives the window as a person would (an orbit, a held fly key, a light drag and a
/// light move, the overlay hidden and shown, F12, Tab to the next method), and every screenshot it takes is what
/// `cssm render` writes with the flags the window printed for it: the camera, light, method
/// and frames it ended with. Each step must also have changed the image, or the comparison
/// would prove nothing about the step.
#[test]
fn view_script_steps_give_screenshots_that_cssm_render_reproduces() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = cornell();
    let script = d.join("tour.txt");
    std::fs::write(
        &script,
        format!(
            "# the camera, then the light, then the method\n\
             orbit 60 -15\n\
             screenshot {orbit}\n\
             hold w 3   # a step, then flies by the frames' time\n\
             screenshot {fly}\n\
             drag-light 30 10\n\
             move-light 20 0   # shift + right drag\n\
             key h\n\
             key h\n\
             screenshot {light}\n\
             key F12\n\
             key Tab\n\
             wait 2\n\
             screenshot {method}\n\
             screenshot {exr}\n\
             quit\n",
            orbit = d.join("orbit.png").display(),
            fly = d.join("fly.png").display(),
            light = d.join("light.png").display(),
            method = d.join("method.png").display(),
            exr = d.join("method.exr").display(),
        ),
    )
    .unwrap();
    let mut view = xvfb_run();
    view.arg("view")
        .arg(&scene)
        .args([
            "--method",
            "direct",
            "--size",
            "64x48",
            "--shot-exr",
            "--script",
        ])
        .arg(&script)
        // F12 writes into the current directory.
        .current_dir(d);
    let out = run(view);
    let text = stderr(&out);
    assert!(out.status.success(), "cssm view: {text}");
    assert!(text.contains("viewing "), "{text}");

    // The scene's own camera and light, for what the steps changed.
    let unmoved = render_with(
        &scene,
        &["--method", "direct", "--size", "64x48"].map(String::from),
        d,
        "unmoved.png",
        false,
    );
    let mut previous = pixels(&unmoved);
    for (name, method) in [
        ("orbit.png", "direct"),
        ("fly.png", "direct"),
        ("light.png", "direct"),
        ("method.png", "rsm"),
    ] {
        let shot = d.join(name);
        let flags = printed_render_flags(&text, &shot);
        assert!(
            flags.join(" ").contains(&format!("--method {method} ")),
            "{name}: {flags:?}"
        );
        let rendered = render_with(&scene, &flags, d, &format!("render-{name}"), false);
        let (a, b) = (pixels(&shot), pixels(&rendered));
        assert_eq!(a.dimensions(), (64, 48));
        assert!(
            a.pixels().any(|p| p.0[..3].iter().any(|&c| c > 16)),
            "{name} is black"
        );
        let differ = differing_pixels(&a, &b);
        assert_eq!(
            differ, 0,
            "{name}: {differ} pixels differ from cssm render {flags:?}"
        );
        let changed = differing_pixels(&a, &previous);
        assert!(changed > 0, "{name}: the step before it changed nothing");
        previous = a;
    }
    // The EXR screenshots (the script's, and F12's with --shot-exr): the linear radiance
    // `cssm render --exr` writes.
    for (printed, shot) in [
        (d.join("method.exr"), d.join("method.exr")),
        (
            PathBuf::from("cssm-view-0000.exr"),
            d.join("cssm-view-0000.exr"),
        ),
    ] {
        let flags = printed_render_flags(&text, &printed);
        let rendered = render_with(&scene, &flags, d, "render.exr", true);
        let (a, b) = (
            image::open(&shot).unwrap().to_rgba32f(),
            image::open(&rendered).unwrap().to_rgba32f(),
        );
        assert_eq!(a.dimensions(), (64, 48));
        assert!(a.pixels().any(|p| p.0[0] > 0.0), "{printed:?} is black");
        assert!(
            a.pixels().zip(b.pixels()).all(|(p, q)| p == q),
            "{printed:?} differs from cssm render --exr {flags:?}"
        );
    }
    // F12's PNG, of the light step's camera and light.
    let flags = printed_render_flags(&text, Path::new("cssm-view-0000.png"));
    assert!(flags.join(" ").contains("--method direct "), "{flags:?}");
    let rendered = render_with(&scene, &flags, d, "render-f12.png", false);
    let f12 = pixels(&d.join("cssm-view-0000.png"));
    assert_eq!(
        differing_pixels(&f12, &pixels(&rendered)),
        0,
        "F12: {flags:?}"
    );
    assert_eq!(differing_pixels(&f12, &pixels(&d.join("light.png"))), 0);
}

/// A bad script is refused before a window opens (no display needed): the file, the line and
/// the problem, exit status 2, no panic.
#[test]
fn view_script_errors_name_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("bad.txt");
    for (text, expected) in [
        ("orbit 10 0\n\nwait many\n", ":3: wait takes a whole number"),
        ("key Tab\nteleport 1 2\n", ":2: unknown step 'teleport'"),
        (
            "screenshot /nonexistent-dir/x.png\n",
            ":1: cannot write /nonexistent-dir/x.png",
        ),
    ] {
        std::fs::write(&script, text).unwrap();
        let out = run({
            let mut c = cssm_command();
            c.env_remove("DISPLAY")
                .env_remove("WAYLAND_DISPLAY")
                .args(["view", "--script"])
                .arg(&script);
            c
        });
        let message = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{message}");
        assert!(
            message.contains(&format!("{}{expected}", script.display())),
            "{text:?}: {message}"
        );
        assert!(!message.contains("panicked"), "{message}");
    }
    let out = run({
        let mut c = cssm_command();
        c.args(["view", "--script"])
            .arg(dir.path().join("none.txt"));
        c
    });
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("cannot read the script"),
        "{}",
        stderr(&out)
    );
}

/// `cssm render --camera/--light` refuse what places nothing.
#[test]
fn render_refuses_a_camera_or_light_that_places_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for (args, expected) in [
        (["--camera", "1,2,3"], "is not six numbers"),
        (
            ["--camera", "-1,2,3,-1,2,3"],
            "the eye and the target are the same point",
        ),
        (["--light", "1,2,3,0,0,0"], "the direction is zero"),
        (["--light", "1,2,3,0,nan,1"], "not a finite number"),
    ] {
        let out = run({
            let mut c = cssm_command();
            c.arg("render")
                .args(args)
                .arg("--out")
                .arg(dir.path().join("x.png"));
            c
        });
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(
            stderr(&out).contains(expected),
            "{args:?}: {}",
            stderr(&out)
        );
        assert!(!dir.path().join("x.png").exists());
    }
}
