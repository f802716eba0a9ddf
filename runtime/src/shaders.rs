//! Every production shader module in one registry: the pipelines create their modules from
//! [`Shader::create`], and the test below validates every one with naga under the capabilities
//! the runtime requests (none beyond core WGSL), so a shader error fails `cargo test` without a GPU.
//!
//! The workgroup sizes are defined once, here ([`WORKGROUP_1D`], [`WORKGROUP_2D`]): the WGSL
//! reads them as constants of the [`prelude`] and the passes dispatch with the same numbers.

use crate::gpu_types::TYPES_WGSL;

/// Invocations per workgroup of the kernels with one invocation per item (texels, leaves,
/// nodes, query pairs, segments).
pub const WORKGROUP_1D: u32 = 64;

/// Side of the square workgroups of the kernels with one invocation per pixel.
pub const WORKGROUP_2D: u32 = 8;

/// The workgroup sizes as WGSL constants.
fn workgroup_wgsl() -> String {
    format!(
        "const WORKGROUP_1D: u32 = {WORKGROUP_1D}u;\nconst WORKGROUP_2D: u32 = {WORKGROUP_2D}u;\n"
    )
}

/// What every module starts with: the workgroup sizes as WGSL constants and the structs shared
/// with Rust (`types.wgsl`, twins in [`crate::gpu_types`]).
pub fn prelude() -> String {
    format!("{}{TYPES_WGSL}\n", workgroup_wgsl())
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
    /// `lightmap/lookup.wgsl` with the CSSM library.
    AtlasLookup,
    /// `lightcuts/final_gather.wgsl` with the CSSM library and `radiosity/transfer.wgsl`.
    FinalGather,
    /// `common/compose.wgsl`.
    Compose,
    /// `common/tonemap.wgsl`.
    Tonemap,
    /// `visibility/query.wgsl`, the batch query kernel, with the CSSM library.
    Query,
    /// `visibility/gather.wgsl`, the gather benchmark kernel, with the CSSM library.
    Gather,
    /// `visibility/bvh.wgsl`, the exact ray-cast baseline.
    Bvh,
}

impl Shader {
    /// Every module.
    pub const ALL: [Shader; 13] = [
        Shader::ShadowMap,
        Shader::GBuffer,
        Shader::DirectScreen,
        Shader::DirectAtlas,
        Shader::RadiosityGather,
        Shader::RadiosityPull,
        Shader::AtlasLookup,
        Shader::FinalGather,
        Shader::Compose,
        Shader::Tonemap,
        Shader::Query,
        Shader::Gather,
        Shader::Bvh,
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
            Shader::AtlasLookup => "atlas lookup",
            Shader::FinalGather => "final gather",
            Shader::Compose => "compose",
            Shader::Tonemap => "tonemap",
            Shader::Query => "visibility query",
            Shader::Gather => "visibility gather",
            Shader::Bvh => "bvh segments",
        }
    }

    /// The module's whole WGSL source.
    pub fn source(self) -> String {
        let light = || {
            format!(
                "{}{}\n{}",
                prelude(),
                crate::common::shadow_map::LOOKUP_WGSL,
                include_str!("direct/light.wgsl")
            )
        };
        // The library a user's shader includes too (`library_wgsl`), behind the sizes.
        let cssm = || workgroup_wgsl() + &crate::visibility::library_wgsl(1);
        let transfer = include_str!("radiosity/transfer.wgsl");
        match self {
            Shader::ShadowMap => include_str!("common/shadow_map.wgsl").to_string(),
            Shader::GBuffer => format!(
                "{}{}\n{}",
                prelude(),
                include_str!("common/albedo.wgsl"),
                include_str!("common/gbuffer.wgsl")
            ),
            Shader::DirectScreen => light() + include_str!("direct/shade.wgsl"),
            Shader::DirectAtlas => light() + include_str!("direct/atlas.wgsl"),
            Shader::RadiosityGather => cssm() + transfer + include_str!("radiosity/gather.wgsl"),
            Shader::RadiosityPull => prelude() + include_str!("radiosity/pull.wgsl"),
            Shader::AtlasLookup => cssm() + include_str!("lightmap/lookup.wgsl"),
            Shader::FinalGather => cssm() + transfer + include_str!("lightcuts/final_gather.wgsl"),
            Shader::Compose => prelude() + include_str!("common/compose.wgsl"),
            Shader::Tonemap => prelude() + include_str!("common/tonemap.wgsl"),
            Shader::Query => cssm() + include_str!("visibility/query.wgsl"),
            Shader::Gather => cssm() + include_str!("visibility/gather.wgsl"),
            Shader::Bvh => prelude() + include_str!("visibility/bvh.wgsl"),
        }
    }

    /// The module on `device`.
    pub fn create(self, device: &wgpu::Device) -> wgpu::ShaderModule {
        device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(self.label()),
            source: wgpu::ShaderSource::Wgsl(self.source().into()),
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

    /// `source` parsed and validated as the runtime's pipelines would compile it.
    pub fn validated(name: &str, source: &str) -> naga::Module {
        let module = naga::front::wgsl::parse_str(source)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), CAPABILITIES)
            .validate(&module)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
        module
    }

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

    /// The module of `shader`, validated.
    pub fn module(shader: Shader) -> naga::Module {
        validated(shader.label(), &shader.source())
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

    /// Every kernel's workgroup size is one of the Rust constants the passes dispatch with.
    #[test]
    fn workgroup_sizes_come_from_the_prelude() {
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
