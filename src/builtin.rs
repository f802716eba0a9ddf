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

/// Directory of the built-in Cornell box, extracting it if this is not a source checkout.
pub fn cornell_box() -> std::io::Result<PathBuf> {
    let checkout = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    if checkout.join("scene.toml").is_file() {
        return Ok(checkout);
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
        .unwrap_or_else(std::env::temp_dir);
    let dir = base
        .join(format!("cssm-{}", env!("CARGO_PKG_VERSION")))
        .join("cornell-box");
    std::fs::create_dir_all(&dir)?;
    for (name, contents) in CORNELL_BOX {
        let path = dir.join(name);
        if std::fs::read_to_string(&path).ok().as_deref() != Some(*contents) {
            std::fs::write(&path, contents)?;
        }
    }
    Ok(dir)
}
