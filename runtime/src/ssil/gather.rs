//! `ssil gather` (`gather.wgsl`, §3, §4, Eq. 3 and 4), per bounce and per level from the
//! coarsest gathered to the finest: `gather`, a level's samples in the ring and the coarser
//! levels' result up-sampled into it; `accumulate`, the bounce's sum at the finest level into
//! the filters' input and, when another bounce follows, its diffuse light the next bounce's
//! senders (§4, "Multi-bounce computation"). CPU twin: [`super::cpu`]'s `gather_pixel` and
//! `accumulate`.

use glam::{Mat4, Vec3};

use super::{Levels, SsilOptions, uniform_buffer};
use crate::{
    common::{
        converge::ConvergeGpu,
        layout,
        pyramid::{GBufferPyramid, SignalPyramid},
    },
    frame::{FrameContext, FrameEncoder},
    gpu_types::GpuView,
    shaders,
};

/// `ssil/gather.wgsl` with `common/bilateral.wgsl`: one level's gather and the coarser levels
/// up-sampled into it (`gather`), and the bounces' sum (`accumulate`).
pub const SHADER: shaders::Shader = shaders::shader!("ssil gather", "ssil/gather.wgsl");

/// `gather.wgsl`'s `GatherParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GatherParams {
    /// The G-buffer's size.
    pub full_size: [u32; 2],
    /// This level's size.
    pub size: [u32; 2],
    /// The coarser level's size.
    pub coarse_size: [u32; 2],
    /// The level (0: the G-buffer's resolution).
    pub level: u32,
    /// Pyramid element of this level's pixel (0, 0).
    pub offset: u32,
    /// Pyramid element of the coarser level's pixel (0, 0).
    pub coarse_offset: u32,
    /// 1 when a coarser level is up-sampled into this one.
    pub has_coarse: u32,
    /// Samples per pixel.
    pub samples: u32,
    /// 1 at the finest gathered level (the full disc).
    pub disc: u32,
    /// Outer radius of the ring, level pixels.
    pub radius: f32,
    /// 1 when visibility is tested.
    pub visibility: u32,
    /// Level pixels skipped at both ends of a march.
    pub bias: f32,
    /// Grid column of this level's (0, 0).
    pub grid_offset: u32,
    /// The up-sampling's depth tolerance.
    pub depth_sigma: f32,
    /// The up-sampling's normal exponent.
    pub normal_power: f32,
    /// The bounce, 0 for the first.
    pub bounce: u32,
    /// 1 when another bounce follows.
    pub next_bounce: u32,
    /// Elements of the pyramid (the stride of the gathered planes).
    pub pixels: u32,
    /// `alpha` of the importance function.
    pub uniform_weight: f32,
    /// 1 for [`super::FormFactor::SampleDisc`].
    pub sample_disc: u32,
    pub(super) padding: u32,
}

/// `gather.wgsl`'s `FrameParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrameParams {
    /// This frame's seed of the sample patterns.
    pub seed: u32,
    /// View depth of the voxels' first slice.
    pub z_near: f32,
    /// View depth of the far end of the last slice.
    pub z_far: f32,
    /// Area of a full-res pixel at view depth 1 facing the eye.
    pub pixel_area: f32,
}

impl FrameParams {
    /// The parameters of a frame of `view` over a scene within `bounds`: the voxels' depth
    /// range brackets the bounds' corners in front of the eye.
    pub fn new(view: &GpuView, (lo, hi): (Vec3, Vec3), seed: u32) -> Self {
        let view_proj = Mat4::from_cols_array_2d(&view.view_proj);
        let depths = (0..8).map(|c| {
            let corner = Vec3::new(
                if c & 1 == 0 { lo.x } else { hi.x },
                if c & 2 == 0 { lo.y } else { hi.y },
                if c & 4 == 0 { lo.z } else { hi.z },
            );
            (view_proj * corner.extend(1.0)).w
        });
        let (near, far) = depths.fold((f32::INFINITY, 0.0f32), |(a, b), z| (a.min(z), b.max(z)));
        let extent = (hi - lo).length().max(1e-6);
        let z_near = near.max(extent * 1e-4);
        let z_far = far.max(z_near + extent * 1e-3);
        Self {
            seed: crate::common::random::pcg_hash(seed),
            z_near,
            z_far,
            pixel_area: pixel_area(&view_proj, (view.size[0], view.size[1])),
        }
    }
}

/// Area of a pixel at view depth 1 on a plane facing the eye, `4 tan(fh/2) tan(fv/2) / (W H)`
/// (Eq. 2), read off the projection: rows 0 and 1 of `view_proj` are the view's x and y axes
/// scaled by `1 / tan(f/2)`.
pub fn pixel_area(view_proj: &Mat4, (width, height): (u32, u32)) -> f32 {
    let sx = view_proj.row(0).truncate().length();
    let sy = view_proj.row(1).truncate().length();
    4.0 / (sx * sy * width as f32 * height as f32)
}

/// The gather and the accumulation, created once.
pub(super) struct GatherPass {
    gather_layout: wgpu::BindGroupLayout,
    gather: wgpu::ComputePipeline,
    accumulate_layout: wgpu::BindGroupLayout,
    accumulate: wgpu::ComputePipeline,
}

/// What the gathers read and write at one image size.
pub(super) struct GatherInputs<'a> {
    /// The frame's [`FrameParams`] uniform.
    pub(super) frame_params: &'a wgpu::Buffer,
    pub(super) pyramid: &'a GBufferPyramid,
    /// The light gathered from (each bounce's senders, per level).
    pub(super) light: &'a SignalPyramid,
    /// The solid voxels ([`super::voxels::VoxelGrid::grid`]).
    pub(super) grid: &'a wgpu::Buffer,
    /// The gathered planes per pyramid element.
    pub(super) acc: &'a wgpu::Buffer,
    /// The bounces' sum at the finest gathered level: the filters' input.
    pub(super) summed: &'a wgpu::Buffer,
    /// The test that ends the bounces: a gather reads its state and gathers nothing once
    /// converged.
    pub(super) converge: &'a ConvergeGpu,
}

/// The bind groups of one image size.
pub(super) struct GatherGroups {
    /// Per bounce, per gathered level from the finest.
    gather: Vec<Vec<wgpu::BindGroup>>,
    /// Per bounce.
    accumulate: Vec<wgpu::BindGroup>,
}

impl GatherPass {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let gather_layout = layout::bind_group_layout(
            device,
            "ssil gather",
            &[
                layout::uniform(0, c),
                layout::uniform(1, c),
                layout::uniform(2, c),
                layout::storage(3, true, c),
                layout::storage(4, true, c),
                layout::storage(5, true, c),
                layout::storage(6, true, c),
                layout::storage(7, true, c),
                layout::storage(8, false, c),
                layout::storage(12, true, c),
            ],
        );
        let module = SHADER.create(device);
        let gather = layout::compute_pipeline_entry(
            device,
            "ssil gather",
            &module,
            "gather",
            &[&gather_layout],
        );
        let accumulate_layout = layout::bind_group_layout(
            device,
            "ssil accumulate",
            &[
                layout::uniform(0, c),
                layout::storage(8, false, c),
                layout::storage(9, false, c),
                layout::storage(10, false, c),
                layout::storage(11, true, c),
            ],
        );
        let accumulate = layout::compute_pipeline_entry(
            device,
            "ssil accumulate",
            &module,
            "accumulate",
            &[&accumulate_layout],
        );
        Self {
            gather_layout,
            gather,
            accumulate_layout,
            accumulate,
        }
    }

    /// The bind groups of every bounce of `options` over `levels`.
    pub(super) fn bind(
        &self,
        ctx: &FrameContext,
        options: &SsilOptions,
        levels: &Levels,
        inputs: &GatherInputs,
    ) -> GatherGroups {
        let device = &ctx.device;
        let gather = (0..options.plan().max)
            .map(|bounce| {
                (levels.start..=levels.last)
                    .map(|level| {
                        let p = levels.gather_params(level, bounce, options);
                        let params = uniform_buffer(device, "ssil gather level", &p);
                        layout::bind_group_at(
                            device,
                            "ssil gather",
                            &self.gather_layout,
                            &[
                                (0, params.as_entire_binding()),
                                (1, ctx.view.as_entire_binding()),
                                (2, inputs.frame_params.as_entire_binding()),
                                (3, ctx.scene.materials.as_entire_binding()),
                                (4, inputs.pyramid.position.as_entire_binding()),
                                (5, inputs.pyramid.normal.as_entire_binding()),
                                (6, inputs.light.signal.as_entire_binding()),
                                (7, inputs.grid.as_entire_binding()),
                                (8, inputs.acc.as_entire_binding()),
                                (12, inputs.converge.state().as_entire_binding()),
                            ],
                        )
                    })
                    .collect()
            })
            .collect();
        let accumulate = (0..options.plan().max)
            .map(|bounce| {
                let p = levels.gather_params(levels.start, bounce, options);
                let params = uniform_buffer(device, "ssil accumulate", &p);
                layout::bind_group_at(
                    device,
                    "ssil accumulate",
                    &self.accumulate_layout,
                    &[
                        (0, params.as_entire_binding()),
                        (8, inputs.acc.as_entire_binding()),
                        (9, inputs.summed.as_entire_binding()),
                        (10, inputs.light.signal.as_entire_binding()),
                        (11, inputs.pyramid.albedo.as_entire_binding()),
                    ],
                )
            })
            .collect();
        GatherGroups { gather, accumulate }
    }

    /// Records bounce `bounce`: every level's gather from the coarsest, then the accumulation.
    pub(super) fn run(
        &self,
        frame: &mut FrameEncoder,
        groups: &GatherGroups,
        levels: &Levels,
        bounce: usize,
    ) {
        let mut pass = frame.compute_pass("ssil gather");
        pass.set_pipeline(&self.gather);
        for level in (levels.start..=levels.last).rev() {
            let group = &groups.gather[bounce][(level - levels.start) as usize];
            pass.set_bind_group(0, group, &[]);
            let (x, y) = shaders::groups_2d(levels.pyramid.size(level));
            pass.dispatch_workgroups(x, y, 1);
        }
        pass.set_pipeline(&self.accumulate);
        pass.set_bind_group(0, &groups.accumulate[bounce], &[]);
        let (x, y) = shaders::groups_2d(levels.pyramid.size(levels.start));
        pass.dispatch_workgroups(x, y, 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_layouts_match_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "GatherParams",
            size_of::<GatherParams>(),
            &[
                ("full_size", offset_of!(GatherParams, full_size)),
                ("size", offset_of!(GatherParams, size)),
                ("coarse_size", offset_of!(GatherParams, coarse_size)),
                ("level", offset_of!(GatherParams, level)),
                ("offset", offset_of!(GatherParams, offset)),
                ("coarse_offset", offset_of!(GatherParams, coarse_offset)),
                ("has_coarse", offset_of!(GatherParams, has_coarse)),
                ("samples", offset_of!(GatherParams, samples)),
                ("disc", offset_of!(GatherParams, disc)),
                ("radius", offset_of!(GatherParams, radius)),
                ("visibility", offset_of!(GatherParams, visibility)),
                ("bias", offset_of!(GatherParams, bias)),
                ("grid_offset", offset_of!(GatherParams, grid_offset)),
                ("depth_sigma", offset_of!(GatherParams, depth_sigma)),
                ("normal_power", offset_of!(GatherParams, normal_power)),
                ("bounce", offset_of!(GatherParams, bounce)),
                ("next_bounce", offset_of!(GatherParams, next_bounce)),
                ("pixels", offset_of!(GatherParams, pixels)),
                ("uniform_weight", offset_of!(GatherParams, uniform_weight)),
                ("sample_disc", offset_of!(GatherParams, sample_disc)),
            ],
        );
        crate::shaders::tests::check_struct(
            &module,
            "FrameParams",
            size_of::<FrameParams>(),
            &[
                ("seed", offset_of!(FrameParams, seed)),
                ("z_near", offset_of!(FrameParams, z_near)),
                ("z_far", offset_of!(FrameParams, z_far)),
                ("pixel_area", offset_of!(FrameParams, pixel_area)),
            ],
        );
    }

    #[test]
    fn pixel_area_is_the_frustum_over_the_pixels() {
        let proj =
            glam::camera::rh::proj::directx::perspective(60f32.to_radians(), 4.0 / 3.0, 0.1, 10.0);
        let view =
            glam::camera::rh::view::look_at_mat4(Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO, Vec3::Y);
        let tan = (30f32).to_radians().tan();
        let expected = 4.0 * tan * (tan * 4.0 / 3.0) / (640.0 * 480.0);
        let area = pixel_area(&(proj * view), (640, 480));
        assert!(
            (area - expected).abs() < 1e-6 * expected,
            "{area} {expected}"
        );
    }
}
