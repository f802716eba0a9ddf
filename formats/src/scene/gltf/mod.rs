//! glTF 2.0 loading (`.gltf` with its buffers, or `.glb`): every node of the default scene that
//! holds a mesh becomes an object, its triangles placed by the node's world transform; the
//! metallic-roughness materials become Lambertian plus normalised Phong
//! ([`convert_material`](materials::convert_material)); `KHR_lights_punctual` spot lights become
//! the scene's spot lights ([`convert_light`](Builder::convert_light)) and the first perspective
//! camera its camera. Buffers and images are read here (regular files only, bounded, buffers
//! hashed), and every range the file claims is checked against the bytes it holds before the
//! `gltf` crate's readers see it.
//!
//! [`Builder::add_gltf`] runs the steps in order, one file each: `read.rs` parses the document
//! and reads its buffers (the GLB's binary chunk, data URIs, files), refusing extensions it
//! lacks; `checks.rs` holds what the file is checked for before the crate's parser and readers
//! see it; `materials.rs` turns images into texture sources and materials into this project's;
//! `nodes.rs` walks the node hierarchy and appends each mesh primitive's triangles;
//! `lights.rs` converts the cameras and lights found on the nodes.

use std::path::Path;

use glam::Affine3A;

use crate::scene::{Builder, Camera, Hasher, SceneError, SpotLight, read_bounded};

mod checks;
mod lights;
mod materials;
mod nodes;
mod read;
#[cfg(test)]
pub(crate) mod tests;

use read::{parse_document, read_buffers};

/// What a glTF file brings besides its triangles.
#[derive(Default)]
pub(super) struct GltfExtras {
    /// The first perspective camera of the scene's nodes, if any.
    pub(super) camera: Option<Camera>,
    /// Its spot lights, and point lights turned into spot lights.
    pub(super) lights: Vec<SpotLight>,
}

/// How the triangles of a glTF file become objects.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum GltfObjects {
    /// One static object per node with a mesh (the scene's static part).
    PerNode,
    /// None: the caller makes the whole file one object (a rigid `[[objects]]` entry).
    Whole,
}

fn gltf_error(path: &Path, message: impl Into<String>) -> SceneError {
    SceneError::Gltf {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

impl Builder {
    /// Loads the glTF file `path`, places every mesh node by `placement` after its own world
    /// transform, appends the triangles and, for [`GltfObjects::PerNode`], pushes one static
    /// object per node that kept triangles.
    pub(super) fn add_gltf(
        &mut self,
        path: &Path,
        placement: Affine3A,
        objects: GltfObjects,
        hasher: &mut Hasher,
    ) -> Result<GltfExtras, SceneError> {
        let bytes = read_bounded(path)?;
        hasher.add(path, &bytes);
        let dir = path.parent().unwrap_or(Path::new("."));
        let outside = self.options.files_outside;
        let (document, blob) = parse_document(path, &bytes)?;
        drop(bytes);
        self.check_gltf_extensions(path, &document)?;
        let buffers = read_buffers(path, dir, outside, &document, blob, hasher)?;
        let images = materials::read_images(path, dir, outside, &document, &buffers)?;
        let material_base = self.add_gltf_materials(path, &document, &images)?;
        self.add_gltf_nodes(path, &document, placement, objects, &buffers, material_base)
    }
}
