//! A scene in GPU memory ([`SceneGpu`]): one vertex per triangle corner with its tangent frame,
//! the materials, and their CPU form ([`cpu_materials`]).

use super::*;

/// The scene's materials as the GPU and the CPU references see them, with their textures
/// (albedo, emission and normals, one array; what [`SceneGpu`] uploads).
///
/// # Errors
/// A texture that cannot be read.
pub fn cpu_materials(
    scene: &Scene,
) -> Result<(Vec<GpuMaterial>, Vec<AlbedoTexture>), RuntimeError> {
    let (textures, layers) = load_textures(scene)?;
    let materials = scene
        .materials
        .iter()
        .zip(&layers)
        .map(|(m, layers)| {
            // The atlas samples no texture: an emission or albedo texture enters it by its
            // mean.
            let times_mean = |value: [f32; 3], layer: i32| match layer {
                -1 => value,
                layer => {
                    let mean = textures[layer as usize].mean();
                    std::array::from_fn(|c| value[c] * mean[c])
                }
            };
            let emission_mean = times_mean(m.emission, layers.emission);
            let kd_mean = times_mean(m.kd, layers.albedo);
            GpuMaterial {
                kd: m.kd,
                ns: m.ns,
                ks: m.ks,
                texture: layers.albedo,
                emission: m.emission,
                emission_texture: layers.emission,
                emission_mean,
                normal_texture: layers.normal,
                kd_mean,
                padding: 0,
            }
        })
        .collect();
    Ok((materials, textures))
}

/// The tangent frame of triangle `t` of `scene` as [`GpuVertex::tangent`] holds it: zero
/// without texture coordinates or with degenerate ones.
pub fn triangle_tangent(scene: &Scene, t: usize) -> [f32; 4] {
    if scene.texcoords.is_empty() {
        return [0.0; 4];
    }
    let uv = scene.triangles[t].map(|v| scene.texcoords[v as usize]);
    crate::normal_map::tangent_frame(scene.triangle(t), uv)
        .map_or([0.0; 4], |(tangent, handedness)| {
            tangent.extend(handedness).to_array()
        })
}

/// A scene in GPU memory: one vertex per triangle corner, materials, textures (albedo and
/// emission).
pub struct SceneGpu {
    /// [`GpuVertex`] buffer, three per triangle.
    pub vertices: wgpu::Buffer,
    /// Number of vertices.
    pub vertex_count: u32,
    /// [`GpuMaterial`] storage buffer.
    pub materials: wgpu::Buffer,
    /// Albedo and emission textures, one layer each (a white 1-layer array when the scene has
    /// none); a material names its layers.
    pub albedo: wgpu::Texture,
    /// View of [`Self::albedo`] as a 2D array.
    pub albedo_view: wgpu::TextureView,
    /// The textures as the CPU reference samples them.
    pub cpu_textures: Vec<AlbedoTexture>,
    /// Materials as uploaded.
    pub cpu_materials: Vec<GpuMaterial>,
    /// Per object of `Scene::objects`, the motion since loading (`mat4x4f`, column-major): the
    /// raster passes draw each vertex at `motion * position` (identity where it was loaded).
    pub motion: wgpu::Buffer,
    /// Every object's object-to-world transform as loaded (`SceneObject::transform`).
    pub load_transforms: Vec<glam::Affine3A>,
}

impl SceneGpu {
    /// Vertex buffer layout of [`GpuVertex`] (locations 0 to 7).
    pub const VERTEX_LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<GpuVertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![
            0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Float32x2, 4 => Uint32, 5 => Uint32,
            6 => Uint32, 7 => Float32x4
        ],
    };

    /// Uploads `scene`; `atlas` (a `.cssm` of the same scene) supplies atlas coordinates.
    ///
    /// # Errors
    /// [`RuntimeError::Texture`] when a `map_Kd` or `map_Ke` cannot be read; [`RuntimeError::Unsupported`]
    /// when `Scene::objects` do not cover the triangles once each.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: &Scene,
        atlas: Option<&CssmFile>,
    ) -> Result<Self, RuntimeError> {
        // A scene built by hand may break the objects' invariants; a loaded one never does.
        if !scene.objects.is_empty() {
            scene
                .check_objects()
                .map_err(|e| RuntimeError::Unsupported(format!("scene '{}': {e}", scene.name)))?;
        }
        let mut vertices = Vec::with_capacity(scene.triangles.len() * 3);
        for (t, tri) in scene.triangles.iter().enumerate() {
            let object = if scene.objects.is_empty() {
                0
            } else {
                scene.object_of(t) as u32
            };
            let [a, b, c] = scene.triangle(t);
            let normal = (b - a).cross(c - a).normalize_or_zero();
            let tangent = triangle_tangent(scene, t);
            for (k, &v) in tri.iter().enumerate() {
                vertices.push(GpuVertex {
                    position: scene.positions[v as usize].to_array(),
                    normal: normal.to_array(),
                    uv: scene.texcoords.get(v as usize).copied().unwrap_or([0.0; 2]),
                    atlas_uv: atlas
                        .and_then(|f| f.triangle_uvs.get(t))
                        .map_or([0.0; 2], |uv| uv[k]),
                    material: scene.triangle_materials[t],
                    triangle: t as u32,
                    object,
                    tangent,
                });
            }
        }
        let vertex_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("scene vertices"),
            contents: bytemuck::cast_slice(&vertices),
            // Storage too: the voxeliser reads the triangles in a compute pass.
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE,
        });
        let (cpu_materials, cpu_textures) = cpu_materials(scene)?;
        let materials = storage_buffer(device, "materials", bytemuck::cast_slice(&cpu_materials));
        let layers = cpu_textures.len().max(1) as u32;
        let side = if cpu_textures.is_empty() {
            1
        } else {
            TEXTURE_SIZE
        };
        let albedo = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("albedo textures"),
            size: wgpu::Extent3d {
                width: side,
                height: side,
                depth_or_array_layers: layers,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let white = [AlbedoTexture {
            texels: vec![[1.0; 3]],
        }];
        let uploads = if cpu_textures.is_empty() {
            &white[..]
        } else {
            &cpu_textures[..]
        };
        for (layer, tex) in uploads.iter().enumerate() {
            let rgba: Vec<f32> = tex
                .texels
                .iter()
                .flat_map(|c| [c[0], c[1], c[2], 1.0])
                .collect();
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &albedo,
                    mip_level: 0,
                    origin: wgpu::Origin3d {
                        x: 0,
                        y: 0,
                        z: layer as u32,
                    },
                    aspect: wgpu::TextureAspect::All,
                },
                bytemuck::cast_slice(&rgba),
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(16 * side),
                    rows_per_image: Some(side),
                },
                wgpu::Extent3d {
                    width: side,
                    height: side,
                    depth_or_array_layers: 1,
                },
            );
        }
        let albedo_view = albedo.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });
        // Every object where it was loaded: the identity motion.
        let object_count = scene.objects.len().max(1);
        let identity = vec![glam::Mat4::IDENTITY.to_cols_array(); object_count];
        let motion = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("object motion"),
            contents: bytemuck::cast_slice(&identity),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        });
        Ok(Self {
            motion,
            load_transforms: scene.objects.iter().map(|o| o.transform).collect(),
            vertices: vertex_buffer,
            vertex_count: vertices.len() as u32,
            materials,
            albedo,
            albedo_view,
            cpu_textures,
            cpu_materials,
        })
    }
}
