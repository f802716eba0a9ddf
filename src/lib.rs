//! `cssm`: bake Coherent Surface Shadow Maps (Ritschel, Grosch, Kautz and Seidel 2008) and
//! query the visibility they store.
//!
//! This facade re-exports the libraries that do the work:
//! - [`formats`]: scenes, the `.cssm` container, the CPU reference visibility query;
//! - [`raycast`]: exact CPU ray casts, surface sampling and the seeded generator (the reference);
//! - [`bake`]: atlas, traversals, depth cube maps, compression, accuracy check;
//! - [`runtime`]: the GPU runtime on wgpu (loaders, visibility queries in WGSL, rendering).
//! - `report` (feature `lab`, on by default): the lab's reports (`cssm_lab::report`): the
//!   compression report measured against the paper, the methods' error against the path tracer,
//!   the comparison page; and `measure` (`cssm_lab::measure`), the engine that renders what
//!   `cssm report error` and `cssm compare` measure;
//! - [`summary`]: what `cssm bake`, `cssm inspect` and `cssm check` print, as text or JSON, and
//!   [`flag_error`], a bake error in the command's flags (`cssm-output`);
//! - [`builtin`]: the built-in scenes.
//!
//! The command's window (feature `viewer`) and the lab (feature `lab`) are on by default; a
//! program that depends on this library with `default-features = false` compiles no windowing,
//! GUI or plotting crate (`scripts/test.sh` holds it to that with `cargo tree`).
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

pub use cssm_bake as bake;
pub use cssm_formats as formats;
pub use cssm_raycast as raycast;
pub use cssm_runtime as runtime;

/// The lab (`cssm-lab`): the reports, the image metrics, the comparison page, the engine that
/// renders what they measure and the diagnostics (feature `lab`).
#[cfg(feature = "lab")]
pub use cssm_lab::{diagnose, measure, report};

pub use cssm_formats::files::{human_bytes, safe_file_stem};
pub use cssm_output::{flag_error, summary};
