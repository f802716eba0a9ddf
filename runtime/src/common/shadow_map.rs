//! Spot-light shadow maps (§4.7): one perspective depth map per light in a texture array, and
//! the PCF lookup `shadow_lookup.wgsl` that shading passes include.

use cssm_formats::{Scene, scene::SpotLight};
use glam::{Mat4, Vec3};

use crate::{RuntimeError, frame::FrameEncoder, gpu_types::GpuSpotLight, load::SceneGpu};

/// Default shadow-map resolution (texels per side).
pub const DEFAULT_RESOLUTION: u32 = 2048;

/// Widest cone a single perspective shadow map covers, degrees (half-angle).
pub const MAX_CUTOFF_DEG: f32 = 80.0;

/// World to shadow-map clip space of `light` for a scene whose bounds are `lo`..`hi`: a
/// perspective frustum one degree wider than the cone on each side.
pub fn light_view_proj(light: &SpotLight, lo: Vec3, hi: Vec3) -> Mat4 {
    let dir = light.direction.normalize();
    let up = if dir.y.abs() > 0.9 { Vec3::Z } else { Vec3::Y };
    let view = glam::camera::rh::view::look_at_mat4(light.position, light.position + dir, up);
    let reach = (0.5 * (lo + hi) - light.position).length() + 0.5 * (hi - lo).length();
    let fov = 2.0 * (light.cutoff_deg + 1.0).to_radians();
    glam::camera::rh::proj::directx::perspective(fov, 1.0, reach * 1e-3, reach * 1.01) * view
}

/// The GPU form of every light of `scene`, shadow maps of `resolution` texels.
///
/// # Errors
/// [`RuntimeError::Unsupported`] for a cone wider than [`MAX_CUTOFF_DEG`].
pub fn gpu_lights(scene: &Scene, resolution: u32) -> Result<Vec<GpuSpotLight>, RuntimeError> {
    let bounds = scene.bounds();
    scene
        .lights
        .iter()
        .map(|l| gpu_light(&scene.name, l, bounds, resolution))
        .collect()
}

/// The GPU form of `light` in the scene `scene_name` whose bounds are `lo`..`hi`.
///
/// # Errors
/// [`RuntimeError::Unsupported`] for a cone wider than [`MAX_CUTOFF_DEG`] or a light that is not
/// finite.
pub fn gpu_light(
    scene_name: &str,
    l: &SpotLight,
    (lo, hi): (Vec3, Vec3),
    resolution: u32,
) -> Result<GpuSpotLight, RuntimeError> {
    if !(l.cutoff_deg > 0.0 && l.cutoff_deg <= MAX_CUTOFF_DEG) {
        return Err(RuntimeError::Unsupported(format!(
            "scene '{scene_name}': spot light cone half-angle {} degrees; the shadow map covers \
             0 to {MAX_CUTOFF_DEG}",
            l.cutoff_deg
        )));
    }
    let finite = l.position.is_finite()
        && l.direction.is_finite()
        && l.direction.length_squared() > 0.0
        && l.intensity.iter().all(|c| c.is_finite());
    if !finite {
        return Err(RuntimeError::Unsupported(format!(
            "scene '{scene_name}': a spot light needs a finite position, intensity and a \
             non-zero direction"
        )));
    }
    let fov = 2.0 * (l.cutoff_deg + 1.0).to_radians();
    // One shadow-map texel spans this much per unit of distance; lifting the lookup by 1.5 of
    // them along the normal keeps lit surfaces from shadowing themselves.
    let texel = 2.0 * (0.5 * fov).tan() / resolution as f32;
    Ok(GpuSpotLight {
        position: l.position.to_array(),
        cos_cutoff: l.cutoff_deg.to_radians().cos(),
        direction: l.direction.normalize().to_array(),
        normal_offset: 1.5 * texel,
        intensity: l.intensity,
        shadow_resolution: resolution as f32,
        view_proj: light_view_proj(l, lo, hi).to_cols_array_2d(),
    })
}

/// One 256-byte-aligned matrix per light, bound with a dynamic offset.
fn transform_bytes(lights: &[GpuSpotLight], stride: u64) -> Vec<u8> {
    let mut bytes = vec![0u8; stride as usize * lights.len()];
    for (i, l) in lights.iter().enumerate() {
        let m = bytemuck::bytes_of(&l.view_proj);
        bytes[i * stride as usize..i * stride as usize + 64].copy_from_slice(m);
    }
    bytes
}

/// Shadow maps of every light, and what shading passes bind to read them.
pub struct ShadowMaps {
    /// Depth array, one layer per light.
    pub texture: wgpu::Texture,
    /// View of it as a 2D array.
    pub view: wgpu::TextureView,
    /// Comparison sampler (less-equal, linear: hardware 2x2 PCF).
    pub sampler: wgpu::Sampler,
    /// [`GpuSpotLight`] storage buffer (at least one entry).
    pub lights: wgpu::Buffer,
    /// Number of lights.
    pub light_count: u32,
    transforms: wgpu::Buffer,
    stride: u64,
    bind_group: wgpu::BindGroup,
    pipeline: wgpu::RenderPipeline,
}

impl ShadowMaps {
    /// Shadow maps for `lights` at `resolution`, of `scene` (its objects where its motion
    /// buffer puts them).
    pub fn new(
        device: &wgpu::Device,
        scene: &SceneGpu,
        lights: &[GpuSpotLight],
        resolution: u32,
    ) -> Self {
        use wgpu::util::DeviceExt;
        let layers = lights.len().max(1) as u32;
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shadow maps"),
            size: wgpu::Extent3d {
                width: resolution,
                height: resolution,
                depth_or_array_layers: layers,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Depth32Float,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow compare"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        let padded: Vec<GpuSpotLight> = if lights.is_empty() {
            vec![GpuSpotLight::default()]
        } else {
            lights.to_vec()
        };
        let light_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("spot lights"),
            contents: bytemuck::cast_slice(&padded),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        });
        // One 256-byte-aligned matrix per light, bound with a dynamic offset.
        let stride = device.limits().min_uniform_buffer_offset_alignment.max(64) as u64;
        let transforms = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("light transforms"),
            contents: &transform_bytes(&padded, stride),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow map"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(64),
                    },
                    count: None,
                },
                crate::common::layout::storage(1, true, wgpu::ShaderStages::VERTEX),
            ],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow map"),
            layout: &layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &transforms,
                        offset: 0,
                        size: wgpu::BufferSize::new(64),
                    }),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: scene.motion.as_entire_binding(),
                },
            ],
        });
        let module = crate::shaders::Shader::ShadowMap.create(device);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("shadow map"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("shadow map"),
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
                bias: wgpu::DepthBiasState {
                    constant: 0,
                    slope_scale: 1.5,
                    clamp: 0.0,
                },
            }),
            multisample: Default::default(),
            fragment: None,
            multiview_mask: None,
            cache: None,
        });
        Self {
            texture,
            view,
            sampler,
            lights: light_buffer,
            light_count: lights.len() as u32,
            transforms,
            stride,
            bind_group,
            pipeline,
        }
    }

    /// Writes moved or changed lights (as many as at creation); the maps are rendered again
    /// by the next [`Self::render`].
    ///
    /// # Panics
    /// When the number of lights differs from the one at creation.
    pub fn update(&self, queue: &wgpu::Queue, lights: &[GpuSpotLight]) {
        assert_eq!(
            lights.len() as u32,
            self.light_count,
            "light count is fixed"
        );
        if lights.is_empty() {
            return;
        }
        queue.write_buffer(&self.lights, 0, bytemuck::cast_slice(lights));
        queue.write_buffer(&self.transforms, 0, &transform_bytes(lights, self.stride));
    }

    /// Records one depth pass per light.
    pub fn render(&self, frame: &mut FrameEncoder, scene: &SceneGpu) {
        for layer in 0..self.light_count {
            let view = self.texture.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2),
                base_array_layer: layer,
                array_layer_count: Some(1),
                ..Default::default()
            });
            let mut pass = frame
                .encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("shadow map"),
                    color_attachments: &[],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &view,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(1.0),
                            store: wgpu::StoreOp::Store,
                        }),
                        stencil_ops: None,
                    }),
                    // Every light's pass is timed under one name; `PassTimer::read` sums them.
                    timestamp_writes: frame.timer.render("shadow maps"),
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[(layer as u64 * self.stride) as u32]);
            pass.set_vertex_buffer(0, scene.vertices.slice(..));
            pass.draw(0..scene.vertex_count, 0..1);
        }
    }
}
