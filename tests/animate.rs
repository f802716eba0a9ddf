//! `cssm render --animate` end to end (GPU: lavapipe where there is no GPU, so every image is
//! tiny): the Cornell box with a rigid block that moves by keyframes, rendered frame by frame;
//! each frame against a still render of the block placed at that frame's pose; the default
//! spin; and bad input (clear message, exit status 2, nothing written).

use std::{
    path::{Path, PathBuf},
    process::{Command, Output},
};

mod common;

use common::{assert_refused as assert_fails, stderr};

/// Runs `cssm`; a `render` at the fixed exposure 0 unless the test gives one: the frames are
/// compared with stills, and each still would otherwise meter its own automatic exposure. A
/// `render` that names no method draws the direct light ([`common::direct_unless_named`]).
fn cssm(args: &[&str]) -> Output {
    let mut args = common::direct_unless_named(args);
    if args.first() == Some(&"render") && !args.iter().any(|a| a.starts_with("--exposure")) {
        args.extend(["--exposure", "0"]);
    }
    Command::new(env!("CARGO_BIN_EXE_cssm"))
        .args(args)
        .output()
        .expect("run cssm")
}

/// The Cornell box with a white block (120 units a side) as the rigid object `block`, placed at
/// `translation`, turned `turn_deg` about y, with `animation` (an `[objects.animation]` table's
/// body, or "" for none), written to `dir`.
fn block_scene(dir: &Path, translation: [f32; 3], turn_deg: f32, animation: &str) -> PathBuf {
    let box_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    for f in ["cornell-box.obj", "cornell-box.mtl"] {
        std::fs::copy(box_dir.join(f), dir.join(f)).unwrap();
    }
    let obj = format!(
        "mtllib cornell-box.mtl\nusemtl white\n{}",
        cssm::builtin::cube_obj([0.0; 3], 60.0, 0, false)
    );
    std::fs::write(dir.join("block.obj"), obj).unwrap();
    let [tx, ty, tz] = translation;
    let animation = if animation.is_empty() {
        String::new()
    } else {
        format!("\n[objects.animation]\n{animation}\n")
    };
    std::fs::write(
        dir.join("scene.toml"),
        format!(
            "name = \"block\"\nmesh = \"cornell-box.obj\"\n\n[camera]\n\
             position = [278.0, 273.0, -800.0]\ntarget = [278.0, 273.0, 0.0]\n\
             up = [0.0, 1.0, 0.0]\nfov_y_deg = 39.3\nresolution = [32, 24]\n\n\
             [[lights]]\ntype = \"spot\"\nposition = [278.0, 540.0, 279.5]\n\
             direction = [0.0, -1.0, 0.0]\ncutoff_deg = 60.0\n\
             intensity = [500000.0, 500000.0, 500000.0]\n\n\
             [[objects]]\nname = \"block\"\nmesh = \"block.obj\"\n\
             translation = [{tx}, {ty}, {tz}]\nrotation_deg = [0.0, {turn_deg}, 0.0]\n\
             scale = 2.0\n{animation}"
        ),
    )
    .unwrap();
    dir.to_path_buf()
}

/// The block slides from x = 100 to x = 400 over 3 s and turns from 30 to 90 degrees.
const SLIDE: &str = "repeat = \"once\"\nkeyframes = [\n  { time = 0.0 },\n  \
                     { time = 3.0, translation = [400.0, 0.0, 150.0], \
                     rotation_deg = [0.0, 90.0, 0.0] },\n]";

fn rgba(path: &Path) -> image::RgbaImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgba8()
}

/// Pixels whose largest channel difference exceeds `tolerance`, as (x, y).
fn differing(a: &image::RgbaImage, b: &image::RgbaImage, tolerance: u8) -> Vec<(u32, u32)> {
    assert_eq!(a.dimensions(), b.dimensions());
    a.enumerate_pixels()
        .filter(|(x, y, p)| {
            let q = b.get_pixel(*x, *y);
            (0..3).any(|c| p.0[c].abs_diff(q.0[c]) > tolerance)
        })
        .map(|(x, y, _)| (x, y))
        .collect()
}

fn frames_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Each frame of `--animate` (direct light: shadow maps and G-buffer follow the block) is the
/// still image of the block placed at that frame's pose; the frames differ where the block and
/// its shadow moved, never on the ceiling; the GIF holds them all.
#[test]
fn animated_frames_are_the_stills_of_each_pose() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene_dir, out) = (tmp.path().join("scene"), tmp.path().join("frames"));
    std::fs::create_dir(&scene_dir).unwrap();
    let scene = block_scene(&scene_dir, [100.0, 0.0, 150.0], 30.0, SLIDE);
    let o = cssm(&[
        "render",
        scene.to_str().unwrap(),
        "--method",
        "direct",
        "--animate",
        "--frames",
        "3",
        "--shadow-resolution",
        "256",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("3 frames over 3 s"), "{}", stderr(&o));
    assert_eq!(
        frames_in(&out),
        [
            "animation.gif",
            "frame-0000.png",
            "frame-0001.png",
            "frame-0002.png"
        ]
    );
    let frames: Vec<_> = (0..3)
        .map(|i| rgba(&out.join(format!("frame-{i:04}.png"))))
        .collect();
    assert!(frames.iter().all(|f| f.dimensions() == (32, 24)));

    // Frame i is at i s: x = 100 + 100 i, turned 30 + 20 i degrees (slerp about one axis).
    for (i, frame) in frames.iter().enumerate() {
        let still_dir = tmp.path().join(format!("still-{i}"));
        std::fs::create_dir(&still_dir).unwrap();
        let x = 100.0 + 100.0 * i as f32;
        let still_scene = block_scene(&still_dir, [x, 0.0, 150.0], 30.0 + 20.0 * i as f32, "");
        let png = tmp.path().join(format!("still-{i}.png"));
        let o = cssm(&[
            "render",
            still_scene.to_str().unwrap(),
            "--method",
            "direct",
            "--shadow-resolution",
            "256",
            "--out",
            png.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let off = differing(frame, &rgba(&png), 8);
        assert!(
            off.len() <= 4,
            "frame {i} differs from the still at its pose in {} pixels: {off:?}",
            off.len()
        );
    }
    for (a, b) in [(0, 1), (1, 2), (0, 2)] {
        let moved = differing(&frames[a], &frames[b], 8);
        assert!(
            moved.len() >= 10,
            "frames {a} and {b} differ in only {} pixels",
            moved.len()
        );
        // The block stands on the floor: the ceiling (the top fifth) does not change.
        assert!(
            moved.iter().all(|&(_, y)| y >= 24 / 5),
            "frames {a} and {b} differ on the ceiling: {moved:?}"
        );
    }

    // The GIF: three 32x24 frames, looping, a second each.
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options
        .read_info(std::fs::File::open(out.join("animation.gif")).unwrap())
        .unwrap();
    assert_eq!((decoder.width(), decoder.height()), (32, 24));
    let mut delays = Vec::new();
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        delays.push(frame.delay);
    }
    assert_eq!(delays, [100, 100, 100]);

    // Again into the same directory: refused without --overwrite, the frames untouched.
    let before = std::fs::read(out.join("frame-0001.png")).unwrap();
    let again = [
        "render",
        scene.to_str().unwrap(),
        "--method",
        "direct",
        "--animate",
        "--frames",
        "2",
        "--duration",
        "1.5",
        "--shadow-resolution",
        "256",
        "--out",
        out.to_str().unwrap(),
    ];
    let o = cssm(&again);
    assert_fails(
        &o,
        "frame-0000.png exists (and 2 more of this animation's files)",
    );
    assert!(stderr(&o).contains("--overwrite"), "{}", stderr(&o));
    assert_eq!(std::fs::read(out.join("frame-0001.png")).unwrap(), before);
    // With --overwrite: frame 1 is now at 0.75 s; the stale frame 2 is named in a warning.
    let o = cssm(&[&again[..], &["--overwrite", "--no-gif"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("1 later frame(s) from an earlier render, from frame-0002.png"),
        "{}",
        stderr(&o)
    );
    assert_ne!(std::fs::read(out.join("frame-0001.png")).unwrap(), before);
    assert!(
        frames_in(&out).iter().all(|n| !n.starts_with('.')),
        "a temporary file was left: {:?}",
        frames_in(&out)
    );
}

/// `--method lightcuts` with the scene's `.cssm` (its block's coherent shadow map moving with
/// it, §3.3), one renderer over every frame; and the default spin of a scene without an
/// animation.
#[test]
fn lightcuts_frames_with_a_cssm_and_the_default_spin() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene_dir, out) = (tmp.path().join("scene"), tmp.path().join("frames"));
    std::fs::create_dir(&scene_dir).unwrap();
    let scene = block_scene(&scene_dir, [100.0, 0.0, 150.0], 30.0, SLIDE);
    let file = tmp.path().join("block.cssm");
    let o = cssm(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        file.to_str().unwrap(),
        "--atlas",
        "32",
        "--cube",
        "8",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = cssm(&[
        "render",
        scene.to_str().unwrap(),
        "--cssm",
        file.to_str().unwrap(),
        "--method",
        "lightcuts",
        "--animate",
        "--frames",
        "3",
        "--shadow-resolution",
        "256",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let frames: Vec<_> = (0..3)
        .map(|i| rgba(&out.join(format!("frame-{i:04}.png"))))
        .collect();
    for (a, b) in [(0, 1), (1, 2)] {
        let moved = differing(&frames[a], &frames[b], 8);
        assert!(
            moved.len() >= 10,
            "lightcuts frames {a} and {b} differ in only {} pixels",
            moved.len()
        );
    }

    // No [objects.animation]: the block turns about its vertical axis through its centre,
    // a full turn in 4 s; frame 1 is at 0.5 s, an eighth of a turn.
    let spin_dir = tmp.path().join("spin");
    std::fs::create_dir(&spin_dir).unwrap();
    let spin_scene = block_scene(&spin_dir, [200.0, 0.0, 150.0], 30.0, "");
    let spin_out = tmp.path().join("spin-frames");
    let o = cssm(&[
        "render",
        spin_scene.to_str().unwrap(),
        "--method",
        "direct",
        "--animate",
        "--fps",
        "2",
        "--duration",
        "1",
        "--shadow-resolution",
        "256",
        "--out",
        spin_out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("turning about the camera's up") && stderr(&o).contains("2 frames"),
        "{}",
        stderr(&o)
    );
    let (a, b) = (
        rgba(&spin_out.join("frame-0000.png")),
        rgba(&spin_out.join("frame-0001.png")),
    );
    // 45 degrees about its centre: its silhouette and shadow change, the ceiling does not.
    let turned = differing(&a, &b, 8);
    assert!(turned.len() >= 3, "the spin changed only {turned:?}");
    assert!(turned.iter().all(|&(_, y)| y >= 24 / 5), "{turned:?}");
}

/// Bad keyframes, flags that do not go together, a scene with nothing to move: exit status 2,
/// a message naming the problem, nothing written.
#[test]
fn bad_animations_and_flags_are_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("frames");
    let o_str = out.to_str().unwrap();
    let bad = |name: &str, animation: &str| -> PathBuf {
        let dir = tmp.path().join(name);
        std::fs::create_dir(&dir).unwrap();
        block_scene(&dir, [100.0, 0.0, 150.0], 0.0, animation)
    };
    let unsorted = bad(
        "unsorted",
        "keyframes = [{ time = 2.0 }, { time = 1.0, translation = [300.0, 0.0, 150.0] }]",
    );
    let render = |scene: &Path, extra: &[&str]| {
        let mut args = vec![
            "render",
            scene.to_str().unwrap(),
            "--method",
            "direct",
            "--animate",
            "--out",
            o_str,
        ];
        args.extend(extra);
        cssm(&args)
    };
    let o = render(&unsorted, &["--frames", "3"]);
    assert_fails(&o, "scene.toml");
    assert_fails(
        &o,
        "object `block`: animation: keyframes[1] (time 1): times must increase strictly",
    );
    let empty = bad("empty", "keyframes = []");
    assert_fails(&render(&empty, &[]), "keyframes is empty");
    let nan = bad(
        "nan",
        "keyframes = [{ time = 0.0 }, { time = 1.0, rotation_deg = [0.0, nan, 0.0] }]",
    );
    assert_fails(&render(&nan, &[]), "rotation_deg must be finite");
    let unknown = bad(
        "unknown",
        "keyframes = [{ time = 0.0 }, { time = 1.0 }]\nloop = true",
    );
    assert_fails(&render(&unknown, &[]), "loop");
    assert!(!out.exists(), "a failed render created {}", out.display());

    let good = bad("good", SLIDE);
    let e = render(&good, &["--frames", "3", "--fps", "2", "--duration", "1"]);
    assert_fails(&e, "at most two of --frames, --fps and --duration");
    assert_fails(&render(&good, &["--fps", "5000"]), "out of range 1..=4096");
    assert_fails(&render(&good, &["--fps", "0"]), "0 is not above 0");
    assert_fails(
        &render(&good, &["--exr", "x.exr"]),
        "--exr is for one image",
    );
    let no_out = cssm(&["render", good.to_str().unwrap(), "--animate"]);
    assert_fails(&no_out, "give --out DIR");
    let o = cssm(&["render", good.to_str().unwrap(), "--fps", "3"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--animate"), "{}", stderr(&o));
    let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    assert_fails(&render(&cornell, &[]), "no [[objects]] entry to move");
    let reference = cssm(&[
        "render",
        good.to_str().unwrap(),
        "--method",
        "reference",
        "--animate",
        "--out",
        o_str,
    ]);
    assert_fails(&reference, "--animate renders on the GPU");
    assert!(!out.exists(), "a failed render created {}", out.display());

    // A script that steps the animation of a scene with nothing to move: refused before a
    // window opens, naming the script's line.
    let script = tmp.path().join("step.txt");
    std::fs::write(&script, "wait 1\nanimate 0.5\n").unwrap();
    let o = cssm(&[
        "view",
        cornell.to_str().unwrap(),
        "--script",
        script.to_str().unwrap(),
    ]);
    assert_fails(&o, &format!("{}:2: ", script.display()));
    assert_fails(&o, "no [[objects]] entry to move");

    // --out naming a file.
    std::fs::write(&out, b"not a directory").unwrap();
    assert_fails(&render(&good, &["--frames", "1"]), "this is a file");
    assert_eq!(std::fs::read(&out).unwrap(), b"not a directory");
}

/// `cssm render --time T` is frame `T / (duration / frames)` of `--animate`: the same poses,
/// the same pixels.
#[test]
fn render_at_a_time_is_that_frame_of_the_animation() {
    let tmp = tempfile::tempdir().unwrap();
    let scene_dir = tmp.path().join("scene");
    std::fs::create_dir(&scene_dir).unwrap();
    let scene = block_scene(&scene_dir, [100.0, 0.0, 150.0], 30.0, SLIDE);
    let s = scene.to_str().unwrap();
    let common = ["--method", "direct", "--shadow-resolution", "256"];
    let frames = tmp.path().join("frames");
    let o = cssm(
        &[
            &["render", s, "--animate", "--frames", "3", "--no-gif"][..],
            &common,
            &["--out", frames.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let at = tmp.path().join("at-2.png");
    let o = cssm(
        &[
            &["render", s, "--time", "2"][..],
            &common,
            &["--out", at.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let frame = rgba(&frames.join("frame-0002.png"));
    assert!(differing(&rgba(&at), &frame, 0).is_empty());
    assert!(!differing(&rgba(&frames.join("frame-0000.png")), &frame, 8).is_empty());
    let o = cssm(&["render", s, "--time", "2", "--animate", "--out", "x"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// Runs `command` to its end, or kills it after two minutes and fails.
fn run_bounded(mut command: Command) -> Output {
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
            panic!("{command:?} did not end within 2 minutes: {}", stderr(&out));
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().expect("wait for cssm")
}

/// The `cssm render` flags `cssm view` printed for its screenshot `shot`, less `--out SHOT`.
fn printed_render_flags(stderr: &str, shot: &Path) -> Vec<String> {
    let prefix = format!("render flags for {}: ", shot.display());
    let line = stderr
        .lines()
        .find_map(|l| l.strip_prefix(&prefix))
        .unwrap_or_else(|| panic!("no '{prefix}' line in:\n{stderr}"));
    let mut flags: Vec<String> = line.split_whitespace().map(str::to_string).collect();
    assert_eq!(flags.pop().as_deref(), shot.to_str(), "{line}");
    assert_eq!(flags.pop().as_deref(), Some("--out"), "{line}");
    flags
}

/// `cssm view` under Xvfb (`apt-get install xvfb xauth`; fails without it): a script steps the
/// animation exactly (`animate 1`), and P plays and pauses it at the frame time; each
/// screenshot is what `cssm render` writes with the flags the window printed (`--time`).
#[test]
fn view_plays_and_steps_the_animation() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let scene_dir = d.join("scene");
    std::fs::create_dir(&scene_dir).unwrap();
    let scene = block_scene(&scene_dir, [100.0, 0.0, 150.0], 30.0, SLIDE);
    let (stepped, played) = (d.join("stepped.png"), d.join("played.png"));
    let script = d.join("play.txt");
    std::fs::write(
        &script,
        format!(
            "screenshot {still}\nanimate 1\nscreenshot {stepped}\nkey p\nwait 3\nkey p\n\
             screenshot {played}\nquit\n",
            still = d.join("still.png").display(),
            stepped = stepped.display(),
            played = played.display(),
        ),
    )
    .unwrap();
    let mut view = Command::new("xvfb-run");
    view.arg("-a")
        .arg(env!("CARGO_BIN_EXE_cssm"))
        .arg("view")
        .arg(&scene)
        .args([
            "--method",
            "direct",
            "--size",
            "32x24",
            "--shadow-resolution",
            "256",
            "--script",
        ])
        .arg(&script);
    let out = run_bounded(view);
    let text = stderr(&out);
    assert!(out.status.success(), "cssm view: {text}");
    assert!(
        text.contains("playing (P pauses)") && text.contains("paused (P plays)"),
        "{text}"
    );
    let still_flags = printed_render_flags(&text, &d.join("still.png"));
    assert!(
        !still_flags.iter().any(|f| f.starts_with("--time")),
        "{still_flags:?}"
    );
    let flags = printed_render_flags(&text, &stepped);
    assert!(flags.contains(&"--time=1".to_string()), "{flags:?}");
    let played_flags = printed_render_flags(&text, &played);
    let time: f32 = played_flags
        .iter()
        .find_map(|f| f.strip_prefix("--time="))
        .unwrap_or_else(|| panic!("{played_flags:?}"))
        .parse()
        .unwrap();
    assert!(time > 1.0, "playing did not move the time on: {time}");
    for (shot, flags, name) in [
        (&stepped, &flags, "render-stepped.png"),
        (&played, &played_flags, "render-played.png"),
    ] {
        let rendered = d.join(name);
        let o = cssm(
            &[
                &["render", scene.to_str().unwrap()][..],
                &flags.iter().map(String::as_str).collect::<Vec<_>>(),
                &["--out", rendered.to_str().unwrap()],
            ]
            .concat(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(
            differing(&rgba(shot), &rgba(&rendered), 0).is_empty(),
            "{}: cssm view's screenshot is not cssm render {flags:?}",
            shot.display()
        );
    }
    // The step moved the block: the image changed.
    let moved = differing(&rgba(&d.join("still.png")), &rgba(&stepped), 8);
    assert!(moved.len() >= 10, "animate 1 changed only {moved:?}");
}
