//! The engine of `cssm report error` and `cssm compare`: the methods rendered and measured
//! against the reference path tracer, their files written. The figures and the files' text are
//! [`crate::report`]'s ([`crate::report::error`], [`crate::report::compare`] and their writers);
//! this module renders and runs.
//!
//! - here: what a run takes from the program that starts it ([`Host`]: its built-in scenes, its
//!   scene loading and its in-memory bake, each with that program's progress display), one
//!   `--method` variant ([`Variant`], which the command line parses), the scenes loaded and the
//!   output directory checked;
//! - [`reference`](mod@reference): the reference path tracer's image in two independent
//!   halves, its noise measured, cached beside the report by the scene's content and the
//!   settings;
//! - [`render`]: one variant's image with its GPU milliseconds per pass and the GPU memory its
//!   renderer holds;
//! - [`error_run`]: `cssm report error`'s run (error.md, error.csv, the images and strips);
//! - [`compare_run`]: `cssm compare`'s run (the page, its chart, CSV, JSON and Markdown).

use std::path::{Path, PathBuf};

use cssm_bake::{BakeError, BakeOptions, Baked};
use cssm_formats::Scene;
use cssm_runtime::method::{MethodEntry, OptionValues, Resolved};

pub mod compare_run;
pub mod error_run;
pub mod reference;
pub mod render;

pub use compare_run::CompareConfig;
pub use error_run::ErrorConfig;
pub use reference::{Reference, ReferenceFiles, ReferenceSpec, reference_image};
pub use render::{GpuTimes, RenderSpec, Rendered, render_variant};

/// What a run takes from the program that starts it (the `cssm` command): the scenes it
/// measures when given none, and how a scene is loaded and baked, with the messages and
/// progress display that program shows for them.
pub trait Host {
    /// Directories of the scenes measured when none is given.
    ///
    /// # Errors
    /// A built-in scene that cannot be prepared.
    fn builtin_scenes(&self) -> std::io::Result<Vec<PathBuf>>;

    /// The scene at `dir`, loaded (its warnings told as the program tells them).
    ///
    /// # Errors
    /// A scene that cannot be loaded, as a message.
    fn load_scene(&self, dir: &Path) -> Result<Scene, String>;

    /// `scene` baked in memory with `options`, its file checked as a written one is: a render
    /// must not trust what a `.cssm` read from disk would not be trusted with.
    ///
    /// # Errors
    /// The bake's.
    fn bake(&self, scene: &Scene, options: &BakeOptions) -> Result<Baked, BakeError>;
}

/// One method variant of a run (a `--method` of `cssm report error`, one of `cssm compare
/// --methods`), checked by the method table.
pub struct Variant {
    /// The spec as the user wrote it, spaces trimmed (`lightcuts:bounces=2`).
    pub spec: String,
    /// The method.
    pub method: &'static MethodEntry,
    /// The options the spec set, and `--bounces` / `--samples` where it did not.
    pub values: OptionValues,
    /// Every option of the method, checked.
    pub resolved: Resolved,
}

/// The scenes in `dirs`, loaded by `host`; none: the host's built-in scenes. Two scenes of one
/// name are refused (a report's file names are the scenes').
///
/// # Errors
/// A scene that cannot be prepared or loaded, two scenes of one name.
pub fn load_scenes(dirs: &[PathBuf], host: &dyn Host) -> Result<Vec<Scene>, String> {
    let dirs = if dirs.is_empty() {
        host.builtin_scenes()
            .map_err(|e| format!("cannot prepare the built-in scenes: {e}"))?
    } else {
        dirs.to_vec()
    };
    let scenes = dirs
        .iter()
        .map(|d| host.load_scene(d))
        .collect::<Result<Vec<_>, _>>()?;
    for (i, s) in scenes.iter().enumerate() {
        if let Some(other) = scenes[..i].iter().find(|o| o.name == s.name) {
            return Err(format!(
                "{} and {} are both named '{}': the report's file names would clash",
                other.path.display(),
                s.path.display(),
                s.name
            ));
        }
    }
    Ok(scenes)
}

/// Refuses an `--out` directory that exists as something else (a report never replaces a
/// file of the user's with a directory).
///
/// # Errors
/// `out` exists and is not a directory.
pub fn check_out_dir(out: &Path) -> Result<(), String> {
    if out.exists() && !out.is_dir() {
        return Err(format!(
            "--out {}: exists and is not a directory",
            out.display()
        ));
    }
    Ok(())
}

/// `name` inside the `--out` directory `out`, never through a link planted there
/// ([`cssm_formats::files::output_in`]; with `directory`,
/// [`cssm_formats::files::output_dir_in`]).
///
/// # Errors
/// What those refuse, naming `--out`.
pub fn output(out: &Path, name: &str, directory: bool) -> Result<PathBuf, String> {
    let path = if directory {
        cssm_formats::files::output_dir_in(out, name)
    } else {
        cssm_formats::files::output_in(out, name)
    };
    path.map_err(|e| format!("--out: {e}"))
}

/// Writes `text` with the project's atomic write (never a half-written file).
///
/// # Errors
/// A failed write, naming `path`.
pub fn write_text(path: &Path, text: &str) -> Result<(), String> {
    cssm_formats::cssm::write_bytes_atomic(path, text.as_bytes()).map_err(|e| e.to_string())
}

/// A progress bar of `rows` image rows on stderr.
fn rows_bar(rows: u64, message: String) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(rows);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg} [{bar:32}] {pos}/{len} rows, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(message);
    bar
}
