//! A `.cssm` file in GPU storage buffers ([`CssmGpu`]): the run data kept in its random-access
//! layout, never decompressed, split over as many bindings as the device's limit asks.

use super::*;

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
