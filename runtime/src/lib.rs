//! The GPU runtime of the CSSM toolchain, on wgpu: loads `.cssm` files and scenes into GPU
//! memory, answers visibility queries between surface points in WGSL (Ritschel et al. 2008,
//! §3.2.2), renders direct light from spot lights with shadow maps and from emissive surfaces
//! (one-sided, §4.7) and global illumination from it (§4: hierarchical radiosity over the atlas,
//! final gathering, lightmap), with a CPU path tracer as ground truth.
//!
//! - [`Gpu`]: a headless device (a real GPU, or Mesa's lavapipe on a machine without one).
//! - [`load`]: [`load::CssmGpu`] and [`load::SceneGpu`], usable with your own device and queue.
//! - [`visibility`]: the WGSL library (`cssm_visible`) and a batch query kernel.
//! - [`common`]: pieces every technique shares (camera, G-buffer, shadow map, tone mapping,
//!   pass timing, read-back).
//! - [`direct`]: the direct-light technique, on screen and into the atlas texels, with its CPU
//!   reference.
//! - [`radiosity`]: GPU hierarchical radiosity over the atlas texels (§4.1-§4.3), with its CPU
//!   twin and a brute-force CPU reference.
//! - [`lightcuts`]: the final gather per pixel (§4.4, §4.5); [`lightmap`]: the atlas looked up
//!   per pixel (§5).
//! - [`reference`](mod@reference): the CPU path tracer, ground truth of the global-illumination methods.
//! - [`Renderer`]: a scene and a method on your device, rendering frame after frame into your
//!   target; [`frame`]: its passes in order and the [`frame::FrameContext`] they share;
//!   [`method`]: the [`method::GiMethod`] seam and [`method::METHODS`], the one table of
//!   methods.
//!
//! # Example: render global illumination into your own texture
//! `examples/embed-runtime/src/main.rs`, a program of its own outside this workspace (it
//! depends on this crate by path; CI builds and runs it on lavapipe after
//! `examples/bake-library` baked the `.cssm` it loads):
//!
#![doc = concat!("```no_run\n", include_str!("../../examples/embed-runtime/src/main.rs"), "```")]
//!
//! # Example: query visibility on your own device
//! ```no_run
//! # fn demo(device: &wgpu::Device, queue: &wgpu::Queue) -> Result<(), Box<dyn std::error::Error>> {
//! use cssm_runtime::load::{read_cssm, CssmGpu};
//! let scene = cssm_formats::Scene::load("scenes/cornell-box".as_ref())?;
//! let file = read_cssm("cornell-box.cssm".as_ref(), &scene)?;
//! let cssm = CssmGpu::new(device, queue, &file, Default::default())?;
//! // Your compute or fragment shader: the library first, bound at group 1.
//! let source = cssm.library_wgsl(1) + r#"
//!     @compute @workgroup_size(64) fn main() {
//!         let seen = cssm_visible(0u, vec3f(0.3, 0.3, 0.4), vec3f(100.0, 200.0, 300.0), vec3f(0.0));
//!     }"#;
//! let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
//!     label: None,
//!     source: wgpu::ShaderSource::Wgsl(source.into()),
//! });
//! // ... pipeline layout with `cssm.bind_group_layout` at index 1, then
//! // `pass.set_bind_group(1, &cssm.bind_group, &[])`.
//! # let _ = module; Ok(()) }
//! ```

pub mod common;
mod device;
mod error;
pub mod frame;
pub mod gpu_types;
pub mod load;
pub mod method;
pub mod normal_map;
pub mod radiosity;
mod renderer;
pub mod shaders;
pub mod visibility;
pub mod work;

/// Declares each method's module (its folder under `runtime/src/`) and lists its entries in
/// [`METHODS`], in order: adding a method is its folder and one line here.
macro_rules! method_table {
    ($($module:ident => [$($entry:ident),+ $(,)?]),+ $(,)?) => {
        $(pub mod $module;)+

        /// Every method, in the order `--help` lists them (see [`method`] for the seam).
        pub const METHODS: &[method::MethodEntry] = &[$($($module::$entry,)+)+];

        /// Every method folder's WGSL (its `SHADERS`), which [`shaders::Shader::all`]
        /// collects with the shared folders'.
        const METHOD_SHADERS: &[shaders::ShaderSet] = &[$($module::SHADERS,)+];
    };
}

method_table! {
    direct => [METHOD],
    lightmap => [HRC, LIGHTMAP],
    lightcuts => [METHOD],
    rsm => [METHOD],
    vct => [METHOD],
    ssil => [METHOD],
    vf => [METHOD],
    reference => [METHOD],
}

pub use device::{Gpu, gpu_memory_bytes, required_limits};
pub use error::RuntimeError;
pub use renderer::{Renderer, RendererSettings};
