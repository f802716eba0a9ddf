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
