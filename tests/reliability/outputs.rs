//! Where the tool writes (issue 23): output paths that are not regular files, outputs onto the
//! command's own inputs, crafted scene names steering the default output, names too long for the
//! file system, stale temporary files of killed writes, and bakes killed mid-write.

use super::*;

/// Output paths that are not regular files are refused before any work and left as they were:
/// a character device, a FIFO (which must not hang the tool either), a directory, a link to
/// nothing, a link to a device. A link to a regular file is written through: the file gets the
/// bake, the link stays a link.
#[test]
fn outputs_that_are_not_regular_files_are_refused_and_kept() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = cornell();
    let scene = scene.to_str().unwrap();

    // A character device of our own (the null device's numbers), inside the temporary directory.
    let null = d.join("null");
    let made = Command::new("mknod")
        .args([null.to_str().unwrap(), "c", "1", "3"])
        .status()
        .expect("mknod");
    assert!(made.success(), "mknod needs root (the tests run as root)");
    let o = run(d, &bake_args(scene, null.to_str().unwrap()));
    assert_refused(&o, "character device");
    assert!(
        std::fs::symlink_metadata(&null)
            .unwrap()
            .file_type()
            .is_char_device()
    );

    let fifo = d.join("pipe");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let o = run(d, &bake_args(scene, fifo.to_str().unwrap()));
    assert_refused(&o, "FIFO");
    assert!(
        std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo()
    );

    let folder = d.join("folder.cssm");
    std::fs::create_dir(&folder).unwrap();
    let o = run(d, &bake_args(scene, folder.to_str().unwrap()));
    assert_refused(&o, "directory");
    assert!(folder.is_dir());

    let dangling = d.join("dangling.cssm");
    std::os::unix::fs::symlink(d.join("nowhere/x.cssm"), &dangling).unwrap();
    let o = run(d, &bake_args(scene, dangling.to_str().unwrap()));
    assert_refused(&o, "symbolic link");
    assert!(
        std::fs::symlink_metadata(&dangling)
            .unwrap()
            .file_type()
            .is_symlink()
    );

    let to_device = d.join("to-device.cssm");
    std::os::unix::fs::symlink(&null, &to_device).unwrap();
    let o = run(d, &bake_args(scene, to_device.to_str().unwrap()));
    assert_refused(&o, "character device");
    assert!(
        std::fs::symlink_metadata(&null)
            .unwrap()
            .file_type()
            .is_char_device()
    );

    // Render outputs go through the same check.
    let o = run(
        d,
        &["render", "--size", "8x6", "--out", null.to_str().unwrap()],
    );
    assert_refused(&o, "character device");
    assert!(
        std::fs::symlink_metadata(&null)
            .unwrap()
            .file_type()
            .is_char_device()
    );

    // A link to a regular file: written through, the link kept.
    let real = d.join("real.cssm");
    std::fs::write(&real, b"old").unwrap();
    let link = d.join("link.cssm");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let o = run(d, &bake_args(scene, link.to_str().unwrap()));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_ne!(std::fs::read(&real).unwrap(), b"old");
    let o = run(d, &["inspect", real.to_str().unwrap()]);
    assert!(
        o.status.success(),
        "the link's target holds the bake: {}",
        stderr(&o)
    );
}

/// A command never writes onto one of its own inputs: `bake -o` the scene's OBJ or MTL (by any
/// path: a link, `..`), `render --out` the `.cssm` it reads or the scene's OBJ, and `--out` and
/// `--exr` naming one file. The inputs are unchanged.
#[test]
fn outputs_never_replace_the_commands_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = cornell_named(d, "Cornell box");
    let obj = scene.join("cornell-box.obj");
    let obj_bytes = std::fs::read(&obj).unwrap();
    let s = scene.to_str().unwrap();

    let o = run(d, &bake_args(s, obj.to_str().unwrap()));
    assert_refused(&o, "which this command reads");
    let roundabout = scene.join("..").join("scene").join("cornell-box.obj");
    let o = run(d, &bake_args(s, roundabout.to_str().unwrap()));
    assert_refused(&o, "which this command reads");
    let link = d.join("obj-link");
    std::os::unix::fs::symlink(&obj, &link).unwrap();
    let o = run(d, &bake_args(s, link.to_str().unwrap()));
    assert_refused(&o, "which this command reads");
    let mtl = std::fs::read_dir(&scene)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "mtl"))
        .expect("the Cornell box has an MTL");
    let o = run(d, &bake_args(s, mtl.to_str().unwrap()));
    assert_refused(&o, "which this command reads");
    assert_eq!(std::fs::read(&obj).unwrap(), obj_bytes);

    let baked = d.join("box.cssm");
    let o = run(d, &bake_args(s, baked.to_str().unwrap()));
    assert!(o.status.success(), "{}", stderr(&o));
    let cssm_bytes = std::fs::read(&baked).unwrap();
    let b = baked.to_str().unwrap();
    let o = run(
        d,
        &[
            "render", s, "--cssm", b, "--method", "lightmap", "--size", "8x6", "--out", b,
        ],
    );
    assert_refused(&o, "which this command reads");
    let o = run(
        d,
        &["render", s, "--size", "8x6", "--out", obj.to_str().unwrap()],
    );
    assert_refused(&o, "which this command reads");
    assert_eq!(std::fs::read(&baked).unwrap(), cssm_bytes);
    assert_eq!(std::fs::read(&obj).unwrap(), obj_bytes);

    let image = d.join("image.png");
    let i = image.to_str().unwrap();
    let o = run(d, &["render", s, "--size", "8x6", "--out", i, "--exr", i]);
    assert_refused(&o, "the same file");
    assert!(!image.exists());
}

/// The default output name comes from the scene's name as one safe file name in the current
/// directory: `../` and absolute names cannot write elsewhere, an empty name does not make a
/// hidden `.cssm`; a name with a terminal escape is refused with a message that carries no
/// escape.
#[test]
fn scene_names_cannot_steer_the_default_output() {
    let dir = tempfile::tempdir().unwrap();
    for (name, expected) in [
        ("../../escaped", "_.._escaped.cssm"),
        ("/tmp/absolute", "_tmp_absolute.cssm"),
        ("", "scene.cssm"),
        ("..", "scene.cssm"),
    ] {
        let case = dir.path().join(format!("case-{}", expected.len()));
        let work = case.join("work");
        std::fs::create_dir_all(&work).unwrap();
        let scene = cornell_named(&case, name);
        let o = run(
            &work,
            &[
                "bake",
                scene.to_str().unwrap(),
                "--atlas",
                "32",
                "--cube",
                "8",
            ],
        );
        assert!(o.status.success(), "{name:?}: {}", stderr(&o));
        assert_eq!(names_in(&work), vec![expected.to_string()], "{name:?}");
        assert_eq!(
            names_in(&case),
            vec!["scene", "work"],
            "{name:?} wrote beside"
        );
    }

    let case = dir.path().join("escape");
    let scene = cornell_named(&case, "box\u{1b}]0;pwned\u{7}");
    let o = run(&case, &["bake", scene.to_str().unwrap()]);
    assert_refused(&o, "control character U+001B");
    assert!(
        !stderr(&o).contains('\u{1b}'),
        "an escape reached the terminal"
    );
    assert_eq!(names_in(&case), vec!["scene"]);
}

/// An output name longer than a file system takes fails before the bake, not after it.
#[test]
fn an_overlong_output_name_fails_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let long = dir.path().join(format!("{}.cssm", "x".repeat(250)));
    let scene = cornell();
    let start = Instant::now();
    // A bake that would take many seconds: the refusal must come first.
    let o = run(
        dir.path(),
        &[
            "bake",
            scene.to_str().unwrap(),
            "-o",
            long.to_str().unwrap(),
            "--atlas",
            "512",
            "--cube",
            "64",
        ],
    );
    assert_refused(&o, "bytes long");
    assert!(
        start.elapsed() < Duration::from_secs(10),
        "refused only after {:?}",
        start.elapsed()
    );
    assert!(names_in(dir.path()).is_empty());
}

/// Temporary files that earlier versions left when killed (`.NAME.tmp-PID`, PID no longer
/// running) are removed by the next write of NAME; one whose process still runs is kept.
#[test]
fn stale_temporary_files_are_cleaned() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // PIDs are below 2^22 on Linux.
    let stale = d.join(".out.cssm.tmp-4194305");
    let alive = d.join(format!(".out.cssm.tmp-{}", std::process::id()));
    let other = d.join(".other.cssm.tmp-4194305");
    for p in [&stale, &alive, &other] {
        std::fs::write(p, b"half a file").unwrap();
    }
    let scene = cornell();
    let out = d.join("out.cssm");
    let o = run(
        d,
        &bake_args(scene.to_str().unwrap(), out.to_str().unwrap()),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stale.exists(), "the stale temporary file survived");
    assert!(alive.exists() && other.exists());
}

/// A bake killed at any point leaves the old file intact and no other file beside it (the
/// temporary file has no name until the rename); a render leaves no directory of its own in
/// the temporary directory.
#[test]
fn killed_bakes_leave_the_old_file_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = cornell();
    let out = d.join("kept.cssm");
    let args = [
        "bake",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--atlas",
        "32",
        "--cube",
        "8",
    ];
    let o = run(d, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let old = std::fs::read(&out).unwrap();
    // A bigger bake, killed at points spread over its run (about 2 s on two cores).
    let big = [
        "bake",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--atlas",
        "128",
        "--cube",
        "32",
    ];
    for delay_ms in [50u64, 300, 800, 1500, 2500] {
        let mut child = Command::new(cssm_binary())
            .args(big)
            .current_dir(d)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(delay_ms));
        let _ = child.kill();
        let finished = child.wait().unwrap().success();
        let now = std::fs::read(&out).unwrap();
        assert!(
            finished || now == old,
            "killed after {delay_ms} ms, the old file changed"
        );
        assert_eq!(names_in(d), vec!["kept.cssm"], "killed after {delay_ms} ms");
        if finished {
            break;
        }
    }

    let tmp = tempfile::tempdir().unwrap();
    let image = d.join("image.png");
    let o = run_in(
        d,
        &["render", "--size", "8x6", "--out", image.to_str().unwrap()],
        &[
            ("TMPDIR", tmp.path().to_str().unwrap()),
            ("XDG_RUNTIME_DIR", ""),
        ],
        Duration::from_secs(120),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        names_in(tmp.path()).is_empty(),
        "left {:?}",
        names_in(tmp.path())
    );
}
