//! Spot-light shadow maps (§4.7): one perspective depth map per light in a texture array, and
//! the PCF lookup `shadow_lookup.wgsl` that shading passes include.
//!
//! When a method reads a reflective shadow map ([`crate::frame::Slot::Rsm`]), the same render
//! of each light's view also writes the RSM (Dachsbacher and Stamminger 2005; Bang 2011 §3.1,
//! §4.2): per texel the world position, the normal turned towards the light and the flux the
//! surface reflects, [`Rsm`]. The shadow lookup and the RSM are one raster of the scene.

use cssm_formats::{Scene, scene::SpotLight};
use glam::{Mat4, Vec3};

use crate::{
    RuntimeError, common::layout, frame::FrameEncoder, gpu_types::GpuSpotLight, load::SceneGpu,
};

/// `common/shadow_map.wgsl`: depth of every light's view (§4.7).
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("shadow map", "common/shadow_map.wgsl");

/// Default shadow-map resolution (texels per side).
pub const DEFAULT_RESOLUTION: u32 = 2048;

/// Widest cone a single perspective shadow map covers, degrees (half-angle).
pub const MAX_CUTOFF_DEG: f32 = cssm_formats::scene::MAX_SPOT_CUTOFF_DEG;

/// Full field of view of the shadow map of a cone of half-angle `cutoff_deg`, radians: one
/// degree wider than the cone on each side.
fn shadow_fov(cutoff_deg: f32) -> f32 {
    2.0 * (cutoff_deg + 1.0).to_radians()
}

/// World to shadow-map clip space of `light` for a scene whose bounds are `lo`..`hi`: a
/// perspective frustum one degree wider than the cone on each side.
pub fn light_view_proj(light: &SpotLight, lo: Vec3, hi: Vec3) -> Mat4 {
    let dir = light.direction.normalize();
    let up = if dir.y.abs() > 0.9 { Vec3::Z } else { Vec3::Y };
    let view = glam::camera::rh::view::look_at_mat4(light.position, light.position + dir, up);
    let reach = (0.5 * (lo + hi) - light.position).length() + 0.5 * (hi - lo).length();
    let fov = shadow_fov(light.cutoff_deg);
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
    let fov = shadow_fov(l.cutoff_deg);
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
        // A pinhole's texel at distance 1 is `texel` wide; its solid angle on the axis.
        texel_solid_angle: texel * texel,
        _pad: [0.0; 3],
    })
}

/// The per-light constants of the raster (`shadow_map.wgsl`: `LightTransform`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct LightTransform {
    view_proj: [[f32; 4]; 4],
    layer: u32,
    _pad: [u32; 3],
}

/// One [`LightTransform`] per light every `stride` bytes, bound with a dynamic offset.
fn transform_bytes(lights: &[GpuSpotLight], stride: u64) -> Vec<u8> {
    let size = std::mem::size_of::<LightTransform>();
    let mut bytes = vec![0u8; stride as usize * lights.len()];
    for (i, l) in lights.iter().enumerate() {
        let transform = LightTransform {
            view_proj: l.view_proj,
            layer: i as u32,
            _pad: [0; 3],
        };
        let at = i * stride as usize;
        bytes[at..at + size].copy_from_slice(bytemuck::bytes_of(&transform));
    }
    bytes
}

/// Format of the RSM targets: positions exact for the CPU references, flux beyond half
/// precision's range (the built-in scenes' lights have intensities of 5e5 W/sr).
pub const RSM_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// The reflective shadow map (Bang 2011 §3.1, Fig. 4.2), one layer per light, written by the
/// shadow-map raster: each texel is a pixel light.
pub struct Rsm {
    /// xyz world position, w 1 where a surface covers the texel (0 elsewhere).
    pub position: wgpu::Texture,
    /// xyz unit normal turned towards the light.
    pub normal: wgpu::Texture,
    /// rgb flux the texel's surface reflects diffusely, W: albedo times the intensity times the
    /// texel's solid angle, zero outside the cone.
    pub flux: wgpu::Texture,
    bind_group: wgpu::BindGroup,
    pipeline: wgpu::RenderPipeline,
}

impl Rsm {
    /// The three targets as 2D-array views (every layer), for the passes that sample them.
    pub fn views(&self) -> [wgpu::TextureView; 3] {
        [&self.position, &self.normal, &self.flux].map(|t| {
            t.create_view(&wgpu::TextureViewDescriptor {
                dimension: Some(wgpu::TextureViewDimension::D2Array),
                ..Default::default()
            })
        })
    }
}

/// A texture array of `layers` layers of `resolution`² in `format`.
fn layered_target(
    device: &wgpu::Device,
    label: &str,
    resolution: u32,
    layers: u32,
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: resolution,
            height: resolution,
            depth_or_array_layers: layers,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    })
}

/// One view of `layer` of `texture`, to render into.
fn layer_view(texture: &wgpu::Texture, layer: u32) -> wgpu::TextureView {
    texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2),
        base_array_layer: layer,
        array_layer_count: Some(1),
        ..Default::default()
    })
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
    /// The reflective shadow map the same raster writes, when asked for at creation.
    pub rsm: Option<Rsm>,
    transforms: wgpu::Buffer,
    stride: u64,
    bind_group: wgpu::BindGroup,
    pipeline: wgpu::RenderPipeline,
}

/// A raster of the scene from the lights: depth only (`fragment` none), or also the RSM.
fn raster_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layouts: &[Option<&wgpu::BindGroupLayout>],
    vertex_entry: &str,
    fragment: Option<wgpu::FragmentState>,
) -> wgpu::RenderPipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("shadow map"),
        bind_group_layouts: layouts,
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("shadow map"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some(vertex_entry),
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
        fragment,
        multiview_mask: None,
        cache: None,
    })
}

impl ShadowMaps {
    /// Shadow maps for `lights` at `resolution`, of `scene` (its objects where its motion
    /// buffer puts them), and the reflective shadow map of the same raster when `rsm`.
    pub fn new(
        device: &wgpu::Device,
        scene: &SceneGpu,
        lights: &[GpuSpotLight],
        resolution: u32,
        rsm: bool,
    ) -> Self {
        use wgpu::util::DeviceExt;
        let layers = lights.len().max(1) as u32;
        let texture = layered_target(
            device,
            "shadow maps",
            resolution,
            layers,
            wgpu::TextureFormat::Depth32Float,
        );
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
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
        });
        // One aligned transform per light, bound with a dynamic offset.
        let alignment = device.limits().min_uniform_buffer_offset_alignment as u64;
        let stride = (std::mem::size_of::<LightTransform>() as u64).next_multiple_of(alignment);
        let transforms = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("light transforms"),
            contents: &transform_bytes(&padded, stride),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let transform_size = std::mem::size_of::<LightTransform>() as u64;
        let stages = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shadow map"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: stages,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: true,
                        min_binding_size: wgpu::BufferSize::new(transform_size),
                    },
                    count: None,
                },
                layout::storage(1, true, wgpu::ShaderStages::VERTEX),
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
                        size: wgpu::BufferSize::new(transform_size),
                    }),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: scene.motion.as_entire_binding(),
                },
            ],
        });
        let module = SHADER.create(device);
        let pipeline = raster_pipeline(device, &module, &[Some(&layout)], "vs_main", None);
        let rsm = rsm.then(|| {
            let fragment = wgpu::ShaderStages::FRAGMENT;
            let rsm_layout = layout::bind_group_layout(
                device,
                "rsm",
                &[
                    layout::storage(0, true, fragment),
                    layout::texture(1, wgpu::TextureViewDimension::D2Array, fragment),
                    layout::storage(2, true, fragment),
                ],
            );
            let bind_group = layout::bind_group(
                device,
                "rsm",
                &rsm_layout,
                &[
                    scene.materials.as_entire_binding(),
                    wgpu::BindingResource::TextureView(&scene.albedo_view),
                    light_buffer.as_entire_binding(),
                ],
            );
            let target = Some(wgpu::ColorTargetState {
                format: RSM_FORMAT,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            });
            let pipeline = raster_pipeline(
                device,
                &module,
                &[Some(&layout), Some(&rsm_layout)],
                "vs_rsm",
                Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some("fs_rsm"),
                    compilation_options: Default::default(),
                    targets: &[target.clone(), target.clone(), target],
                }),
            );
            let [position, normal, flux] = ["rsm position", "rsm normal", "rsm flux"]
                .map(|label| layered_target(device, label, resolution, layers, RSM_FORMAT));
            Rsm {
                position,
                normal,
                flux,
                bind_group,
                pipeline,
            }
        });
        Self {
            texture,
            view,
            sampler,
            lights: light_buffer,
            light_count: lights.len() as u32,
            rsm,
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

    /// Records one raster per light: its depth, and its RSM when there is one.
    pub fn render(&self, frame: &mut FrameEncoder, scene: &SceneGpu) {
        for layer in 0..self.light_count {
            let view = layer_view(&self.texture, layer);
            let rsm_views: Vec<wgpu::TextureView> = match &self.rsm {
                Some(rsm) => [&rsm.position, &rsm.normal, &rsm.flux]
                    .iter()
                    .map(|t| layer_view(t, layer))
                    .collect(),
                None => Vec::new(),
            };
            let colour: Vec<_> = rsm_views.iter().map(layout::cleared_colour).collect();
            let mut pass = frame
                .encoder
                .begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("shadow map"),
                    color_attachments: &colour,
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
            let offset = [(layer as u64 * self.stride) as u32];
            match &self.rsm {
                Some(rsm) => {
                    pass.set_pipeline(&rsm.pipeline);
                    pass.set_bind_group(0, &self.bind_group, &offset);
                    pass.set_bind_group(1, &rsm.bind_group, &[]);
                }
                None => {
                    pass.set_pipeline(&self.pipeline);
                    pass.set_bind_group(0, &self.bind_group, &offset);
                }
            }
            pass.set_vertex_buffer(0, scene.vertices.slice(..));
            pass.draw(0..scene.vertex_count, 0..1);
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn light_transform_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "LightTransform",
            size_of::<super::LightTransform>(),
            &[
                ("view_proj", offset_of!(super::LightTransform, view_proj)),
                ("layer", offset_of!(super::LightTransform, layer)),
            ],
        );
    }
}
