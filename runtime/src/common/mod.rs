//! GPU pieces every technique shares, each defined once: the camera, the G-buffer, the test
//! that ends a run of bounces once converged, the spot-light shadow map (and its reflective
//! shadow map), tone mapping, pass timing, read-back, bind-group shorthands, the edge-aware
//! blur and up-sampling of indirect light computed at reduced resolution, and the conservative
//! voxelisation the voxel techniques start from.

pub mod camera;
pub mod compose;
pub mod converge;
pub mod filters;
pub mod gbuffer;
pub mod history;
pub mod layout;
pub mod pyramid;
pub mod random;
pub mod readback;
pub mod resolve;
pub mod shadow_map;
pub mod sort;
pub mod timestamps;
pub mod tonemap;
pub mod voxelize;

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[
        shadow_map::SHADER,
        gbuffer::SHADER,
        converge::SHADER,
        compose::SHADER,
        tonemap::SHADER,
        filters::SHADER,
        resolve::SHADER,
        pyramid::SHADER,
        voxelize::SHADER,
    ],
    libraries: &[
        crate::shaders::library!("common/albedo.wgsl"),
        crate::shaders::library!("common/shadow_lookup.wgsl"),
        crate::shaders::library!("common/lowres.wgsl"),
        crate::shaders::library!("common/voxel.wgsl"),
        crate::shaders::library!("common/bilateral.wgsl"),
        crate::shaders::library!("common/random.wgsl"),
    ],
};
