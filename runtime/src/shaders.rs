//! Every production shader module in one registry: the pipelines create their modules from
//! [`Shader::create`], and the test below validates every one with naga under the capabilities
//! the runtime requests (none beyond core WGSL), so a shader error fails `cargo test` without a GPU.
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
    ComposableModuleDescriptor, Composer, NagaModuleDescriptor, ShaderDefValue,
};

/// Invocations per workgroup of the kernels with one invocation per item (texels, leaves,
/// nodes, query pairs, segments).
pub const WORKGROUP_1D: u32 = 64;

/// Side of the square workgroups of the kernels with one invocation per pixel.
pub const WORKGROUP_2D: u32 = 8;

/// The libraries the modules import (`#import cssm::...`), each defining its import path:
/// the structs shared with Rust (`cssm::types`, twins in [`crate::gpu_types`]), albedo textures,
/// the shadow lookup, the light model, the CSSM visibility query, the moving objects' query
/// (§3.3), the light transfer, the
/// low-res pixel's representative pixel, the voxel fragment, the sparse voxel octree's reads,
/// the joint bilateral weight, the point proxy and its voxel grid, the sample patterns' hash,
/// the atlas texels where their objects' motion puts them (§3.3), ray casting through a BVH
/// (`cssm::bvh`).
const LIBRARIES: [(&str, &str); 15] = [
    ("runtime/src/types.wgsl", include_str!("types.wgsl")),
    (
        "runtime/src/common/albedo.wgsl",
        include_str!("common/albedo.wgsl"),
    ),
    (
        "runtime/src/common/shadow_lookup.wgsl",
        include_str!("common/shadow_lookup.wgsl"),
    ),
    (
        "runtime/src/direct/light.wgsl",
        include_str!("direct/light.wgsl"),
    ),
    (
        "runtime/src/visibility/cssm.wgsl",
        include_str!("visibility/cssm.wgsl"),
    ),
    (
        "runtime/src/visibility/moving.wgsl",
        include_str!("visibility/moving.wgsl"),
    ),
    (
        "runtime/src/radiosity/transfer.wgsl",
        include_str!("radiosity/transfer.wgsl"),
    ),
    (
        "runtime/src/common/lowres.wgsl",
        include_str!("common/lowres.wgsl"),
    ),
    (
        "runtime/src/common/voxel.wgsl",
        include_str!("common/voxel.wgsl"),
    ),
    ("runtime/src/vct/svo.wgsl", include_str!("vct/svo.wgsl")),
    (
        "runtime/src/common/bilateral.wgsl",
        include_str!("common/bilateral.wgsl"),
    ),
    ("runtime/src/vf/proxy.wgsl", include_str!("vf/proxy.wgsl")),
    (
        "runtime/src/common/random.wgsl",
        include_str!("common/random.wgsl"),
    ),
    (
        "runtime/src/visibility/posed.wgsl",
        include_str!("visibility/posed.wgsl"),
    ),
    (
        "runtime/src/visibility/bvh_trace.wgsl",
        include_str!("visibility/bvh_trace.wgsl"),
    ),
];

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
/// # Errors
/// A library that does not parse (a bug: the registry test composes every module).
pub fn composer() -> Result<Composer, String> {
    let mut composer = Composer::default();
    for (file_path, source) in LIBRARIES {
        let added = composer.add_composable_module(ComposableModuleDescriptor {
            source,
            file_path,
            shader_defs: {
                let mut defs = shader_defs(CSSM_GROUP, CssmShape::default(), 0);
                for name in PER_MODULE_DEFS {
                    defs.remove(name);
                }
                defs
            },
            ..Default::default()
        });
        if let Err(e) = added {
            return Err(e.emit_to_string(&composer));
        }
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

/// A production shader module.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shader {
    /// `common/shadow_map.wgsl`: depth of every light's view (§4.7).
    ShadowMap,
    /// `common/gbuffer.wgsl` with `common/albedo.wgsl`.
    GBuffer,
    /// `direct/shade.wgsl` with `direct/light.wgsl` and the shadow lookup.
    DirectScreen,
    /// `direct/atlas.wgsl` with `direct/light.wgsl` and the shadow lookup.
    DirectAtlas,
    /// `radiosity/gather.wgsl` with the CSSM library and `radiosity/transfer.wgsl`.
    RadiosityGather,
    /// `radiosity/pull.wgsl`.
    RadiosityPull,
    /// `common/converge.wgsl`: the test that ends a run of bounces (`check`) and the copy that
    /// holds its solution (`hold`).
    Converge,
    /// `lightmap/lookup.wgsl` with the CSSM library.
    AtlasLookup,
    /// `lightcuts/final_gather.wgsl` with the CSSM library and `radiosity/transfer.wgsl`.
    FinalGather,
    /// `common/compose.wgsl`.
    Compose,
    /// `common/tonemap.wgsl`.
    Tonemap,
    /// `common/filters.wgsl`: edge-aware blur (`blur_x`, `blur_y`) and joint bilateral
    /// up-sampling (`upsample`), with `common/lowres.wgsl`.
    Filters,
    /// `visibility/query.wgsl`, the batch query kernel, with the CSSM library.
    Query,
    /// `visibility/gather.wgsl`, the gather benchmark kernel, with the CSSM library.
    Gather,
    /// `visibility/tiles.wgsl`, the benchmark kernel of a G-buffer's tiles querying senders,
    /// one query a thread, with the CSSM library.
    TileQueries,
    /// `visibility/moving_query.wgsl`, the batch query between posed surface points, with the
    /// CSSM library and `visibility/moving.wgsl` (§3.3).
    MovingQuery,
    /// `visibility/bvh.wgsl`, the exact ray-cast baseline, with `visibility/bvh_trace.wgsl`.
    Bvh,
    /// `visibility/depth_maps.wgsl`, the bake's depth cube maps by ray casting (§3.2.1), with
    /// `visibility/bvh_trace.wgsl`.
    DepthMaps,
    /// `rsm/sample.wgsl`, the RSM gather with the micro linear buffer.
    RsmSampling,
    /// `common/resolve.wgsl`, two planes of gathered light reflected towards the eye (`rsm`,
    /// `ssil`).
    Resolve,
    /// `common/pyramid.wgsl`: the G-buffer pyramid's vote (`vote`) and a signal's mean
    /// (`mean`).
    Pyramid,
    /// `ssil/sender.wgsl`: the diffuse direct light leaving every pixel, and the next bounce's.
    SsilSender,
    /// `ssil/voxels.wgsl`: the view frustum's solid voxels by XOR (`vs_main`, `fs_main`) and
    /// their AND down the levels (`and_down`).
    SsilVoxels,
    /// `ssil/gather.wgsl` with `common/bilateral.wgsl`: one level's gather and the coarser
    /// levels up-sampled into it (`gather`), and the bounces' sum (`accumulate`).
    SsilGather,
    /// `ssil/temporal.wgsl`: the reprojected history blended in.
    SsilTemporal,
    /// `vf/proxies.wgsl`: the point proxies' voxel keys (`hash`) and each voxel's range of
    /// the sorted proxies (`cell_ranges`).
    VfProxies,
    /// `vf/light.wgsl`: the direct light onto the proxies, VPLs (`vpl`), and each voxel's
    /// order-0/1 spherical harmonics of their light (`voxel_sh_sum`).
    VfLight,
    /// `vf/march.wgsl`: the sparse shadow rays through the proxies' voxels.
    VfMarch,
    /// `vf/filter.wgsl`: the visibility filter, the union of the neighbours' voxel lists.
    VfFilter,
    /// `vf/gather.wgsl` with `common/bilateral.wgsl`: the weighted lists' VPLs and harmonics.
    VfGather,
    /// `common/voxelize.wgsl`, conservative voxelisation into a voxel-fragment list.
    Voxelize,
    /// `vct/octree.wgsl`, the sparse voxel octree's structure from the fragments
    /// (`flag`, `allocate`, `next_level`).
    Octree,
    /// `vct/radiance.wgsl` with `vct/svo.wgsl`: light injection, leaves, MIP-mapping, bricks.
    VoxelRadiance,
    /// `vct/trace.wgsl` with `vct/svo.wgsl`: the cones per pixel (`main`) and the test's
    /// probe (`probe`).
    ConeTrace,
}

impl Shader {
    /// Every module.
    pub const ALL: [Shader; 34] = [
        Shader::ShadowMap,
        Shader::GBuffer,
        Shader::DirectScreen,
        Shader::DirectAtlas,
        Shader::RadiosityGather,
        Shader::RadiosityPull,
        Shader::Converge,
        Shader::AtlasLookup,
        Shader::FinalGather,
        Shader::Compose,
        Shader::Tonemap,
        Shader::Filters,
        Shader::Query,
        Shader::Gather,
        Shader::TileQueries,
        Shader::MovingQuery,
        Shader::Bvh,
        Shader::DepthMaps,
        Shader::RsmSampling,
        Shader::Resolve,
        Shader::Voxelize,
        Shader::Octree,
        Shader::VoxelRadiance,
        Shader::ConeTrace,
        Shader::Pyramid,
        Shader::SsilSender,
        Shader::SsilVoxels,
        Shader::SsilGather,
        Shader::SsilTemporal,
        Shader::VfProxies,
        Shader::VfLight,
        Shader::VfMarch,
        Shader::VfFilter,
        Shader::VfGather,
    ];

    /// Label of the module (and of its pipeline).
    pub fn label(self) -> &'static str {
        match self {
            Shader::ShadowMap => "shadow map",
            Shader::GBuffer => "gbuffer",
            Shader::DirectScreen => "direct screen",
            Shader::DirectAtlas => "direct atlas",
            Shader::RadiosityGather => "radiosity gather",
            Shader::RadiosityPull => "radiosity pull",
            Shader::Converge => "converge",
            Shader::AtlasLookup => "atlas lookup",
            Shader::FinalGather => "final gather",
            Shader::Compose => "compose",
            Shader::Tonemap => "tonemap",
            Shader::Filters => "edge-aware filters",
            Shader::Query => "visibility query",
            Shader::Gather => "visibility gather",
            Shader::TileQueries => "visibility tiles",
            Shader::MovingQuery => "moving objects' query",
            Shader::Bvh => "bvh segments",
            Shader::DepthMaps => "depth cube maps",
            Shader::RsmSampling => "rsm sampling",
            Shader::Resolve => "resolve",
            Shader::Pyramid => "pyramid",
            Shader::SsilSender => "ssil sender",
            Shader::SsilVoxels => "ssil voxels",
            Shader::SsilGather => "ssil gather",
            Shader::SsilTemporal => "ssil temporal",
            Shader::VfProxies => "vf proxies",
            Shader::VfLight => "vf light",
            Shader::VfMarch => "vf shadow rays",
            Shader::VfFilter => "vf visibility filter",
            Shader::VfGather => "vf gather",
            Shader::Voxelize => "voxelize",
            Shader::Octree => "octree",
            Shader::VoxelRadiance => "voxel radiance",
            Shader::ConeTrace => "vct trace",
        }
    }

    /// The module's own source and its path (its imports come from the libraries).
    pub fn source(self) -> (&'static str, &'static str) {
        match self {
            Shader::ShadowMap => (
                "runtime/src/common/shadow_map.wgsl",
                include_str!("common/shadow_map.wgsl"),
            ),
            Shader::GBuffer => (
                "runtime/src/common/gbuffer.wgsl",
                include_str!("common/gbuffer.wgsl"),
            ),
            Shader::DirectScreen => (
                "runtime/src/direct/shade.wgsl",
                include_str!("direct/shade.wgsl"),
            ),
            Shader::DirectAtlas => (
                "runtime/src/direct/atlas.wgsl",
                include_str!("direct/atlas.wgsl"),
            ),
            Shader::RadiosityGather => (
                "runtime/src/radiosity/gather.wgsl",
                include_str!("radiosity/gather.wgsl"),
            ),
            Shader::RadiosityPull => (
                "runtime/src/radiosity/pull.wgsl",
                include_str!("radiosity/pull.wgsl"),
            ),
            Shader::Converge => (
                "runtime/src/common/converge.wgsl",
                include_str!("common/converge.wgsl"),
            ),
            Shader::AtlasLookup => (
                "runtime/src/lightmap/lookup.wgsl",
                include_str!("lightmap/lookup.wgsl"),
            ),
            Shader::FinalGather => (
                "runtime/src/lightcuts/final_gather.wgsl",
                include_str!("lightcuts/final_gather.wgsl"),
            ),
            Shader::Compose => (
                "runtime/src/common/compose.wgsl",
                include_str!("common/compose.wgsl"),
            ),
            Shader::Tonemap => (
                "runtime/src/common/tonemap.wgsl",
                include_str!("common/tonemap.wgsl"),
            ),
            Shader::Filters => (
                "runtime/src/common/filters.wgsl",
                include_str!("common/filters.wgsl"),
            ),
            Shader::Query => (
                "runtime/src/visibility/query.wgsl",
                include_str!("visibility/query.wgsl"),
            ),
            Shader::Gather => (
                "runtime/src/visibility/gather.wgsl",
                include_str!("visibility/gather.wgsl"),
            ),
            Shader::TileQueries => (
                "runtime/src/visibility/tiles.wgsl",
                include_str!("visibility/tiles.wgsl"),
            ),
            Shader::MovingQuery => (
                "runtime/src/visibility/moving_query.wgsl",
                include_str!("visibility/moving_query.wgsl"),
            ),
            Shader::Bvh => (
                "runtime/src/visibility/bvh.wgsl",
                include_str!("visibility/bvh.wgsl"),
            ),
            Shader::DepthMaps => (
                "runtime/src/visibility/depth_maps.wgsl",
                include_str!("visibility/depth_maps.wgsl"),
            ),
            Shader::RsmSampling => (
                "runtime/src/rsm/sample.wgsl",
                include_str!("rsm/sample.wgsl"),
            ),
            Shader::Octree => (
                "runtime/src/vct/octree.wgsl",
                include_str!("vct/octree.wgsl"),
            ),
            Shader::VoxelRadiance => (
                "runtime/src/vct/radiance.wgsl",
                include_str!("vct/radiance.wgsl"),
            ),
            Shader::ConeTrace => ("runtime/src/vct/trace.wgsl", include_str!("vct/trace.wgsl")),
            Shader::Voxelize => (
                "runtime/src/common/voxelize.wgsl",
                include_str!("common/voxelize.wgsl"),
            ),
            Shader::Resolve => (
                "runtime/src/common/resolve.wgsl",
                include_str!("common/resolve.wgsl"),
            ),
            Shader::Pyramid => (
                "runtime/src/common/pyramid.wgsl",
                include_str!("common/pyramid.wgsl"),
            ),
            Shader::SsilSender => (
                "runtime/src/ssil/sender.wgsl",
                include_str!("ssil/sender.wgsl"),
            ),
            Shader::SsilVoxels => (
                "runtime/src/ssil/voxels.wgsl",
                include_str!("ssil/voxels.wgsl"),
            ),
            Shader::SsilGather => (
                "runtime/src/ssil/gather.wgsl",
                include_str!("ssil/gather.wgsl"),
            ),
            Shader::SsilTemporal => (
                "runtime/src/ssil/temporal.wgsl",
                include_str!("ssil/temporal.wgsl"),
            ),
            Shader::VfProxies => (
                "runtime/src/vf/proxies.wgsl",
                include_str!("vf/proxies.wgsl"),
            ),
            Shader::VfLight => ("runtime/src/vf/light.wgsl", include_str!("vf/light.wgsl")),
            Shader::VfMarch => ("runtime/src/vf/march.wgsl", include_str!("vf/march.wgsl")),
            Shader::VfFilter => ("runtime/src/vf/filter.wgsl", include_str!("vf/filter.wgsl")),
            Shader::VfGather => ("runtime/src/vf/gather.wgsl", include_str!("vf/gather.wgsl")),
        }
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
    /// `cssm::visibility` are built with (`Shader::Query.create_for(device, cssm.shape())`).
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
        for shader in Shader::ALL {
            let module = module(shader);
            assert!(
                !module.entry_points.is_empty(),
                "{}: no entry point",
                shader.label()
            );
        }
    }

    /// The passes that read texel geometry read the objects' motion (`posed.wgsl`, §3.3) only
    /// when composed for moving objects, and validate so composed.
    #[test]
    fn texels_read_the_motion_only_in_scenes_with_moving_objects() {
        for shader in [
            Shader::DirectAtlas,
            Shader::RadiosityGather,
            Shader::FinalGather,
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
        for shader in Shader::ALL {
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
