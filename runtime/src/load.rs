//! Loaders: a `.cssm` file into GPU storage buffers ([`CssmGpu`], the run data kept in its
//! random-access layout, never decompressed), and a scene into vertex buffers, materials and
//! textures, albedo and emission ([`SceneGpu`]). Both take a plain `&wgpu::Device` and
//! `&wgpu::Queue`, so they work inside a user's own renderer.

use std::path::Path;

use cssm_formats::{CssmFile, Scene, TextureSource, cssm, visibility::QueryOptions};
use glam::Vec3;
use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    gpu_types::{GpuCssmParams, GpuMaterial, GpuTexel, GpuVertex},
};

/// Reads a `.cssm` file and checks that it was baked from `scene` (same content hash and
/// triangle count).
///
/// # Errors
/// [`RuntimeError::Cssm`] for an unreadable, corrupt or invalid file (the error names it),
/// [`RuntimeError::SceneMismatch`] when it belongs to another scene or another version of it.
pub fn read_cssm(path: &Path, scene: &Scene) -> Result<CssmFile, RuntimeError> {
    let file = cssm::read(path)?;
    check_scene(path, &file, scene)?;
    Ok(file)
}

/// Checks that `file` (read from `path`) was baked from `scene`: the same triangle count and
/// content hash, and every index into the scene in range
/// ([`cssm_formats::cssm::validate_for_scene`]).
///
/// # Errors
/// [`RuntimeError::SceneMismatch`] saying whether the file comes from another scene or the
/// scene's files changed since the bake; [`RuntimeError::Cssm`] for an index out of range.
pub fn check_scene(path: &Path, file: &CssmFile, scene: &Scene) -> Result<(), RuntimeError> {
    let mismatch = |reason: String| RuntimeError::SceneMismatch {
        path: path.to_path_buf(),
        reason,
    };
    let same_name = file.scene.name == scene.name;
    let other_scene = || {
        format!(
            "it was baked from the scene '{}' ({} triangles, in {}), this is '{}' ({} triangles)",
            file.scene.name,
            file.scene.triangle_count,
            file.scene.dir,
            scene.name,
            scene.triangles.len()
        )
    };
    if file.scene.triangle_count as usize != scene.triangles.len() {
        return Err(mismatch(if same_name {
            format!(
                "the scene '{}' has {} triangles now, {} when baked",
                scene.name,
                scene.triangles.len(),
                file.scene.triangle_count
            )
        } else {
            other_scene()
        }));
    }
    if file.scene.content_hash != scene.content_hash {
        return Err(mismatch(if same_name {
            format!("the files of scene '{}' changed since the bake", scene.name)
        } else {
            other_scene()
        }));
    }
    cssm::validate_for_scene(file, scene).map_err(|e| {
        RuntimeError::Cssm(cssm::CssmError::File {
            path: path.to_path_buf(),
            inner: Box::new(e),
        })
    })
}

/// The most bytes one storage binding of a device of `limits` can hold: the binding limit,
/// and no more than a buffer may be.
pub fn storage_binding_bytes(limits: &wgpu::Limits) -> u64 {
    limits
        .max_storage_buffer_binding_size
        .min(limits.max_buffer_size)
}

pub(crate) fn limit_check(
    device: &wgpu::Device,
    what: &'static str,
    bytes: u64,
) -> Result<(), RuntimeError> {
    let limit = storage_binding_bytes(&device.limits());
    if bytes > limit {
        return Err(RuntimeError::TooLarge {
            what,
            needed: bytes,
            limit,
        });
    }
    Ok(())
}

/// Whether a device of `limits` can bind run data spanning `run_bindings` storage bindings
/// (`run_bytes` in all): at most [`MAX_RUN_BINDINGS`], and the passes that query the CSSM
/// (the radiosity gather binds the most: [`crate::required_limits`]) still within the
/// device's storage buffers per shader stage.
fn check_run_bindings(
    limits: &wgpu::Limits,
    run_bindings: u32,
    run_bytes: u64,
) -> Result<(), RuntimeError> {
    let binding = storage_binding_bytes(limits);
    if run_bindings > MAX_RUN_BINDINGS {
        return Err(RuntimeError::Unsupported(format!(
            "the runs need {run_bytes} bytes, more than {MAX_RUN_BINDINGS} storage bindings of \
             {binding} bytes (the GPU's limit per binding) hold; bake at a smaller atlas or cube"
        )));
    }
    let needed = crate::required_limits().max_storage_buffers_per_shader_stage + run_bindings - 1;
    if run_bindings > 1 && limits.max_storage_buffers_per_shader_stage < needed {
        return Err(RuntimeError::Unsupported(format!(
            "the runs need {run_bytes} bytes, spread over {run_bindings} storage bindings of \
             {binding} bytes (the GPU's limit per binding); the passes that query them would \
             bind {needed} storage buffers per shader stage, the GPU allows {}",
            limits.max_storage_buffers_per_shader_stage
        )));
    }
    Ok(())
}

/// A storage buffer holding `data` (at least 16 bytes: empty bindings are not allowed).
pub(crate) fn storage_buffer(device: &wgpu::Device, label: &str, data: &[u8]) -> wgpu::Buffer {
    let mut padded;
    let contents = if data.len() < 16 {
        padded = data.to_vec();
        padded.resize(16, 0);
        &padded[..]
    } else {
        data
    };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    })
}

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

/// A `.cssm` file in GPU memory: the query constants, the texel table, the atlas grid, the
/// triangles' atlas coordinates and the run data, bound as one bind group that the WGSL library
/// ([`crate::visibility::library_wgsl`]) reads.
pub struct CssmGpu {
    /// Query constants (uniform, binding 0).
    pub params_buffer: wgpu::Buffer,
    /// [`GpuTexel`] per defined texel (binding 1).
    pub texels: wgpu::Buffer,
    /// Texel index of every atlas cell (binding 2).
    pub grid: wgpu::Buffer,
    /// Six floats per triangle (binding 3).
    pub triangle_uvs: wgpu::Buffer,
    /// Run offsets (binding 4).
    pub offsets: wgpu::Buffer,
    /// The runs, in order: binding 5, then 6, 7, ... when they exceed one storage binding
    /// ([`Self::run_bindings`] buffers of [`GpuCssmParams::runs_per_binding`] runs, the last
    /// one the rest).
    pub runs: Vec<wgpu::Buffer>,
    /// Storage bindings the runs span (1 unless they exceed the device's
    /// `max_storage_buffer_binding_size`; at most [`MAX_RUN_BINDINGS`]). The modules that
    /// import the query are composed for it ([`crate::shaders::Shader::create_for`]).
    pub run_bindings: u32,
    /// Layout of [`Self::bind_group`].
    pub bind_group_layout: wgpu::BindGroupLayout,
    /// The bind group.
    pub bind_group: wgpu::BindGroup,
    /// The constants as uploaded.
    pub params: GpuCssmParams,
    /// Bytes of the run data on the GPU (offsets + runs), the figure of the compression tables.
    pub run_bytes: u64,
    /// Steps of the query's search over one pixel's runs: the bit length of this file's longest
    /// run list ([`crate::shaders::search_steps`]).
    pub search_steps: u32,
    /// The query's search compiles as a loop ([`crate::shaders::search_loop_allowed`] on the
    /// device it was loaded on; a test may set it to build the looped form on llvmpipe, whose
    /// loop limit only long gathers reach).
    pub search_loop: bool,
}

/// Most storage bindings the runs of one `.cssm` may span (`CSSM_RUN_BINDINGS` in
/// `visibility/cssm.wgsl`): 1 GiB of runs at WebGPU's default 128 MiB per binding.
pub const MAX_RUN_BINDINGS: u32 = 8;

/// How the runs of `run_count` runs are spread over storage bindings on a device whose buffers
/// may bind at most `binding_bytes`: (runs per binding, bindings). The runs are cut at any
/// index, not at segment or pixel boundaries: the query finds a run's binding from its index
/// alone (`cssm_run` in `visibility/cssm.wgsl`).
pub fn run_split(run_count: u64, binding_bytes: u64) -> (u32, u32) {
    let per_binding = (binding_bytes / 4).clamp(1, u64::from(u32::MAX));
    let bindings = run_count.div_ceil(per_binding).max(1);
    (per_binding as u32, bindings.min(u64::from(u32::MAX)) as u32)
}

impl CssmGpu {
    /// Bind group layout entries of the CSSM bind group, visible to `stages`, for run data
    /// spanning `run_bindings` storage bindings ([`Self::run_bindings`]).
    pub fn layout_entries(
        stages: wgpu::ShaderStages,
        run_bindings: u32,
    ) -> Vec<wgpu::BindGroupLayoutEntry> {
        let storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: stages,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        [
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: stages,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            },
            storage(1),
            storage(2),
            storage(3),
            storage(4),
        ]
        .into_iter()
        .chain((0..run_bindings.max(1)).map(|k| storage(5 + k)))
        .collect()
    }

    /// The WGSL visibility library for this file's layout, its bindings at `@group(group)`:
    /// [`crate::visibility::library_wgsl`] with [`Self::shape`].
    pub fn library_wgsl(&self, group: u32) -> String {
        crate::visibility::library_wgsl(group, self.shape())
    }

    /// How the modules that import the query are composed for this file
    /// ([`crate::shaders::Shader::create_for`]).
    pub fn shape(&self) -> crate::shaders::CssmShape {
        crate::shaders::CssmShape {
            run_bindings: self.run_bindings,
            search_steps: self.search_steps,
            search_loop: self.search_loop,
            counters: false,
        }
    }

    /// Uploads `file` (which `cssm::read` or `cssm::decode` validated) with query `options`.
    ///
    /// Runs larger than one storage binding spread over several (up to [`MAX_RUN_BINDINGS`]);
    /// the other tables must each fit one.
    ///
    /// # Errors
    /// [`RuntimeError::TooLarge`] when a table other than the runs exceeds the device's storage
    /// binding limit, [`RuntimeError::Unsupported`] when the runs need more than
    /// [`MAX_RUN_BINDINGS`] bindings or more storage buffers per shader stage than the device
    /// allows.
    ///
    /// # Example
    /// ```no_run
    /// # fn demo(device: &wgpu::Device, queue: &wgpu::Queue) -> Result<(), Box<dyn std::error::Error>> {
    /// use cssm_runtime::load::CssmGpu;
    /// let scene = cssm_formats::Scene::load("scenes/cornell-box".as_ref())?;
    /// let file = cssm_runtime::load::read_cssm("cornell-box.cssm".as_ref(), &scene)?;
    /// let cssm = CssmGpu::new(device, queue, &file, Default::default())?;
    /// // Bind `cssm.bind_group` at group 1 of your pipeline and prepend the library:
    /// let source = cssm.library_wgsl(1) + "/* your shader calling cssm_visible(...) */";
    /// # let _ = (cssm, source); Ok(()) }
    /// ```
    pub fn new(
        device: &wgpu::Device,
        _queue: &wgpu::Queue,
        file: &CssmFile,
        options: QueryOptions,
    ) -> Result<Self, RuntimeError> {
        let r = file.params.atlas_resolution;
        let mut map_of_texel = vec![0u32; file.texels.len()];
        for (k, &t) in file.sequence.iter().enumerate() {
            map_of_texel[t as usize] = k as u32;
        }
        let mut grid = vec![u32::MAX; (r * r) as usize];
        let texels: Vec<GpuTexel> = file
            .texels
            .iter()
            .enumerate()
            .map(|(i, t)| {
                grid[t.y as usize * r as usize + t.x as usize] = i as u32;
                GpuTexel {
                    position: t.position,
                    area: t.area,
                    normal: t.normal,
                    chart: t.chart,
                    map: map_of_texel[i],
                    material: t.material,
                    x: t.x as u32,
                    y: t.y as u32,
                    object: t.object,
                    _pad: [0; 3],
                }
            })
            .collect();
        let uvs: Vec<f32> = file
            .triangle_uvs
            .iter()
            .flat_map(|c| [c[0][0], c[0][1], c[1][0], c[1][1], c[2][0], c[2][1]])
            .collect();
        let limits = device.limits();
        let binding_bytes = storage_binding_bytes(&limits);
        let (runs_per_binding, run_bindings) =
            run_split(file.runs.runs.len() as u64, binding_bytes);
        check_run_bindings(&limits, run_bindings, 4 * file.runs.runs.len() as u64)?;
        let p = &file.params;
        let params = GpuCssmParams {
            atlas_resolution: r,
            cube_resolution: p.cube_resolution,
            map_count: file.runs.map_count,
            pixel_count: file.runs.pixel_count,
            near: p.near,
            far: p.far,
            // The same f32 expression as `DepthQuantizer::new`, so depths decode identically.
            depth_scale: cssm_formats::cube::DEPTH_MAX as f32 / (p.far - p.near),
            bias_near: options.bias_near,
            bias_relative: options.bias_relative,
            flags: u32::from(options.pcf)
                | (u32::from(options.sender_filter) << 1)
                | (u32::from(options.both_ends) << 2)
                | (u32::from(file.pixel_grid == cssm_formats::cube::PixelGrid::Staggered) << 3)
                | (u32::from(file.cube_frame == cssm_formats::cube::CubeFrame::Turned) << 4),
            triangle_count: file.triangle_uvs.len() as u32,
            runs_per_binding,
        };
        let texel_bytes: &[u8] = bytemuck::cast_slice(&texels);
        limit_check(device, "the texel table", texel_bytes.len() as u64)?;
        limit_check(
            device,
            "the run offsets",
            4 * file.runs.offsets.len() as u64,
        )?;
        limit_check(
            device,
            "the triangle atlas coordinates",
            4 * uvs.len() as u64,
        )?;
        let params_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("cssm params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let texels = storage_buffer(device, "cssm texels", texel_bytes);
        let grid = storage_buffer(device, "cssm grid", bytemuck::cast_slice(&grid));
        let triangle_uvs = storage_buffer(device, "cssm triangle uvs", bytemuck::cast_slice(&uvs));
        let offsets = storage_buffer(
            device,
            "cssm offsets",
            bytemuck::cast_slice(&file.runs.offsets),
        );
        let runs: Vec<wgpu::Buffer> = if file.runs.runs.is_empty() {
            vec![storage_buffer(device, "cssm runs", &[])]
        } else {
            file.runs
                .runs
                .chunks(runs_per_binding as usize)
                .map(|part| storage_buffer(device, "cssm runs", bytemuck::cast_slice(part)))
                .collect()
        };
        let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cssm"),
            entries: &Self::layout_entries(
                wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::FRAGMENT,
                run_bindings,
            ),
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("cssm"),
            layout: &bind_group_layout,
            entries: &[
                params_buffer.as_entire_binding(),
                texels.as_entire_binding(),
                grid.as_entire_binding(),
                triangle_uvs.as_entire_binding(),
                offsets.as_entire_binding(),
            ]
            .into_iter()
            .chain(runs.iter().map(wgpu::Buffer::as_entire_binding))
            .enumerate()
            .map(|(i, resource)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource,
            })
            .collect::<Vec<_>>(),
        });
        Ok(Self {
            params_buffer,
            texels,
            grid,
            triangle_uvs,
            offsets,
            runs,
            run_bindings,
            bind_group_layout,
            bind_group,
            params,
            run_bytes: file.runs.gpu_bytes(),
            search_steps: crate::shaders::search_steps(&file.runs),
            search_loop: crate::shaders::search_loop_allowed(device),
        })
    }
}

/// Side of the square textures on the GPU: every `map_Kd` and `map_Ke` is resampled to it so
/// that all fit one texture array.
pub const TEXTURE_SIZE: u32 = 512;

/// A texture (albedo or emission) resampled to [`TEXTURE_SIZE`], linear RGB (the CPU
/// references sample it).
#[derive(Clone, Debug)]
pub struct AlbedoTexture {
    /// Row-major texels, linear RGB.
    pub texels: Vec<[f32; 3]>,
}

impl AlbedoTexture {
    /// Bilinear sample with repeat wrapping at texture coordinates `uv` (v up, as in OBJ), the
    /// same filter `albedo_sample` in `common/albedo.wgsl` applies.
    pub fn sample(&self, uv: [f32; 2]) -> Vec3 {
        let s = TEXTURE_SIZE as f32;
        let x = uv[0] * s - 0.5;
        let y = (1.0 - uv[1]) * s - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: f32, yi: f32| {
            let n = TEXTURE_SIZE as i64;
            let (xi, yi) = ((xi as i64).rem_euclid(n), (yi as i64).rem_euclid(n));
            Vec3::from(self.texels[(yi * n + xi) as usize])
        };
        at(x0, y0) * (1.0 - fx) * (1.0 - fy)
            + at(x0 + 1.0, y0) * fx * (1.0 - fy)
            + at(x0, y0 + 1.0) * (1.0 - fx) * fy
            + at(x0 + 1.0, y0 + 1.0) * fx * fy
    }

    /// Mean of the texels, linear RGB (the texture's mean over its area, which bilinear
    /// filtering with repeat wrapping keeps).
    pub fn mean(&self) -> [f32; 3] {
        let sum = self
            .texels
            .iter()
            .fold(glam::DVec3::ZERO, |acc, t| acc + Vec3::from(*t).as_dvec3());
        (sum / self.texels.len().max(1) as f64).as_vec3().to_array()
    }
}

/// A material's layers in the texture array, -1 for none.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TextureLayers {
    /// Albedo texture (`map_Kd`, glTF `baseColorTexture`).
    pub albedo: i32,
    /// Emission texture (`map_Ke`, glTF `emissiveTexture`).
    pub emission: i32,
    /// Tangent-space normals (MTL `norm`, glTF `normalTexture`, or MTL `bump` turned into
    /// normals; [`crate::normal_map`]).
    pub normal: i32,
}

/// How an image becomes a layer: the same image may be two layers (an albedo texture used as
/// a height map too, or a height map at two multipliers).
#[derive(Clone, Copy, Debug, PartialEq)]
enum LayerKind {
    /// sRGB colours decoded to linear (albedo, emission).
    Colour,
    /// A height map turned into normals at this bump multiplier.
    Height(f32),
    /// A tangent-space normal map at this scale.
    Normal(f32),
}

/// Reads every material's textures (albedo: `map_Kd`, glTF `baseColorTexture`; emission:
/// `map_Ke`, glTF `emissiveTexture`; normals: `Material::normal_map`), each image once per way
/// it is read, resampled to [`TEXTURE_SIZE`]; returns the textures (one array for all kinds,
/// normals as unit vectors, see [`crate::normal_map`]) and each material's layers.
///
/// # Errors
/// [`RuntimeError::Texture`] for an image that cannot be read, naming its file.
pub fn load_textures(
    scene: &Scene,
) -> Result<(Vec<AlbedoTexture>, Vec<TextureLayers>), RuntimeError> {
    use cssm_formats::NormalMapKind;
    let mut textures = Vec::new();
    let mut sources: Vec<(&TextureSource, LayerKind)> = Vec::new();
    let mut layers = Vec::with_capacity(scene.materials.len());
    for m in &scene.materials {
        let normal = m.normal_map.as_ref().map(|n| {
            let kind = match n.kind {
                NormalMapKind::Height { multiplier } => LayerKind::Height(multiplier),
                NormalMapKind::Tangent { scale } => LayerKind::Normal(scale),
            };
            (&n.source, kind)
        });
        let wanted = [
            m.map_kd.as_ref().map(|s| (s, LayerKind::Colour)),
            m.map_emission.as_ref().map(|s| (s, LayerKind::Colour)),
            normal,
        ];
        let mut layer = [-1i32; 3];
        for (slot, wanted) in layer.iter_mut().zip(wanted) {
            let Some((source, kind)) = wanted else {
                continue;
            };
            *slot = match sources.iter().position(|s| *s == (source, kind)) {
                Some(i) => i as i32,
                None => {
                    let texels = match kind {
                        LayerKind::Colour => decode_texture(source)?,
                        LayerKind::Height(multiplier) => {
                            let grey: Vec<f32> = decode_image(source, "bump map")?
                                .iter()
                                .map(|c| (c[0] + c[1] + c[2]) / 3.0)
                                .collect();
                            crate::normal_map::height_to_normals(&grey, multiplier)
                        }
                        LayerKind::Normal(scale) => crate::normal_map::decode_normals(
                            &decode_image(source, "normal map")?,
                            scale,
                        ),
                    };
                    sources.push((source, kind));
                    textures.push(AlbedoTexture { texels });
                    textures.len() as i32 - 1
                }
            };
        }
        layers.push(TextureLayers {
            albedo: layer[0],
            emission: layer[1],
            normal: layer[2],
        });
    }
    Ok((textures, layers))
}

/// Decodes the image of `source` and resamples it to [`TEXTURE_SIZE`]² texels, linear RGB
/// (the image is sRGB-encoded, as `map_Kd` and `map_Ke` files and glTF colour and emissive
/// textures are).
///
/// # Errors
/// [`RuntimeError::Texture`] naming the file (or the scene file that embeds the image) when it
/// cannot be read or decoded.
pub fn decode_texture(source: &TextureSource) -> Result<Vec<[f32; 3]>, RuntimeError> {
    // Linear before resampling: an sRGB-space filter darkens every edge between light and dark
    // (a stripe of sRGB 255 and 0 resampled there keeps a linear mean of 0.36, not 0.5), and the
    // atlas takes a texture by its mean (`GpuMaterial::kd_mean`).
    resampled(source, "", srgb_to_linear)
}

/// Decodes the image of `source` and resamples it to [`TEXTURE_SIZE`]² texels, each channel
/// as stored, in `[0, 1]` (no transfer function: height and normal maps hold values, not
/// colours). `what` ("normal map", ...; empty for a colour texture) prefixes the reason of an
/// error.
///
/// # Errors
/// [`RuntimeError::Texture`] naming the file (or the scene file that embeds the image) when it
/// cannot be read or decoded.
pub fn decode_image(source: &TextureSource, what: &str) -> Result<Vec<[f32; 3]>, RuntimeError> {
    resampled(source, what, |c| c)
}

/// The image of `source`, each channel in `[0, 1]` through `transfer`, then resampled to
/// [`TEXTURE_SIZE`]² texels (16 bits per channel while resampling).
fn resampled(
    source: &TextureSource,
    what: &str,
    transfer: fn(f32) -> f32,
) -> Result<Vec<[f32; 3]>, RuntimeError> {
    let texture_error = |reason: String| {
        let reason = if what.is_empty() {
            reason
        } else {
            format!("{what}: {reason}")
        };
        RuntimeError::Texture {
            path: source.origin().to_path_buf(),
            reason: match source {
                TextureSource::File(_) => reason,
                TextureSource::Embedded { label, .. } => format!("{label}: {reason}"),
            },
        }
    };
    // Decoded within image's default limits (512 MiB of allocation).
    let img = match source {
        TextureSource::File(path) => {
            // A regular file only (a FIFO would hang the decoder's open).
            let (file, _) = cssm_formats::files::open_regular(path)
                .map_err(|e| texture_error(e.to_string()))?;
            // The format from the extension, as `image::open` does; from the contents otherwise.
            let mut reader = image::ImageReader::new(std::io::BufReader::new(file));
            match image::ImageFormat::from_path(path) {
                Ok(format) => reader.set_format(format),
                Err(_) => {
                    reader = reader
                        .with_guessed_format()
                        .map_err(|e| texture_error(e.to_string()))?;
                }
            }
            reader.decode()
        }
        TextureSource::Embedded { bytes, mime, .. } => {
            let mut reader = image::ImageReader::new(std::io::Cursor::new(&bytes[..]));
            match mime.as_deref().and_then(image::ImageFormat::from_mime_type) {
                Some(format) => reader.set_format(format),
                None => {
                    reader = reader
                        .with_guessed_format()
                        .map_err(|e| texture_error(e.to_string()))?;
                }
            }
            reader.decode()
        }
    }
    .map_err(|e| texture_error(e.to_string()))?;
    let table: Vec<u16> = (0..=255u8)
        .map(|c| (transfer(f32::from(c) / 255.0).clamp(0.0, 1.0) * 65535.0).round() as u16)
        .collect();
    let wide = reduced_wide(&img, &table);
    drop(img);
    let resized = image::imageops::resize(
        &wide,
        TEXTURE_SIZE,
        TEXTURE_SIZE,
        image::imageops::FilterType::Triangle,
    );
    Ok(resized
        .pixels()
        .map(|p| p.0.map(|c| f32::from(c) / 65535.0))
        .collect())
}

/// A side above which an image is first reduced by whole box factors ([`reduced_wide`]).
const REDUCE_ABOVE: u32 = 2 * TEXTURE_SIZE;

/// `img` through `table` (8-bit channel to 16-bit value) as 16-bit RGB. An image wider or
/// taller than [`REDUCE_ABOVE`] is reduced on the way by whole factors that keep it at least
/// that size, averaging each box after the table (so in linear space), a stripe of rows at a
/// time: a 23000² texture costs its decode and a few megabytes, not two full-size copies.
fn reduced_wide(
    img: &image::DynamicImage,
    table: &[u16],
) -> image::ImageBuffer<image::Rgb<u16>, Vec<u16>> {
    use image::GenericImageView;
    let (w, h) = img.dimensions();
    let (kx, ky) = ((w / REDUCE_ABOVE).max(1), (h / REDUCE_ABOVE).max(1));
    if kx == 1 && ky == 1 {
        let rgb = img.to_rgb8();
        return image::ImageBuffer::from_fn(w, h, |x, y| {
            image::Rgb(rgb.get_pixel(x, y).0.map(|c| table[c as usize]))
        });
    }
    let (nw, nh) = (w.div_ceil(kx), h.div_ceil(ky));
    let mut sums = vec![[0u64; 3]; nw as usize * nh as usize];
    let mut counts = vec![0u32; nw as usize * nh as usize];
    for row in 0..nh {
        let y0 = row * ky;
        let stripe = img.crop_imm(0, y0, w, ky.min(h - y0)).to_rgb8();
        for (x, _, p) in stripe.enumerate_pixels() {
            let i = (row * nw + x / kx) as usize;
            for (sum, c) in sums[i].iter_mut().zip(p.0) {
                *sum += u64::from(table[c as usize]);
            }
            counts[i] += 1;
        }
    }
    image::ImageBuffer::from_fn(nw, nh, |x, y| {
        let i = (y * nw + x) as usize;
        let n = u64::from(counts[i].max(1));
        image::Rgb(sums[i].map(|s| ((s + n / 2) / n) as u16))
    })
}

/// The sRGB transfer function, inverted.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A texture far larger than the renderer's is reduced in linear space, a stripe at a
    /// time, to the mean the full-size path gives (issue 53, class 5).
    #[test]
    fn a_huge_texture_is_reduced_in_stripes_to_the_same_linear_mean() {
        // A checkerboard of sRGB 255 and 64: its linear mean is the mean of the two linear
        // values (averaging in sRGB first would give a darker one).
        let (w, h) = (3 * REDUCE_ABOVE + 5, REDUCE_ABOVE + 3);
        let img = image::RgbImage::from_fn(w, h, |x, y| {
            image::Rgb(if (x + y) % 2 == 0 { [255; 3] } else { [64; 3] })
        });
        let table: Vec<u16> = (0..=255u8)
            .map(|c| (srgb_to_linear(f32::from(c) / 255.0) * 65535.0).round() as u16)
            .collect();
        let reduced = reduced_wide(&image::DynamicImage::ImageRgb8(img), &table);
        assert_eq!(reduced.dimensions(), (w.div_ceil(3), h));
        let mean = |v: &[u16]| v.iter().map(|&c| f64::from(c)).sum::<f64>() / v.len() as f64;
        let expected = 0.5 * (f64::from(table[255]) + f64::from(table[64]));
        assert!(
            (mean(reduced.as_raw()) - expected).abs() < 0.01 * expected,
            "{} vs {expected}",
            mean(reduced.as_raw())
        );
    }

    /// A textured material reflects in the atlas Kd times its texture's linear mean (the
    /// G-buffer and the path tracer see Kd times the texture); an untextured one its Kd.
    #[test]
    fn the_atlas_albedo_of_a_textured_material_is_kd_times_the_texture_mean() {
        let dir = tempfile::tempdir().unwrap();
        // Half the pixels sRGB 255 (linear 1), half sRGB 0: a linear mean of one half.
        let mut stripes = image::RgbImage::new(4, 4);
        for (x, _, p) in stripes.enumerate_pixels_mut() {
            *p = image::Rgb(if x % 2 == 0 { [255; 3] } else { [0; 3] });
        }
        stripes.save(dir.path().join("stripes.png")).unwrap();
        std::fs::write(
            dir.path().join("quad.mtl"),
            "newmtl tex\nKd 0.8 0.6 0.4\nmap_Kd stripes.png\nnewmtl plain\nKd 0.5 0.5 0.5\n",
        )
        .unwrap();
        std::fs::write(
            dir.path().join("quad.obj"),
            "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n\
             vt 0 1\nusemtl tex\nf 1/1 2/2 3/3\nusemtl plain\nf 1/1 3/3 4/4\n",
        )
        .unwrap();
        let scene = Scene::load(dir.path()).unwrap();
        let (materials, _) = cpu_materials(&scene).unwrap();
        let by_name = |name: &str| {
            let i = scene.materials.iter().position(|m| m.name == name).unwrap();
            materials[i]
        };
        let textured = by_name("tex");
        assert_eq!(textured.kd, [0.8, 0.6, 0.4], "the G-buffer's Kd stays");
        for (mean, kd) in textured.kd_mean.iter().zip([0.8, 0.6, 0.4]) {
            assert!((mean - 0.5 * kd).abs() < 1e-6, "{:?}", textured.kd_mean);
        }
        assert_eq!(by_name("plain").kd_mean, [0.5; 3]);
    }
}
