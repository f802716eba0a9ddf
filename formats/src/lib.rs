//! On-disk formats of the CSSM toolchain.
//!
//! - [`scene`]: scene directories (`scene.toml` + OBJ/MTL, or plain OBJ directories).
//! - [`cssm`]: the `.cssm` container of a baked Coherent Surface Shadow Map.
//! - [`texel`]: the atlas texel table and traversal kinds.
//! - [`hierarchy`]: the median-cut texel hierarchy with bounding spheres and normal cones (§4.2).
//! - [`visibility`]: the CPU reference visibility query over a baked CSSM (§3.2.2).
//! - [`csm`]: the coherent shadow maps of rigid objects and their CPU query (§3.1, §3.3).
#![forbid(unsafe_code)]
#![warn(missing_docs)]

// The unit tests share test files with the integration tests, which name the crate.
#[cfg(test)]
extern crate self as cssm_formats;

pub mod csm;
pub mod cssm;
pub mod cube;
pub mod files;
pub mod hierarchy;
pub mod hull;
pub mod moving;
pub mod scene;
pub mod texel;
pub mod visibility;

pub use cssm::{BakeParams, CssmError, CssmFile, RunData, SceneRef};
pub use hierarchy::{Hierarchy, HierarchyNode};
pub use scene::{
    Camera, LoadOptions, Material, NormalMap, NormalMapKind, ObjectKind, Scene, SceneError,
    SceneObject, SpotLight, TextureSource, hash_hex,
};
pub use texel::{Texel, Traversal};
