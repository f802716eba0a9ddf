//! Loaders: a `.cssm` file into GPU storage buffers ([`CssmGpu`], the run data kept in its
//! random-access layout, never decompressed), and a scene into vertex buffers, materials and
//! textures, albedo and emission ([`SceneGpu`]). Both take a plain `&wgpu::Device` and
//! `&wgpu::Queue`, so they work inside a user's own renderer.

mod cssm_gpu;
mod scene_gpu;
mod textures;

use std::path::Path;

use cssm_formats::{CssmFile, Scene, TextureSource, cssm, visibility::QueryOptions};
use glam::Vec3;
use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    gpu_types::{GpuCssmParams, GpuMaterial, GpuTexel, GpuVertex},
};

pub use cssm_gpu::{CssmGpu, MAX_RUN_BINDINGS, run_split};
pub use scene_gpu::{SceneGpu, cpu_materials, triangle_tangent};
pub use textures::{
    AlbedoTexture, TEXTURE_SIZE, TextureLayers, decode_image, decode_texture, load_textures,
    srgb_to_linear,
};

/// Reads a `.cssm` file and checks that it was baked from `scene` (same content hash and
/// triangle count).
///
/// # Errors
/// [`RuntimeError::Cssm`] for an unreadable, corrupt or invalid file (the error names it),
/// [`RuntimeError::SceneMismatch`] when it belongs to another scene or another version of it.
pub fn read_cssm(path: &Path, scene: &Scene) -> Result<CssmFile, RuntimeError> {
    let file = cssm::read(path)?;
    check_scene(path, &file, scene)?;
    Ok(file)
}

/// Checks that `file` (read from `path`) was baked from `scene`: the same triangle count and
/// content hash, and every index into the scene in range
/// ([`cssm_formats::cssm::validate_for_scene`]).
///
/// # Errors
/// [`RuntimeError::SceneMismatch`] saying whether the file comes from another scene or the
/// scene's files changed since the bake; [`RuntimeError::Cssm`] for an index out of range.
pub fn check_scene(path: &Path, file: &CssmFile, scene: &Scene) -> Result<(), RuntimeError> {
    let mismatch = |reason: String| RuntimeError::SceneMismatch {
        path: path.to_path_buf(),
        reason,
    };
    let same_name = file.scene.name == scene.name;
    let other_scene = || {
        format!(
            "it was baked from the scene '{}' ({} triangles, in {}), this is '{}' ({} triangles)",
            file.scene.name,
            file.scene.triangle_count,
            file.scene.dir,
            scene.name,
            scene.triangles.len()
        )
    };
    if file.scene.triangle_count as usize != scene.triangles.len() {
        return Err(mismatch(if same_name {
            format!(
                "the scene '{}' has {} triangles now, {} when baked",
                scene.name,
                scene.triangles.len(),
                file.scene.triangle_count
            )
        } else {
            other_scene()
        }));
    }
    if file.scene.content_hash != scene.content_hash {
        return Err(mismatch(if same_name {
            format!("the files of scene '{}' changed since the bake", scene.name)
        } else {
            other_scene()
        }));
    }
    cssm::validate_for_scene(file, scene).map_err(|e| {
        RuntimeError::Cssm(cssm::CssmError::File {
            path: path.to_path_buf(),
            inner: Box::new(e),
        })
    })
}

/// The most bytes one storage binding of a device of `limits` can hold: the binding limit,
/// and no more than a buffer may be.
pub fn storage_binding_bytes(limits: &wgpu::Limits) -> u64 {
    limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size)
}

pub(crate) fn limit_check(
    device: &wgpu::Device,
    what: &'static str,
    bytes: u64,
) -> Result<(), RuntimeError> {
    let limit = storage_binding_bytes(&device.limits());
    if bytes > limit {
        return Err(RuntimeError::TooLarge {
            what,
            needed: bytes,
            limit,
        });
    }
    Ok(())
}

/// Whether a device of `limits` can bind run data spanning `run_bindings` storage bindings
/// (`run_bytes` in all): at most [`MAX_RUN_BINDINGS`], and the passes that query the CSSM
/// (the radiosity gather binds the most: [`crate::required_limits`]) still within the
/// device's storage buffers per shader stage.
fn check_run_bindings(
    limits: &wgpu::Limits,
    run_bindings: u32,
    run_bytes: u64,
) -> Result<(), RuntimeError> {
    let binding = storage_binding_bytes(limits);
    if run_bindings > MAX_RUN_BINDINGS {
        return Err(RuntimeError::Unsupported(format!(
            "the runs need {run_bytes} bytes, more than {MAX_RUN_BINDINGS} storage bindings of \
             {binding} bytes (the GPU's limit per binding) hold; bake at a smaller atlas or cube"
        )));
    }
    let needed = crate::required_limits().max_storage_buffers_per_shader_stage + run_bindings - 1;
    if run_bindings > 1 && limits.max_storage_buffers_per_shader_stage < needed {
        return Err(RuntimeError::Unsupported(format!(
            "the runs need {run_bytes} bytes, spread over {run_bindings} storage bindings of \
             {binding} bytes (the GPU's limit per binding); the passes that query them would \
             bind {needed} storage buffers per shader stage, the GPU allows {}",
            limits.max_storage_buffers_per_shader_stage
        )));
    }
    Ok(())
}

/// A storage buffer holding `data` (at least 16 bytes: empty bindings are not allowed).
pub(crate) fn storage_buffer(device: &wgpu::Device, label: &str, data: &[u8]) -> wgpu::Buffer {
    let mut padded;
    let contents = if data.len() < 16 {
        padded = data.to_vec();
        padded.resize(16, 0);
        &padded[..]
    } else {
        data
    };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    })
}
