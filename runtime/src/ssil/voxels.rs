//! `ssil voxels` and `ssil voxel levels` (`voxels.wgsl`, §4 after Eisemann and Décoret 2008):
//! with `visibility=voxels`, the view frustum's solid voxelisation, [`SLICES`] one-bit slices of
//! view depth per pixel of the first gathered level, each fragment toggling (XOR) its column
//! from its depth on; then each coarser level's columns the AND of their children. CPU twin:
//! the grid as [`super::cpu`]'s march reads it (tests in `tests/gpu/ssil.rs`).

use super::{Levels, uniform_buffer};
use crate::{
    common::layout,
    frame::{FrameContext, FrameEncoder},
    load::SceneGpu,
    shaders,
};

/// `ssil/voxels.wgsl`: the view frustum's solid voxels by XOR (`vs_main`, `fs_main`) and their
/// AND down the levels (`and_down`).
pub const SHADER: shaders::Shader = shaders::shader!("ssil voxels", "ssil/voxels.wgsl");

/// Slices of view depth per voxel column (`voxels.wgsl`: `SLICES`).
pub const SLICES: u32 = 128;

/// `voxels.wgsl`'s `VoxelParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct VoxelParams {
    pub(super) z_near: f32,
    pub(super) z_far: f32,
    pub(super) columns: [u32; 2],
}

/// `voxels.wgsl`'s `AndParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct AndParams {
    fine_size: [u32; 2],
    coarse_size: [u32; 2],
    fine_offset: u32,
    coarse_offset: u32,
    padding: [u32; 2],
}

/// Format of the voxel raster's depth target, which only gives the pass its size (no test, no
/// write).
const VOXEL_TARGET: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The XOR raster and the AND down the levels, created once.
pub(super) struct VoxelPass {
    voxel_layout: wgpu::BindGroupLayout,
    voxels: wgpu::RenderPipeline,
    and_layout: wgpu::BindGroupLayout,
    and_down: wgpu::ComputePipeline,
}

/// The grid of one image size: its columns, the raster's target and the bind groups.
pub(super) struct VoxelGrid {
    /// Four words per column of every gathered level, finest first.
    pub(super) grid: wgpu::Buffer,
    target: wgpu::Texture,
    voxel_group: wgpu::BindGroup,
    and_groups: Vec<wgpu::BindGroup>,
}

impl VoxelPass {
    pub(super) fn new(device: &wgpu::Device) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let vf = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let voxel_layout = layout::bind_group_layout(
            device,
            "ssil voxels",
            &[
                layout::uniform(0, vf),
                layout::uniform(1, wgpu::ShaderStages::FRAGMENT),
                layout::storage(2, true, wgpu::ShaderStages::VERTEX),
                layout::storage(3, false, wgpu::ShaderStages::FRAGMENT),
            ],
        );
        let module = SHADER.create(device);
        let voxels = Self::voxel_raster(device, &voxel_layout, &module);
        let and_layout = layout::bind_group_layout(
            device,
            "ssil voxel levels",
            &[layout::storage(3, false, c), layout::uniform(4, c)],
        );
        let and_down = layout::compute_pipeline_entry(
            device,
            "ssil voxel levels",
            &module,
            "and_down",
            &[&and_layout],
        );
        Self {
            voxel_layout,
            voxels,
            and_layout,
            and_down,
        }
    }

    /// The XOR raster: every triangle, both sides, no depth test, into the grid.
    fn voxel_raster(
        device: &wgpu::Device,
        bind_layout: &wgpu::BindGroupLayout,
        module: &wgpu::ShaderModule,
    ) -> wgpu::RenderPipeline {
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("ssil voxels"),
            bind_group_layouts: &[Some(bind_layout)],
            immediate_size: 0,
        });
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("ssil voxels"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(SceneGpu::VERTEX_LAYOUT)],
            },
            primitive: wgpu::PrimitiveState {
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: VOXEL_TARGET,
                depth_write_enabled: Some(false),
                depth_compare: Some(wgpu::CompareFunction::Always),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[],
            }),
            multiview_mask: None,
            cache: None,
        })
    }

    /// The grid of `levels` over `ctx`'s image, the raster reading `params` (a
    /// [`VoxelParams`] uniform the frame writes).
    pub(super) fn bind(
        &self,
        ctx: &FrameContext,
        levels: &Levels,
        params: &wgpu::Buffer,
    ) -> VoxelGrid {
        let device = &ctx.device;
        let grid = super::storage_buffer(device, "ssil voxels", 16 * u64::from(levels.columns()));
        let target = layout::texture_2d(
            device,
            "ssil voxels target",
            levels.pyramid.size(levels.start),
            VOXEL_TARGET,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let voxel_group = layout::bind_group(
            device,
            "ssil voxels",
            &self.voxel_layout,
            &[
                ctx.view.as_entire_binding(),
                params.as_entire_binding(),
                ctx.scene.motion.as_entire_binding(),
                grid.as_entire_binding(),
            ],
        );
        let and_groups = (levels.start + 1..=levels.last)
            .map(|level| {
                let (fw, fh) = levels.pyramid.size(level - 1);
                let (cw, ch) = levels.pyramid.size(level);
                let params = uniform_buffer(
                    device,
                    "ssil voxel level",
                    &AndParams {
                        fine_size: [fw, fh],
                        coarse_size: [cw, ch],
                        fine_offset: levels.grid_offset(level - 1),
                        coarse_offset: levels.grid_offset(level),
                        padding: [0; 2],
                    },
                );
                layout::bind_group_at(
                    device,
                    "ssil voxel levels",
                    &self.and_layout,
                    &[
                        (3, grid.as_entire_binding()),
                        (4, params.as_entire_binding()),
                    ],
                )
            })
            .collect();
        VoxelGrid {
            grid,
            target,
            voxel_group,
            and_groups,
        }
    }

    /// The XOR raster into the finest gathered level's columns, then the AND down the levels.
    pub(super) fn run(
        &self,
        ctx: &FrameContext,
        frame: &mut FrameEncoder,
        grid: &VoxelGrid,
        levels: &Levels,
    ) {
        frame.encoder.clear_buffer(&grid.grid, 0, None);
        let target = grid.target.create_view(&Default::default());
        {
            let mut pass = frame
                .encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("ssil voxels"),
                    color_attachments: &[],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &target,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(1.0),
                            store: wgpu::StoreOp::Discard,
                        }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: frame.timer.render("ssil voxels"),
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
            let scale = (1u32 << levels.start) as f32;
            let (w, h) = ctx.size();
            pass.set_viewport(0.0, 0.0, w as f32 / scale, h as f32 / scale, 0.0, 1.0);
            pass.set_pipeline(&self.voxels);
            pass.set_bind_group(0, &grid.voxel_group, &[]);
            pass.set_vertex_buffer(0, ctx.scene.vertices.slice(..));
            pass.draw(0..ctx.scene.vertex_count, 0..1);
        }
        if levels.last > levels.start {
            let mut pass = frame.compute_pass("ssil voxel levels");
            pass.set_pipeline(&self.and_down);
            for (level, group) in (levels.start + 1..).zip(&grid.and_groups) {
                pass.set_bind_group(0, group, &[]);
                let (x, y) = shaders::groups_2d(levels.pyramid.size(level));
                pass.dispatch_workgroups(x, y, 1);
            }
        }
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
            "VoxelParams",
            size_of::<VoxelParams>(),
            &[
                ("z_near", offset_of!(VoxelParams, z_near)),
                ("z_far", offset_of!(VoxelParams, z_far)),
                ("columns", offset_of!(VoxelParams, columns)),
            ],
        );
        crate::shaders::tests::check_struct(
            &module,
            "AndParams",
            size_of::<AndParams>(),
            &[
                ("fine_size", offset_of!(AndParams, fine_size)),
                ("coarse_size", offset_of!(AndParams, coarse_size)),
                ("fine_offset", offset_of!(AndParams, fine_offset)),
                ("coarse_offset", offset_of!(AndParams, coarse_offset)),
            ],
        );
    }
}
