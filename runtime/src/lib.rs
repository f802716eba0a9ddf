//! The GPU runtime of the CSSM toolchain, on wgpu: loads `.cssm` files and scenes into GPU
//! memory, answers visibility queries between surface points in WGSL (Ritschel et al. 2008,
//! §3.2.2), renders direct light from spot lights with shadow maps and from emissive surfaces
//! (one-sided, §4.7) and global illumination from it, beside the real-time techniques it is
//! measured against, with a CPU path tracer as ground truth.
//!
//! The methods (`--method`, one line each of [`METHODS`]): `direct` (direct light only), `hrc`
//! and `lightmap` (hierarchical radiosity over the atlas, §4.1-§4.3, looked up per pixel, §5),
//! `lightcuts` (the final gather per pixel, §4.4, §4.5), `rsm` (reflective shadow maps with a
//! micro linear buffer, Bang 2011), `vct` (voxel cone tracing, Crassin et al. 2011), `ssil`
//! (screen-space indirect light, Soler et al. 2010), `vf` (visibility filtering, Chen et al.
//! 2014) and `reference` (the CPU path tracer).
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
//! - [`rsm`], [`vct`], [`ssil`], [`vf`]: the dynamic techniques, a folder each with its passes,
//!   WGSL and CPU twin.
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

#[cfg(test)]
mod tests {
    use std::path::Path;

    /// The text of `path` from the repository's root.
    fn read(path: &str) -> String {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        std::fs::read_to_string(root.join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    /// The methods `text` (the prose list `place`) does not name in backticks.
    fn missing(place: &str, text: &str, names: impl Iterator<Item = &'static str>) -> Vec<String> {
        names
            .filter(|name| !text.contains(&format!("`{name}`")))
            .map(|name| format!("{place} misses `{name}`"))
            .collect()
    }

    /// Every prose list of the methods names each one of [`crate::METHODS`]: adding a method to
    /// the table and not to the lists that index the code fails here.
    #[test]
    fn prose_lists_of_methods_name_every_method() {
        let names = || crate::METHODS.iter().map(|m| m.name);
        let mut wrong = Vec::new();
        let crate_doc: String = read("runtime/src/lib.rs")
            .lines()
            .filter(|l| l.starts_with("//!"))
            .collect();
        wrong.extend(missing(
            "runtime/src/lib.rs's crate doc",
            &crate_doc,
            names(),
        ));
        let readme = read("README.md");
        let where_is = readme
            .split("## What is where")
            .nth(1)
            .and_then(|s| s.split("\n## ").next())
            .expect("README.md has a \"What is where\" section");
        wrong.extend(missing("README.md's \"What is where\"", where_is, names()));
        let architecture = read("docs/architecture.md");
        let runtime_row = architecture
            .lines()
            .find(|l| l.starts_with("| `cssm-runtime` |"))
            .expect("docs/architecture.md has the cssm-runtime row");
        wrong.extend(missing(
            "docs/architecture.md's cssm-runtime row",
            runtime_row,
            names(),
        ));
        let frame_doc: String = read("runtime/src/frame.rs")
            .lines()
            .filter(|l| l.starts_with("//!"))
            .collect();
        let gpu_gi = crate::METHODS
            .iter()
            .filter(|m| m.on_gpu() && m.name != "direct")
            .map(|m| m.name);
        wrong.extend(missing("runtime/src/frame.rs's passes", &frame_doc, gpu_gi));
        let manifest = read("runtime/Cargo.toml");
        let description = manifest
            .lines()
            .find(|l| l.starts_with("description"))
            .expect("runtime/Cargo.toml has a description");
        for name in names() {
            let word = description
                .split(|c: char| !c.is_ascii_alphanumeric())
                .any(|w| w == name);
            if !word {
                wrong.push(format!("runtime/Cargo.toml's description misses {name}"));
            }
        }
        assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    }
}
