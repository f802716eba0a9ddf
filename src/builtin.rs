//! Built-in scenes, embedded so that `cssm bake` with no scene works anywhere.
//!
//! In a source checkout the scene directory of the checkout is used as it is; an installed
//! binary writes the embedded copy to the user's cache directory once and uses that.

use std::path::{Path, PathBuf};

/// The built-in Cornell box: (file name, contents).
const CORNELL_BOX: &[(&str, &str)] = &[
    (
        "scene.toml",
        include_str!("../scenes/cornell-box/scene.toml"),
    ),
    (
        "cornell-box.obj",
        include_str!("../scenes/cornell-box/cornell-box.obj"),
    ),
    (
        "cornell-box.mtl",
        include_str!("../scenes/cornell-box/cornell-box.mtl"),
    ),
];

/// The built-in Cornell box with a glossy floor: (file name, contents).
const CORNELL_GLOSSY: &[(&str, &str)] = &[
    (
        "scene.toml",
        include_str!("../scenes/cornell-glossy/scene.toml"),
    ),
    (
        "cornell-glossy.obj",
        include_str!("../scenes/cornell-glossy/cornell-glossy.obj"),
    ),
    (
        "cornell-glossy.mtl",
        include_str!("../scenes/cornell-glossy/cornell-glossy.mtl"),
    ),
];

/// Directory of the built-in Cornell box, extracting it if this is not a source checkout.
pub fn cornell_box() -> std::io::Result<PathBuf> {
    scene("cornell-box", CORNELL_BOX)
}

/// Directory of the built-in Cornell box with a glossy floor (normalised Phong, Ns = 50),
/// extracting it if this is not a source checkout.
pub fn cornell_glossy() -> std::io::Result<PathBuf> {
    scene("cornell-glossy", CORNELL_GLOSSY)
}

/// `scenes/NAME` of the checkout, else the embedded `files` written to the cache directory.
fn scene(name: &str, files: &[(&str, &str)]) -> std::io::Result<PathBuf> {
    let checkout = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    if checkout.join("scene.toml").is_file() {
        return Ok(checkout);
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(std::env::temp_dir);
    let dir = base
        .join(format!("cssm-{}", env!("CARGO_PKG_VERSION")))
        .join(name);
    std::fs::create_dir_all(&dir)?;
    for (file, contents) in files {
        let path = dir.join(file);
        if std::fs::read_to_string(&path).ok().as_deref() != Some(*contents) {
            std::fs::write(&path, contents)?;
        }
    }
    Ok(dir)
}

/// An axis-aligned cube of side `size` with its lowest corner at `corner`, as OBJ text: eight
/// `v` lines and six quads numbered after `first_vertex` earlier vertices (0 for a file of its
/// own), their normals pointing out of the cube when `outward`, into it otherwise. The rigid
/// block of the moving-object tests and benchmarks.
///
/// ```
/// let obj = cssm::builtin::cube_obj([0.0, 0.0, 0.0], 60.0, 0, false);
/// assert_eq!(obj.lines().filter(|l| l.starts_with("v ")).count(), 8);
/// assert!(obj.contains("f 1 2 3 4"));
/// let appended = cssm::builtin::cube_obj([100.0, 0.0, 0.0], 60.0, 8, true);
/// assert!(appended.contains("f 12 11 10 9"));
/// ```
pub fn cube_obj(corner: [f32; 3], size: f32, first_vertex: usize, outward: bool) -> String {
    let mut obj = String::new();
    for z in [0.0, size] {
        for (x, y) in [(0.0, 0.0), (size, 0.0), (size, size), (0.0, size)] {
            obj += &format!("v {} {} {}\n", corner[0] + x, corner[1] + y, corner[2] + z);
        }
    }
    // Counter-clockwise seen from inside the cube: the normals point into it.
    for f in [
        [1, 2, 3, 4],
        [8, 7, 6, 5],
        [1, 5, 6, 2],
        [2, 6, 7, 3],
        [3, 7, 8, 4],
        [4, 8, 5, 1],
    ] {
        let [a, b, c, d] = f.map(|i| i + first_vertex);
        let [a, b, c, d] = if outward { [d, c, b, a] } else { [a, b, c, d] };
        obj += &format!("f {a} {b} {c} {d}\n");
    }
    obj
}
