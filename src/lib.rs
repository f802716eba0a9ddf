//! `cssm`: bake Coherent Surface Shadow Maps (Ritschel, Grosch, Kautz and Seidel 2008) and
//! query the visibility they store.
//!
//! This facade re-exports the libraries that do the work:
//! - [`formats`]: scenes, the `.cssm` container, the CPU reference visibility query;
//! - [`raycast`]: exact CPU ray casts, surface sampling and the seeded generator (the reference);
//! - [`bake`]: atlas, traversals, depth cube maps, compression, accuracy check;
//! - [`runtime`]: the GPU runtime on wgpu (loaders, visibility queries in WGSL, rendering).
//! - [`report`]: the compression report (`cssm report compression`), measured against the paper,
//!   and the methods' error against the path tracer (`cssm report error`).
//! - [`summary`]: what `cssm bake`, `cssm inspect` and `cssm check` print, as text or JSON.
//!
//! ```no_run
//! use cssm::{bake, formats};
//!
//! let scene = formats::Scene::load(std::path::Path::new("scenes/cornell-box"))?;
//! let baked = bake::bake(&scene, &bake::BakeOptions::default(), &mut |_| {})?;
//! formats::cssm::write_atomic(std::path::Path::new("cornell-box.cssm"), &baked.file)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod builtin;
pub mod report;
pub mod summary;

pub use cssm_bake as bake;
pub use cssm_formats as formats;
pub use cssm_raycast as raycast;
pub use cssm_runtime as runtime;

/// A bake error as the command line says it: a parameter by the flag that sets it (`cssm bake`
/// and `cssm report compression` spell them alike), any other error as the library does.
///
/// ```
/// use cssm::bake::BakeOptions;
///
/// let e = BakeOptions { atlas_resolution: 16, ..Default::default() }.check().unwrap_err();
/// assert_eq!(cssm::flag_error(&e), "--atlas 16 is out of range 32..=1024");
/// ```
pub fn flag_error(e: &bake::BakeError) -> String {
    match e {
        bake::BakeError::Parameter {
            parameter,
            value,
            problem,
        } => {
            let flag = match parameter {
                bake::BakeParameter::AtlasResolution => "--atlas",
                bake::BakeParameter::CubeResolution => "--cube",
                bake::BakeParameter::Near => "--near",
            };
            format!("{flag} {value} {problem}")
        }
        other => other.to_string(),
    }
}

/// `name` (a scene's or a method's) as one safe file-name component: path separators, `:` and
/// control characters become `_`, leading dots are dropped (no hidden file, no `..`), at most
/// 200 bytes are kept, and an empty result is `scene`. Default output names are built from
/// it, so a crafted scene name cannot write outside the directory it is meant for.
///
/// ```
/// assert_eq!(cssm::safe_file_stem("Cornell box"), "Cornell box");
/// assert_eq!(cssm::safe_file_stem("../../etc/passwd"), "_.._etc_passwd");
/// assert_eq!(cssm::safe_file_stem("/abs\u{1b}[31m"), "_abs_[31m");
/// assert_eq!(cssm::safe_file_stem(".."), "scene");
/// assert_eq!(cssm::safe_file_stem(""), "scene");
/// ```
pub fn safe_file_stem(name: &str) -> String {
    let mapped: String = name
        .chars()
        .map(|c| match c {
            '/' | '\\' | ':' => '_',
            c if c.is_control() => '_',
            c => c,
        })
        .collect();
    let mut stem = mapped.trim_start_matches('.').to_string();
    if stem.len() > 200 {
        let mut end = 200;
        while !stem.is_char_boundary(end) {
            end -= 1;
        }
        stem.truncate(end);
    }
    if stem.trim().is_empty() {
        "scene".into()
    } else {
        stem
    }
}

/// `bytes` in binary units (B, KiB, MiB, GiB, TiB) with `decimals` digits after the point;
/// whole bytes below 1 KiB.
///
/// ```
/// assert_eq!(cssm::human_bytes(512, 2), "512 B");
/// assert_eq!(cssm::human_bytes(3 << 20, 1), "3.0 MiB");
/// ```
pub fn human_bytes(bytes: u64, decimals: usize) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.decimals$} {}", UNITS[u])
    }
}
