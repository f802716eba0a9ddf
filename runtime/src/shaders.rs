//! Every production shader module in one registry: the pipelines create their modules from
//! [`Shader::create`], and the test below validates every one with naga under the capabilities
//! the runtime requests (none beyond core WGSL), so a shader error fails `cargo test` without a GPU.
//!
//! The registry lists no shader itself. Each folder of the runtime declares its WGSL once, as
//! `pub const SHADERS: ShaderSet` (its modules, each a constant of the pass file that runs it,
//! `pub const SHADER: Shader = shader!("label", "folder/pass.wgsl")`, and its libraries); the
//! registry collects the shared folders' sets and, through the method table (`method_table!`),
//! every method's. A test fails on a WGSL file under `runtime/src/` that no set lists.
//!
//! Modules are composed with naga_oil (Bevy's shader composer, on naga 30): each library
//! declares its import path (`#define_import_path cssm::types`, `cssm::albedo`,
//! `cssm::shadow_lookup`, `cssm::light`, `cssm::visibility`, `cssm::transfer`,
//! `cssm::lowres`, `cssm::voxel`, `cssm::svo`, `cssm::bilateral`, `cssm::proxy`,
//! `cssm::random`) and a module
//! imports what it uses (`#import cssm::visibility::{cssm_texels, cssm_visibility_texel}`).
//!
//! The workgroup sizes are defined once, here ([`WORKGROUP_1D`], [`WORKGROUP_2D`]): the WGSL
//! reads them as shader definitions (`@workgroup_size(#{WORKGROUP_1D})`) and the passes
//! dispatch with the same numbers.

use std::{
    borrow::Cow,
    collections::HashMap,
    sync::{Mutex, OnceLock},
};

use naga_oil::compose::{
    ComposableModuleDescriptor, Composer, ComposerErrorInner, NagaModuleDescriptor, ShaderDefValue,
};

/// Invocations per workgroup of the kernels with one invocation per item (texels, leaves,
/// nodes, query pairs, segments).
pub const WORKGROUP_1D: u32 = 64;

/// Side of the square workgroups of the kernels with one invocation per pixel.
pub const WORKGROUP_2D: u32 = 8;

/// The project's own library (`cssm::types`): the structs shared with Rust, twins in
/// [`crate::gpu_types`]. The other libraries live in the folders that own them
/// ([`ShaderSet::libraries`]).
const TYPES: Library = library!("types.wgsl");

/// Bind group of the CSSM library in the runtime's own modules (group 0 is each pass's own).
pub const CSSM_GROUP: u32 = 1;

/// Bind group of the moving objects' library (`cssm::moving`) in the modules that import it.
pub const MOVING_GROUP: u32 = 2;

/// Bind group of the sparse voxel octree library (`cssm::svo`) in the modules that read it.
pub const SVO_GROUP: u32 = 1;

/// How the CSSM library (`visibility/cssm.wgsl`) is composed for one loaded `.cssm`: what the
/// modules importing it are built with ([`crate::load::CssmGpu::shape`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CssmShape {
    /// Storage bindings the run data spans (`CSSM_RUN_BINDINGS`; 1 unless the file's runs
    /// exceed one binding: [`crate::load::CssmGpu::run_bindings`]).
    pub run_bindings: u32,
    /// Steps of the binary search over one pixel's runs (`CSSM_SEARCH_STEPS`): enough for the
    /// file's longest run list ([`search_steps`]), at most [`MAX_SEARCH_STEPS`].
    pub search_steps: u32,
    /// The search as a loop (`CSSM_SEARCH_LOOP`) rather than unrolled: every driver but
    /// llvmpipe, whose loop limit per invocation a final gather's searches would pass
    /// ([`search_loop_allowed`]).
    pub search_loop: bool,
    /// The query counts its work per invocation (`CSSM_COUNTERS`: taps, search steps, texel and
    /// sender loads), for the counting kernels ([`crate::visibility::QueryKernel::run_counted`]).
    pub counters: bool,
}

/// The most search steps a file can need: a segment's pixel holds at most 2^16 runs.
pub const MAX_SEARCH_STEPS: u32 = 17;

impl Default for CssmShape {
    /// One run binding, the search unrolled to [`MAX_SEARCH_STEPS`]: right for any file.
    fn default() -> Self {
        Self {
            run_bindings: 1,
            search_steps: MAX_SEARCH_STEPS,
            search_loop: false,
            counters: false,
        }
    }
}

/// Steps of the query's binary search over a file's run lists (`CSSM_SEARCH_STEPS`): enough
/// for the longest list ([`cssm_formats::cssm::RunData::search_steps`]).
pub fn search_steps(runs: &cssm_formats::cssm::RunData) -> u32 {
    runs.search_steps().min(MAX_SEARCH_STEPS)
}

/// Whether the query's search may be a loop on `device`: not on llvmpipe (Mesa's CPU driver,
/// behind lavapipe), which ends an invocation's loops after 65,535 iterations in all.
pub fn search_loop_allowed(device: &wgpu::Device) -> bool {
    let info = device.adapter_info();
    !(info.device_type == wgpu::DeviceType::Cpu || info.name.contains("llvmpipe"))
}

/// The shader definitions every module is composed with: the workgroup sizes
/// (`#{WORKGROUP_1D}`, `#{WORKGROUP_2D}`), the CSSM library's bind group (`#{CSSM_GROUP}`), its
/// shape for the loaded file ([`CssmShape`]) and the moving objects' CSMs (`MOVING_CSMS`).
fn shader_defs(
    cssm_group: u32,
    shape: CssmShape,
    moving_csms: u32,
) -> HashMap<String, ShaderDefValue> {
    HashMap::from([
        ("WORKGROUP_1D".into(), ShaderDefValue::UInt(WORKGROUP_1D)),
        ("WORKGROUP_2D".into(), ShaderDefValue::UInt(WORKGROUP_2D)),
        ("CSSM_GROUP".into(), ShaderDefValue::UInt(cssm_group)),
        (
            "CSSM_RUN_BINDINGS".into(),
            ShaderDefValue::UInt(shape.run_bindings),
        ),
        (
            "CSSM_SEARCH_STEPS".into(),
            ShaderDefValue::UInt(shape.search_steps),
        ),
        (
            "CSSM_SEARCH_LOOP".into(),
            ShaderDefValue::UInt(u32::from(shape.search_loop)),
        ),
        (
            "CSSM_COUNTERS".into(),
            ShaderDefValue::UInt(u32::from(shape.counters)),
        ),
        ("SVO_GROUP".into(), ShaderDefValue::UInt(SVO_GROUP)),
        ("MOVING_GROUP".into(), ShaderDefValue::UInt(MOVING_GROUP)),
        ("MOVING_CSMS".into(), ShaderDefValue::UInt(moving_csms)),
    ])
}

/// The definitions each composed module gives its libraries, not fixed when they are added
/// (naga_oil refuses a definition whose value differs between a library and the module
/// importing it).
const PER_MODULE_DEFS: [&str; 5] = [
    "CSSM_RUN_BINDINGS",
    "CSSM_SEARCH_STEPS",
    "CSSM_SEARCH_LOOP",
    "CSSM_COUNTERS",
    "MOVING_CSMS",
];

/// A naga_oil composer holding every library.
///
/// The folders list their libraries in no particular order, and naga_oil takes a library only
/// once the ones it imports are in: each round adds every library whose imports are there, until
/// none is left.
///
/// # Errors
/// A library that does not parse, or whose imports no library defines (a bug: the registry test
/// composes every module).
pub fn composer() -> Result<Composer, String> {
    let mut composer = Composer::default();
    let mut defs = shader_defs(CSSM_GROUP, CssmShape::default(), 0);
    for name in PER_MODULE_DEFS {
        defs.remove(name);
    }
    let mut waiting: Vec<Library> = libraries().collect();
    while !waiting.is_empty() {
        let mut deferred = Vec::new();
        let mut last_error = None;
        for library in waiting.iter().copied() {
            let added = composer.add_composable_module(ComposableModuleDescriptor {
                source: library.source,
                file_path: library.path,
                shader_defs: defs.clone(),
                ..Default::default()
            });
            match added {
                Ok(_) => {}
                Err(e) if matches!(e.inner, ComposerErrorInner::ImportNotFound(..)) => {
                    last_error = Some(e.emit_to_string(&composer));
                    deferred.push(library);
                }
                Err(e) => return Err(e.emit_to_string(&composer)),
            }
        }
        if deferred.len() == waiting.len() {
            return Err(last_error.unwrap_or_default());
        }
        waiting = deferred;
    }
    Ok(composer)
}

/// Workgroups of [`WORKGROUP_1D`] covering `items` (at least one).
pub fn groups_1d(items: u32) -> u32 {
    items.max(1).div_ceil(WORKGROUP_1D)
}

/// Workgroups of [`WORKGROUP_2D`]² covering a `width` x `height` image.
pub fn groups_2d((width, height): (u32, u32)) -> (u32, u32) {
    (width.div_ceil(WORKGROUP_2D), height.div_ceil(WORKGROUP_2D))
}

/// `shader!("vf shadow rays", "vf/march.wgsl")`: the module at that path under `runtime/src/`,
/// its pipelines labelled so. A folder declares its modules with it and lists them in its
/// [`ShaderSet`].
macro_rules! shader {
    ($label:literal, $path:literal) => {
        $crate::shaders::Shader::new(
            $label,
            concat!("runtime/src/", $path),
            include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/src/", $path)),
        )
    };
}
pub(crate) use shader;

/// `library!("vf/proxy.wgsl")`: the library at that path under `runtime/src/` (it defines its
/// import path), for a folder's [`ShaderSet::libraries`].
macro_rules! library {
    ($path:literal) => {
        $crate::shaders::Library {
            path: concat!("runtime/src/", $path),
            source: include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/src/", $path)),
        }
    };
}
pub(crate) use library;

/// A WGSL library the modules import (`#import cssm::...`): it defines its import path
/// (`#define_import_path cssm::svo`).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Library {
    /// Its path from the repository's root, for naga_oil's messages.
    pub path: &'static str,
    /// Its WGSL.
    pub source: &'static str,
}

/// What one folder of the runtime brings to the registry: its modules and its libraries. Every
/// folder with WGSL declares one as `pub const SHADERS: ShaderSet`; [`Shader::all`] collects the
/// shared folders' and, through the method table (`method_table!` in `lib.rs`), every method's.
#[derive(Clone, Copy, Debug)]
pub struct ShaderSet {
    /// The modules with entry points, one per pass or group of passes.
    pub modules: &'static [Shader],
    /// The libraries they import.
    pub libraries: &'static [Library],
}

impl ShaderSet {
    /// A folder without WGSL (a method that runs on the CPU).
    pub const NONE: ShaderSet = ShaderSet {
        modules: &[],
        libraries: &[],
    };
}

/// The folders shared by the methods, then every method's (the method table's order).
fn sets() -> impl Iterator<Item = &'static ShaderSet> {
    [
        &crate::common::SHADERS,
        &crate::visibility::SHADERS,
        &crate::radiosity::SHADERS,
    ]
    .into_iter()
    .chain(crate::METHOD_SHADERS.iter())
}

/// Every library: `cssm::types`, then each folder's.
fn libraries() -> impl Iterator<Item = Library> {
    std::iter::once(TYPES).chain(sets().flat_map(|set| set.libraries.iter().copied()))
}

/// A production shader module: its WGSL, where it lives, and its label. Each is a constant of
/// the folder whose passes run it (`crate::vf::march::SHADER`), declared with `shader!`.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Shader {
    label: &'static str,
    path: &'static str,
    source: &'static str,
}

/// The path, not the WGSL, in `{:?}`.
impl std::fmt::Debug for Library {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.path)
    }
}

/// The label and the path, not the WGSL, in `{:?}`.
impl std::fmt::Debug for Shader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({})", self.label, self.path)
    }
}

impl Shader {
    /// The module `source`, read from `path` (from the repository's root), labelled `label`.
    pub const fn new(label: &'static str, path: &'static str, source: &'static str) -> Self {
        Self {
            label,
            path,
            source,
        }
    }

    /// Every module, folder by folder ([`ShaderSet`]).
    pub fn all() -> impl Iterator<Item = Shader> {
        sets().flat_map(|set| set.modules.iter().copied())
    }

    /// Label of the module (and of its pipeline).
    pub fn label(self) -> &'static str {
        self.label
    }

    /// The module's own source and its path (its imports come from the libraries).
    pub fn source(self) -> (&'static str, &'static str) {
        (self.path, self.source)
    }

    /// The module composed by naga_oil from its source and the libraries it imports.
    ///
    /// # Errors
    /// naga_oil's message (a bug: the registry test composes every module).
    pub fn module(self) -> Result<naga::Module, String> {
        self.module_for(CssmShape::default())
    }

    /// The module composed for a CSSM of shape `shape` ([`crate::load::CssmGpu::shape`];
    /// [`Self::module`] is `module_for(CssmShape::default())`).
    ///
    /// # Errors
    /// naga_oil's message (a bug: the registry test composes every module).
    pub fn module_for(self, shape: CssmShape) -> Result<naga::Module, String> {
        self.module_for_scene(shape, 0)
    }

    /// [`Self::module_for`] for a scene whose `.cssm` holds `moving_csms` coherent shadow maps
    /// of moving objects (`MOVING_CSMS`: the moving objects' query tests exactly that many, so
    /// a static scene's modules carry none of its code; lavapipe compiles each copy).
    ///
    /// # Errors
    /// naga_oil's message (a bug: the registry test composes every module).
    pub fn module_for_scene(
        self,
        shape: CssmShape,
        moving_csms: u32,
    ) -> Result<naga::Module, String> {
        // One composer for the process: the libraries are parsed once, and naga_oil keeps each
        // composed import, so a renderer's start-up does not parse them again per module.
        static COMPOSER: OnceLock<Result<Mutex<Composer>, String>> = OnceLock::new();
        let shared = COMPOSER.get_or_init(|| composer().map(Mutex::new));
        let mut composer = shared
            .as_ref()
            .map_err(Clone::clone)?
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        let (file_path, source) = self.source();
        composer
            .make_naga_module(NagaModuleDescriptor {
                source,
                file_path,
                shader_defs: shader_defs(CSSM_GROUP, shape, moving_csms),
                ..Default::default()
            })
            .map_err(|e| e.emit_to_string(&composer))
    }

    /// The module on `device`. Should composition fail (a bug the registry test catches), the
    /// uncomposed source goes to wgpu, whose validation error names the module.
    pub fn create(self, device: &wgpu::Device) -> wgpu::ShaderModule {
        self.create_for(device, CssmShape::default())
    }

    /// The module on `device` for a CSSM of shape `shape`: what the modules that import
    /// `cssm::visibility` are built with (`visibility::QUERY_SHADER.create_for(device, cssm.shape())`).
    pub fn create_for(self, device: &wgpu::Device, shape: CssmShape) -> wgpu::ShaderModule {
        self.create_for_scene(device, shape, 0)
    }

    /// [`Self::create_for`] for a `.cssm` with `moving_csms` coherent shadow maps
    /// ([`Self::module_for_scene`]; [`crate::visibility::moving::MovingGpu::csm_count`]).
    pub fn create_for_scene(
        self,
        device: &wgpu::Device,
        shape: CssmShape,
        moving_csms: u32,
    ) -> wgpu::ShaderModule {
        let source = match self.module_for_scene(shape, moving_csms) {
            Ok(module) => wgpu::ShaderSource::Naga(Cow::Owned(module)),
            Err(_) => wgpu::ShaderSource::Wgsl(self.source().1.into()),
        };
        device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(self.label()),
            source,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The naga capabilities the shaders may use: none beyond core WGSL. The runtime requests
    /// only timestamp queries and filterable 32-bit float textures of the device
    /// (`Gpu::new_headless`), neither of which is a shader capability, so a module that needs
    /// more fails here.
    pub const CAPABILITIES: naga::valid::Capabilities = naga::valid::Capabilities::empty();

    /// Asserts that the WGSL struct `name` of `module` has `size` bytes and each member of
    /// `offsets` its offset: the Rust twin's `size_of` and `offset_of!`.
    pub fn check_struct(module: &naga::Module, name: &str, size: usize, offsets: &[(&str, usize)]) {
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("module lays out");
        let (handle, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("{name} missing from the module"));
        assert_eq!(layouter[handle].size as usize, size, "size of {name}");
        let naga::TypeInner::Struct { members, .. } = &ty.inner else {
            panic!("{name} is not a struct")
        };
        for (member, offset) in offsets {
            let m = members
                .iter()
                .find(|m| m.name.as_deref() == Some(*member))
                .unwrap_or_else(|| panic!("{name}.{member} missing"));
            assert_eq!(m.offset as usize, *offset, "offset of {name}.{member}");
        }
    }

    /// The module of `shader`, composed and validated.
    pub fn module(shader: Shader) -> naga::Module {
        let module = shader
            .module()
            .unwrap_or_else(|e| panic!("{}: {e}", shader.label()));
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), CAPABILITIES)
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}: {e:?}", shader.label()));
        module
    }

    #[test]
    fn every_production_module_validates() {
        for shader in Shader::all() {
            let module = module(shader);
            assert!(
                !module.entry_points.is_empty(),
                "{}: no entry point",
                shader.label()
            );
        }
    }

    /// Every WGSL file under `runtime/src/` is in the registry once, as a module or a library:
    /// a folder that forgets to list a shader in its `SHADERS` fails here, not on a GPU. Labels
    /// name one module each (they name the pipelines in a profiler).
    #[test]
    fn every_wgsl_file_is_registered_once() {
        fn wgsl_files(dir: &std::path::Path, found: &mut Vec<String>) {
            for entry in std::fs::read_dir(dir).expect("runtime/src reads") {
                let path = entry.expect("directory entry").path();
                if path.is_dir() {
                    wgsl_files(&path, found);
                } else if path.extension().is_some_and(|e| e == "wgsl") {
                    let from_root = path
                        .strip_prefix(env!("CARGO_MANIFEST_DIR"))
                        .expect("under the crate");
                    found.push(format!("runtime/{}", from_root.display()));
                }
            }
        }
        let mut on_disk = Vec::new();
        wgsl_files(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src"),
            &mut on_disk,
        );
        on_disk.sort();
        let mut registered: Vec<String> = Shader::all()
            .map(|s| s.source().0)
            .chain(libraries().map(|l| l.path))
            .map(String::from)
            .collect();
        registered.sort();
        assert_eq!(registered, on_disk);
        let mut labels: Vec<&str> = Shader::all().map(Shader::label).collect();
        labels.sort_unstable();
        let count = labels.len();
        labels.dedup();
        assert_eq!(labels.len(), count, "a label names two modules");
    }

    /// The passes that read texel geometry read the objects' motion (`posed.wgsl`, §3.3) only
    /// when composed for moving objects, and validate so composed.
    #[test]
    fn texels_read_the_motion_only_in_scenes_with_moving_objects() {
        for shader in [
            crate::direct::ATLAS_SHADER,
            crate::radiosity::GATHER_SHADER,
            crate::lightcuts::FINAL_GATHER_SHADER,
        ] {
            for csms in [0, 1, MOVING_MAX_CSMS_FOR_TEST] {
                let module = shader
                    .module_for_scene(CssmShape::default(), csms)
                    .unwrap_or_else(|e| panic!("{}: {e}", shader.label()));
                naga::valid::Validator::new(naga::valid::ValidationFlags::all(), CAPABILITIES)
                    .validate(&module)
                    .unwrap_or_else(|e| panic!("{} ({csms} CSMs): {e:?}", shader.label()));
                let reads_motion = module.global_variables.iter().any(|(_, g)| {
                    g.name
                        .as_deref()
                        .is_some_and(|n| n.contains("texel_motion"))
                });
                assert_eq!(reads_motion, csms > 0, "{} ({csms} CSMs)", shader.label());
            }
        }
    }

    const MOVING_MAX_CSMS_FOR_TEST: u32 = crate::visibility::moving::MOVING_MAX_CSMS as u32;

    /// Every kernel's workgroup size is one of the Rust constants the passes dispatch with.
    #[test]
    fn workgroup_sizes_come_from_the_shader_definitions() {
        for shader in Shader::all() {
            for entry in module(shader).entry_points {
                if entry.stage != naga::ShaderStage::Compute {
                    continue;
                }
                let size = entry.workgroup_size;
                let expected = if size[1] == 1 {
                    [WORKGROUP_1D, 1, 1]
                } else {
                    [WORKGROUP_2D, WORKGROUP_2D, 1]
                };
                assert_eq!(size, expected, "{} {}", shader.label(), entry.name);
            }
        }
        assert_eq!(groups_1d(0), 1);
        assert_eq!(groups_1d(WORKGROUP_1D + 1), 2);
        assert_eq!(groups_2d((9, 8)), (2, 1));
    }
}
