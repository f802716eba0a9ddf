//! Errors of the runtime.

use std::path::PathBuf;

/// Everything that can go wrong between a `.cssm` file or a scene and a frame on the GPU.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    /// No GPU adapter could be found.
    #[error(
        "no GPU adapter found ({0}); on a machine without a GPU install Mesa's lavapipe \
         (Debian: apt-get install mesa-vulkan-drivers)"
    )]
    NoAdapter(String),
    /// The adapter refused to create a device.
    #[error("the GPU adapter '{adapter}' refused to create a device: {reason}")]
    NoDevice {
        /// Adapter name.
        adapter: String,
        /// What wgpu said.
        reason: String,
    },
    /// A `.cssm` file could not be read or failed validation (the error names the file).
    #[error(transparent)]
    Cssm(#[from] cssm_formats::cssm::CssmError),
    /// A `.cssm` file was baked from another scene than the one it is used with.
    #[error("{}: baked from another scene ({reason}); re-bake it with `cssm bake`", path.display())]
    SceneMismatch {
        /// The file.
        path: PathBuf,
        /// Which figure differs.
        reason: String,
    },
    /// A scene could not be loaded.
    #[error(transparent)]
    Scene(#[from] cssm_formats::scene::SceneError),
    /// An albedo texture could not be read.
    #[error("{}: cannot read texture: {reason}", path.display())]
    Texture {
        /// The texture file.
        path: PathBuf,
        /// What the decoder said.
        reason: String,
    },
    /// Data too large for the device's limits.
    #[error("{what} needs {needed} bytes but the GPU allows {limit} per buffer binding")]
    TooLarge {
        /// Which buffer.
        what: &'static str,
        /// Bytes needed.
        needed: u64,
        /// The device's limit.
        limit: u64,
    },
    /// The scene or request cannot be rendered as asked.
    #[error("{0}")]
    Unsupported(String),
    /// The GPU reported an error (validation, out of memory, device lost).
    #[error("GPU error: {0}")]
    Gpu(String),
    /// Writing an output image failed.
    #[error("{}: {reason}", path.display())]
    Output {
        /// The file.
        path: PathBuf,
        /// What failed.
        reason: String,
    },
}
