//! The G-buffer raster pass (`gbuffer.wgsl`): per pixel the world position, the normal turned
//! towards the eye, the material, the albedo, the triangle, the atlas coordinates, and the
//! radiance the surface emits towards the eye with the side it is seen from (emission is
//! one-sided: only the front, which the triangle's winding normal faces, emits). Every
//! screen-space pass of every technique reads these.

use crate::{common::layout, frame::FrameEncoder, load::SceneGpu};

/// `common/gbuffer.wgsl` with `common/albedo.wgsl`.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("gbuffer", "common/gbuffer.wgsl");

/// Format of the position, normal and albedo targets (exact positions and normals for the
/// queries that follow).
pub const TARGET_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// Format of the atlas-coordinate target: two exact floats.
pub const ATLAS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rg32Float;

/// Format of the emission target: half floats (to 65,504, a relative step of 1/1024) keep the
/// five targets within the 64 bytes per sample of [`crate::required_limits`].
pub const EMISSION_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// The G-buffer targets and the pass that fills them.
pub struct GBuffer {
    /// xyz world position, w 1 where covered.
    pub position: wgpu::Texture,
    /// xyz normal towards the eye, w material index.
    pub normal: wgpu::Texture,
    /// rgb albedo, w triangle index.
    pub albedo: wgpu::Texture,
    /// xy atlas coordinates (texels).
    pub atlas: wgpu::Texture,
    /// rgb radiance emitted towards the eye (zero where the eye sees a back side), a 1 where the
    /// eye sees the front side (the side the winding normal faces), 0 the back.
    pub emission: wgpu::Texture,
    depth: wgpu::Texture,
    pipeline: wgpu::RenderPipeline,
    bind_group: wgpu::BindGroup,
}

fn target(
    device: &wgpu::Device,
    label: &str,
    w: u32,
    h: u32,
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    let usage = wgpu::TextureUsages::RENDER_ATTACHMENT
        | wgpu::TextureUsages::TEXTURE_BINDING
        | wgpu::TextureUsages::COPY_SRC;
    layout::texture_2d(device, label, (w, h), format, usage)
}

/// The five colour targets and the depth buffer of `width` x `height`.
fn targets(device: &wgpu::Device, width: u32, height: u32) -> [wgpu::Texture; 6] {
    [
        target(device, "gbuffer position", width, height, TARGET_FORMAT),
        target(device, "gbuffer normal", width, height, TARGET_FORMAT),
        target(device, "gbuffer albedo", width, height, TARGET_FORMAT),
        target(device, "gbuffer atlas", width, height, ATLAS_FORMAT),
        target(device, "gbuffer emission", width, height, EMISSION_FORMAT),
        target(
            device,
            "gbuffer depth",
            width,
            height,
            wgpu::TextureFormat::Depth32Float,
        ),
    ]
}

impl GBuffer {
    /// Targets of `width` x `height` for `scene`, reading the view constants from `view`.
    pub fn new(
        device: &wgpu::Device,
        scene: &SceneGpu,
        view: &wgpu::Buffer,
        width: u32,
        height: u32,
    ) -> Self {
        let module = SHADER.create(device);
        let fragment = wgpu::ShaderStages::FRAGMENT;
        let bind_layout = layout::bind_group_layout(
            device,
            "gbuffer",
            &[
                layout::uniform(0, wgpu::ShaderStages::VERTEX_FRAGMENT),
                layout::storage(1, true, fragment),
                layout::texture(2, wgpu::TextureViewDimension::D2Array, fragment),
                layout::storage(3, true, wgpu::ShaderStages::VERTEX),
            ],
        );
        let bind_group = layout::bind_group(
            device,
            "gbuffer",
            &bind_layout,
            &[
                view.as_entire_binding(),
                scene.materials.as_entire_binding(),
                wgpu::BindingResource::TextureView(&scene.albedo_view),
                scene.motion.as_entire_binding(),
            ],
        );
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("gbuffer"),
            bind_group_layouts: &[Some(&bind_layout)],
            immediate_size: 0,
        });
        let color = |format| {
            Some(wgpu::ColorTargetState {
                format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })
        };
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("gbuffer"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(SceneGpu::VERTEX_LAYOUT)],
            },
            primitive: wgpu::PrimitiveState {
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: wgpu::TextureFormat::Depth32Float,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[
                    color(TARGET_FORMAT),
                    color(TARGET_FORMAT),
                    color(TARGET_FORMAT),
                    color(ATLAS_FORMAT),
                    color(EMISSION_FORMAT),
                ],
            }),
            multiview_mask: None,
            cache: None,
        });
        let [position, normal, albedo, atlas, emission, depth] = targets(device, width, height);
        Self {
            position,
            normal,
            albedo,
            atlas,
            emission,
            depth,
            pipeline,
            bind_group,
        }
    }

    /// New targets of `width` x `height`; the pipeline stays.
    pub fn resize(&mut self, device: &wgpu::Device, width: u32, height: u32) {
        [
            self.position,
            self.normal,
            self.albedo,
            self.atlas,
            self.emission,
            self.depth,
        ] = targets(device, width, height);
    }

    /// Image width and height.
    pub fn size(&self) -> (u32, u32) {
        (self.position.width(), self.position.height())
    }

    /// Records the raster pass.
    pub fn render(&self, frame: &mut FrameEncoder, scene: &SceneGpu) {
        let views: Vec<wgpu::TextureView> = [
            &self.position,
            &self.normal,
            &self.albedo,
            &self.atlas,
            &self.emission,
        ]
        .iter()
        .map(|t| t.create_view(&Default::default()))
        .collect();
        let depth = self.depth.create_view(&Default::default());
        let attachments: Vec<_> = views.iter().map(layout::cleared_colour).collect();
        let mut pass = frame
            .encoder
            .begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("gbuffer"),
                color_attachments: &attachments,
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: frame.timer.render("gbuffer"),
                occlusion_query_set: None,
                multiview_mask: None,
            });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_vertex_buffer(0, scene.vertices.slice(..));
        pass.draw(0..scene.vertex_count, 0..1);
    }
}
