//! Geometry the bake must take or refuse in words (issue 53, classes 1 and 3): single charts of
//! any shape on the atlas page, scenes of more separate pieces than the atlas stage takes, and
//! moving objects placed far beyond the scene.

use super::*;

/// Writes an OBJ of the triangles `faces` (1-based indices into `vertices`) to `dir/name`.
fn write_obj(dir: &Path, name: &str, vertices: &[[f32; 3]], faces: &[[u32; 3]]) -> PathBuf {
    let mut text = String::new();
    for v in vertices {
        text += &format!("v {} {} {}\n", v[0], v[1], v[2]);
    }
    for f in faces {
        text += &format!("f {} {} {}\n", f[0], f[1], f[2]);
    }
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join(name), text).unwrap();
    dir.to_path_buf()
}

/// A 20x10 floor with a 1 m cube standing on it, one OBJ, no scene.toml.
fn floor_and_cube(dir: &Path) -> PathBuf {
    let mut vertices = vec![
        [-10.0, 0.0, -5.0],
        [10.0, 0.0, -5.0],
        [10.0, 0.0, 5.0],
        [-10.0, 0.0, 5.0],
    ];
    let mut faces = vec![[1, 3, 2], [1, 4, 3]];
    // The cube's corners: bit 0 x, bit 1 y, bit 2 z.
    for k in 0..8 {
        let bit = |b: u32, lo: f32, hi: f32| if k & (1 << b) != 0 { hi } else { lo };
        vertices.push([bit(0, -0.5, 0.5), bit(1, 0.0, 1.0), bit(2, -0.5, 0.5)]);
    }
    // Each side as a quad of corner numbers, counter-clockwise seen from outside.
    let sides = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    for [a, b, c, d] in sides.map(|s| s.map(|i: u32| i + 5)) {
        faces.extend([[a, b, c], [a, c, d]]);
    }
    write_obj(dir, "floor-cube.obj", &vertices, &faces)
}

/// Every single chart that is not square (a long floor with a cube, one triangle, a 2x1
/// rectangle, a trapezoid) failed to bake with the default options: xatlas put the chart on a
/// page grown around it, and the bake's file then failed its own check ("lies off the 64x64
/// atlas"). They bake with no options now, and the floor and cube render with a method that
/// bakes in memory.
#[test]
fn single_chart_scenes_bake_and_render_with_defaults() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let floor = floor_and_cube(&d.join("floor"));
    let triangle = write_obj(
        &d.join("triangle"),
        "t.obj",
        &[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        &[[1, 3, 2]],
    );
    let rectangle = [
        [0.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
    ];
    let rectangle_dir = write_obj(
        &d.join("rectangle"),
        "r.obj",
        &rectangle,
        &[[1, 4, 3], [1, 3, 2]],
    );
    let trapezoid = [
        [0.0, 0.0, 0.0],
        [3.0, 0.0, 0.0],
        [2.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
    ];
    let trapezoid_dir = write_obj(
        &d.join("trapezoid"),
        "z.obj",
        &trapezoid,
        &[[1, 4, 3], [1, 3, 2]],
    );
    for scene in [&floor, &triangle, &rectangle_dir, &trapezoid_dir] {
        let o = run(d, &["bake", scene.to_str().unwrap(), "-o", "out.cssm"]);
        assert!(o.status.success(), "{}: {}", scene.display(), stderr(&o));
        let o = run(d, &["inspect", "out.cssm"]);
        assert!(o.status.success(), "{}: {}", scene.display(), stderr(&o));
    }
    // No --cssm: the render bakes in memory, and checks that file as one read from disk.
    let o = run(
        d,
        &[
            "render",
            floor.to_str().unwrap(),
            "--method",
            "lightmap",
            "--size",
            "64x48",
            "--out",
            "lightmap.png",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("lightmap.png").is_file());
}

/// A scene of more separate pieces than the atlas stage takes (20,000 loose quads) made xatlas
/// run for minutes through gigabytes, and under a memory limit write through a failed
/// allocation (SIGSEGV, no message). It is refused at once, in words; so are more pieces than
/// the page has texels.
#[test]
fn scenes_of_too_many_pieces_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let quads = |n: u32| {
        let mut vertices = Vec::new();
        let mut faces = Vec::new();
        for i in 0..n {
            let (x, z) = ((i % 150) as f32 * 2.0, (i / 150) as f32 * 2.0);
            vertices.extend([
                [x, 0.0, z],
                [x + 1.0, 0.0, z],
                [x + 1.0, 0.0, z + 1.0],
                [x, 0.0, z + 1.0],
            ]);
            let b = 4 * i + 1;
            faces.extend([[b, b + 2, b + 1], [b, b + 3, b + 2]]);
        }
        write_obj(
            &d.join(format!("quads-{n}")),
            "quads.obj",
            &vertices,
            &faces,
        )
    };
    let many = quads(20_000);
    let start = Instant::now();
    let o = run_in(
        d,
        &["bake", many.to_str().unwrap(), "-o", "x.cssm"],
        &[],
        Duration::from_secs(60),
    );
    assert_refused(&o, "the scene is 20000 separate pieces of surface");
    assert_refused(&o, "more than the 8192 the atlas stage takes");
    assert!(
        start.elapsed() < Duration::from_secs(20),
        "{:?}",
        start.elapsed()
    );
    let some = quads(1600);
    let o = run(
        d,
        &[
            "bake",
            some.to_str().unwrap(),
            "-o",
            "x.cssm",
            "--atlas",
            "32",
        ],
    );
    assert_refused(
        &o,
        "a 32x32 atlas has 1024 texels: use --atlas 64 or larger",
    );
}

/// `check --place` a moving object 1e24 away panicked inside the ray caster's BVH; at 1e22 it
/// printed an agreement over no pairs without a word. A placement beyond 1000 scene sizes is
/// refused under the option's name.
#[test]
fn placements_far_beyond_the_scene_are_refused_in_words() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let quad = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let scene = write_obj(&d.join("scene"), "quad.obj", &quad, &[[1, 2, 3], [1, 3, 4]]);
    std::fs::write(
        scene.join("scene.toml"),
        "name = \"quad\"\nmesh = \"quad.obj\"\n\n[[objects]]\nname = \"tile\"\nmesh = \"quad.obj\"\n\
         translation = [0.0, 0.0, 1.0]\n",
    )
    .unwrap();
    let o = run(d, &bake_args(scene.to_str().unwrap(), "q.cssm"));
    assert!(o.status.success(), "{}", stderr(&o));
    for x in ["1e22", "1e24", "-3e38"] {
        let place = format!("tile={x},0,0");
        let o = run(
            d,
            &[
                "check",
                "q.cssm",
                "--scene",
                scene.to_str().unwrap(),
                "--place",
                &place,
                "--pairs",
                "1000",
            ],
        );
        assert_refused(&o, "--place: object 'tile' placed");
        assert_refused(&o, "beyond 1000 times the scene's size");
    }
    let o = run(
        d,
        &[
            "check",
            "q.cssm",
            "--scene",
            scene.to_str().unwrap(),
            "--place",
            "tile=0.5,0,2",
            "--pairs",
            "1000",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
}
