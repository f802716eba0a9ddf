//! What the tool reads (issue 23): a `.cssm`, scene file or texture that is a FIFO, an endless
//! device or a directory, refused at once and never hanging; files whose sizes or headers would
//! exhaust memory, refused from their first bytes; crafted or foreign `.cssm` contents, refused
//! before a renderer indexes with them.

use super::*;

/// A .cssm input that is a FIFO, a device that never ends (like /dev/zero), or a directory is
/// refused at once with what it is, by every command that reads one; a FIFO neither hangs the
/// tool nor is written to.
#[test]
fn cssm_inputs_that_are_not_regular_files_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fifo(&d.join("pipe.cssm"));
    zero_device(&d.join("zero.cssm"));
    std::fs::create_dir(d.join("folder.cssm")).unwrap();
    let quick = Duration::from_secs(30);
    let scene = cornell();
    let scene = scene.to_str().unwrap();
    for (name, what) in [
        ("pipe.cssm", "FIFO"),
        ("zero.cssm", "character device"),
        ("folder.cssm", "directory"),
    ] {
        let o = run_in(d, &["inspect", name], &[], quick);
        assert_refused(&o, what);
        assert_refused(&o, name);
        let o = run_in(d, &["check", name, "--pairs", "100"], &[], quick);
        assert_refused(&o, what);
        let o = run_in(
            d,
            &[
                "render", scene, "--method", "lightmap", "--cssm", name, "--size", "8x6", "--out",
                "x.png",
            ],
            &[],
            quick,
        );
        assert_refused(&o, what);
        assert!(!d.join("x.png").exists());
    }
    assert!(
        std::fs::symlink_metadata(d.join("pipe.cssm"))
            .unwrap()
            .file_type()
            .is_fifo()
    );
}

/// A scene whose scene.toml, OBJ or MTL is a FIFO or an endless device is refused naming the
/// file and what it is, before anything is baked or written.
#[test]
fn scene_files_that_are_not_regular_files_are_refused_at_once() {
    let quick = Duration::from_secs(30);
    for (file, make, what) in [
        ("scene.toml", fifo as fn(&Path), "FIFO"),
        ("cornell-box.obj", fifo, "FIFO"),
        ("cornell-box.mtl", fifo, "FIFO"),
        ("cornell-box.obj", zero_device, "character device"),
        ("cornell-box.mtl", zero_device, "character device"),
        (
            "cornell-box.obj",
            |p: &Path| std::fs::create_dir(p).unwrap(),
            "directory",
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let scene = cornell_with(dir.path(), file, make);
        let args = bake_args(scene.to_str().unwrap(), "out.cssm");
        let o = run_in(dir.path(), &args, &[], quick);
        assert_refused(&o, what);
        assert_refused(&o, file);
        assert!(!dir.path().join("out.cssm").exists(), "{file} as {what}");
    }
}

/// A texture (map_Kd) that is a FIFO neither hangs the bake nor the render: the bake warns and
/// goes on without it (the bake does not read textures), the render refuses naming the texture.
#[test]
fn a_texture_that_is_a_fifo_does_not_hang() {
    let dir = tempfile::tempdir().unwrap();
    let scene = cornell_named(dir.path(), "cornell-box");
    let mtl = scene.join("cornell-box.mtl");
    let text = std::fs::read_to_string(&mtl).unwrap();
    // The first material gets the texture.
    let at = text.find("newmtl").unwrap();
    let line_end = at + text[at..].find('\n').unwrap() + 1;
    let textured = format!(
        "{}map_Kd pipe.png\n{}",
        &text[..line_end],
        &text[line_end..]
    );
    std::fs::write(&mtl, textured).unwrap();
    fifo(&scene.join("pipe.png"));
    let quick = Duration::from_secs(60);
    let scene = scene.to_str().unwrap();
    let o = run_in(
        dir.path(),
        &[
            "render", scene, "--method", "direct", "--size", "8x6", "--out", "x.png",
        ],
        &[],
        quick,
    );
    assert_refused(&o, "pipe.png");
    assert_refused(&o, "FIFO");
    assert!(!dir.path().join("x.png").exists());
}

/// Files whose sizes would exhaust memory are refused after their first bytes, quickly: a
/// 3 GB foreign file, a 3 GB file with a .cssm header, a header that promises more payload
/// than the file holds, a small payload claiming to inflate to gigabytes (a zstd bomb), and an
/// OBJ of 3 GB.
#[test]
fn huge_or_lying_files_are_refused_from_their_first_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let huge = 3u64 << 30;
    sparse_file(&d.join("foreign.cssm"), b"not a cssm file", huge);
    sparse_file(&d.join("long.cssm"), &cssm_header(1000, 500), huge);
    let mut short = cssm_header(1000, 500);
    short.extend_from_slice(&[0; 100]);
    std::fs::write(d.join("short.cssm"), short).unwrap();
    let mut bomb = cssm_header(6 << 30, 1000);
    bomb.extend_from_slice(&[0; 1000]);
    std::fs::write(d.join("bomb.cssm"), bomb).unwrap();
    let quick = Duration::from_secs(20);
    for (name, needle) in [
        ("foreign.cssm", "not a .cssm file"),
        ("long.cssm", "500"),
        ("short.cssm", "500"),
        ("bomb.cssm", "inflate"),
    ] {
        let start = Instant::now();
        let o = run_in(d, &["inspect", name], &[], quick);
        assert_refused(&o, name);
        assert_refused(&o, needle);
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "{name}: {:?}",
            start.elapsed()
        );
    }
    let scene = cornell_with(d, "cornell-box.obj", |p| sparse_file(p, b"v 0 0 0\n", huge));
    let args = bake_args(scene.to_str().unwrap(), "out.cssm");
    let o = run_in(d, &args, &[], quick);
    assert_refused(&o, "cornell-box.obj");
    assert_refused(&o, "larger than the limit");
}

/// A .cssm whose checksum holds but whose contents index past the scene (a texel's material
/// 99 of the Cornell box's few) is refused by every command that uses it with the scene,
/// naming the texel, before a renderer indexes with it; a file of another scene is refused
/// naming both scenes.
#[test]
fn crafted_or_foreign_cssm_contents_are_refused_before_use() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = cornell();
    let scene = scene.to_str().unwrap();
    let o = run(d, &bake_args(scene, "good.cssm"));
    assert!(o.status.success(), "{}", stderr(&o));
    let mut file = cssm_formats::cssm::read(&d.join("good.cssm")).unwrap();
    file.texels[3].material = 99;
    let bytes = cssm_formats::cssm::encode(&file).unwrap();
    std::fs::write(d.join("crafted.cssm"), bytes).unwrap();
    let o = run(d, &["check", "crafted.cssm", "--pairs", "100"]);
    assert_refused(&o, "texel 3 has material 99");
    let o = run(
        d,
        &[
            "render",
            scene,
            "--method",
            "lightmap",
            "--cssm",
            "crafted.cssm",
            "--size",
            "8x6",
            "--out",
            "x.png",
        ],
    );
    assert_refused(&o, "texel 3 has material 99");
    assert!(!d.join("x.png").exists());

    let other = cornell_named(d, "another-box");
    let o = run(
        d,
        &[
            "check",
            "good.cssm",
            "--scene",
            other.to_str().unwrap(),
            "--pairs",
            "100",
        ],
    );
    assert_refused(&o, "baked from the scene 'cornell-box'");
    assert_refused(&o, "'another-box'");
}
