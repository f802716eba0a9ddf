//! `cssm`: bake Coherent Surface Shadow Maps (Ritschel, Grosch, Kautz and Seidel 2008) and
//! query the visibility they store.
//!
//! This facade re-exports the libraries that do the work:
//! - [`formats`]: scenes, the `.cssm` container, the CPU reference visibility query;
//! - [`bake`]: atlas, traversals, depth cube maps, compression, accuracy check;
//! - [`runtime`]: the GPU runtime on wgpu (loaders, visibility queries in WGSL, rendering).
//! - [`report`]: the compression report (`cssm report compression`), measured against the paper.
//!
//! ```no_run
//! use cssm::{bake, formats};
//!
//! let scene = formats::Scene::load(std::path::Path::new("scenes/cornell-box"))?;
//! let baked = bake::bake(&scene, &bake::BakeOptions::default(), &mut |_, _| {})?;
//! formats::cssm::write_atomic(std::path::Path::new("cornell-box.cssm"), &baked.file)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod builtin;
pub mod report;

pub use cssm_bake as bake;
pub use cssm_formats as formats;
pub use cssm_runtime as runtime;
