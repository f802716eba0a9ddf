//! Visibility among moving rigid objects on the GPU (§3.3): [`MovingGpu`] holds the objects'
//! placements and coherent shadow maps for the WGSL library `moving.wgsl`
//! (`moving_visibility_between`), and [`MovingQueryKernel`] answers a batch of queries between
//! posed surface points, for the test that holds it to the CPU reference
//! `cssm_formats::moving::MovingQuery` and for benchmarks.

use bytemuck::{Pod, Zeroable};
use cssm_formats::{
    CssmFile, Scene,
    moving::{Placement, object_groups},
};
use glam::{Affine3A, Vec3};
use wgpu::util::DeviceExt;

use crate::{
    Gpu, RuntimeError,
    common::layout,
    load::{CssmGpu, limit_check},
};

/// `visibility/moving_query.wgsl`, the batch query between posed surface points, with the CSSM
/// library and `visibility/moving.wgsl` (§3.3).
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("moving objects' query", "visibility/moving_query.wgsl");

/// Rigid objects with a coherent shadow map the GPU query tests: `moving.wgsl` loops over them
/// where the driver allows loops, and on llvmpipe (whose loop limit a gather would reach) has
/// one `#if MOVING_CSMS > k` step per CSM, eight of them.
pub const MOVING_MAX_CSMS: usize = 8;

/// Storage buffers per shader stage the moving objects' bind group adds to a pass's (the
/// placements, CSMs, cells, offsets, runs, and the objects' motion that moves their texels,
/// `posed.wgsl`). A scene with moving objects needs the device to allow
/// [`crate::required_limits`]' 12 and these; a static scene's passes leave the group out.
pub const MOVING_STORAGE_BUFFERS: u32 = 6;

/// One object's placement as `moving.wgsl` reads it: the rows of its affine transforms.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuPlacement {
    /// Rows of [`Placement::to_baked`].
    pub to_baked: [[f32; 4]; 3],
    /// Rows of [`Placement::normal_to_baked`] (w unused).
    pub normal: [[f32; 4]; 3],
    /// Rows of [`Placement::to_object`].
    pub to_object: [[f32; 4]; 3],
    /// [`Placement::group`].
    pub group: u32,
    /// Unused.
    pub _pad: [u32; 3],
}

fn rows(t: &Affine3A) -> [[f32; 4]; 3] {
    let m = glam::Mat4::from(*t);
    [0, 1, 2].map(|r| m.row(r).to_array())
}

impl From<&Placement> for GpuPlacement {
    fn from(p: &Placement) -> Self {
        let n = glam::Mat3::from(p.normal_to_baked());
        Self {
            to_baked: rows(&p.to_baked),
            normal: [0, 1, 2].map(|r| n.row(r).extend(0.0).to_array()),
            to_object: rows(&p.to_object),
            group: p.group,
            _pad: [0; 3],
        }
    }
}

/// One coherent shadow map as `moving.wgsl` reads it (`Csm`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuCsm {
    /// Bounding sphere centre (object space).
    pub center: [f32; 3],
    /// Its radius.
    pub radius: f32,
    /// Side of the octahedral map of directions.
    pub directions: u32,
    /// Side of each depth map.
    pub resolution: u32,
    /// Its object.
    pub object: u32,
    /// Where its `map_of_cell` starts in the cells buffer.
    pub cells_base: u32,
    /// Where its run offsets start in the offsets buffer.
    pub offsets_base: u32,
    /// Where its runs start in the runs buffer (its offsets are relative to it).
    pub runs_base: u32,
    /// Unused.
    pub _pad: [u32; 2],
}

/// The moving objects' bind group (`MOVING_GROUP` in the modules that import `cssm::moving` or
/// `cssm::posed`): placements (written by [`MovingGpu::set_pose`]), CSMs and their run data,
/// and at binding 5 the objects' motion since loading (`SceneGpu::motion`, the raster passes'
/// matrices, written by `Renderer::set_object_transform`), which moves their atlas texels
/// (`posed.wgsl`, §3.3).
pub struct MovingGpu {
    /// One [`GpuPlacement`] per object (binding 0).
    pub placements: wgpu::Buffer,
    /// Layout of [`Self::bind_group`].
    pub bind_group_layout: wgpu::BindGroupLayout,
    /// The bind group.
    pub bind_group: wgpu::BindGroup,
    /// Each object's transform as baked (as loaded).
    baked: Vec<Affine3A>,
    /// Each object's group ([`object_groups`]).
    groups: Vec<u32>,
    /// How many CSMs the file holds: the modules importing `cssm::moving` are composed for it
    /// ([`crate::shaders::Shader::create_for_scene`]).
    pub csm_count: u32,
}

impl MovingGpu {
    /// The layout's entries (every binding read-only storage).
    pub fn layout_entries(visibility: wgpu::ShaderStages) -> Vec<wgpu::BindGroupLayoutEntry> {
        (0..MOVING_STORAGE_BUFFERS)
            .map(|b| layout::storage(b, true, visibility))
            .collect()
    }

    /// Uploads the CSMs of `file` and every object of `scene` (the scene `file` was baked
    /// from, validated against it) where it was loaded; `motion` is the objects' motion since
    /// loading (`SceneGpu::motion`: one `mat4x4f` per object), bound for `posed.wgsl`. `Err`
    /// when there are more than [`MOVING_MAX_CSMS`] or a buffer exceeds the device's limits.
    pub fn new(
        device: &wgpu::Device,
        file: &CssmFile,
        scene: &Scene,
        motion: &wgpu::Buffer,
    ) -> Result<Self, RuntimeError> {
        let csms: Vec<&cssm_formats::csm::CsmData> = file.csms.iter().collect();
        if csms.len() > MOVING_MAX_CSMS {
            return Err(RuntimeError::Unsupported(format!(
                "{} moving objects: the GPU query tests at most {MOVING_MAX_CSMS}",
                csms.len()
            )));
        }
        let allowed = device.limits().max_storage_buffers_per_shader_stage;
        let needed =
            crate::required_limits().max_storage_buffers_per_shader_stage + MOVING_STORAGE_BUFFERS;
        if !csms.is_empty() && allowed < needed {
            return Err(RuntimeError::Unsupported(format!(
                "moving objects need {needed} storage buffers per shader stage; this device \
                 allows {allowed}"
            )));
        }
        let groups = object_groups(&scene.objects);
        let baked: Vec<Affine3A> = scene.objects.iter().map(|o| o.transform).collect();
        let (mut cells, mut offsets, mut runs) = (Vec::new(), Vec::new(), Vec::new());
        let mut gpu_csms = Vec::with_capacity(csms.len());
        for c in &csms {
            gpu_csms.push(GpuCsm {
                center: c.center,
                radius: c.radius,
                directions: c.directions,
                resolution: c.resolution,
                object: c.object,
                cells_base: cells.len() as u32,
                offsets_base: offsets.len() as u32,
                runs_base: runs.len() as u32,
                _pad: [0; 2],
            });
            cells.extend_from_slice(&c.map_of_cell);
            offsets.extend_from_slice(&c.runs.offsets);
            runs.extend_from_slice(&c.runs.runs);
        }
        // wgpu refuses empty storage buffers: a scene without moving objects binds one zero.
        for v in [&mut cells, &mut offsets, &mut runs] {
            if v.is_empty() {
                v.push(0);
            }
        }
        if gpu_csms.is_empty() {
            // No directions: the placeholder the shader skips.
            gpu_csms.push(GpuCsm::default());
        }
        let placements: Vec<GpuPlacement> = baked
            .iter()
            .zip(&groups)
            .map(|(&t, &group)| GpuPlacement::from(&Placement::new(t, t, group)))
            .collect();
        let buffer = |label: &'static str, bytes: &[u8], usage| -> Result<wgpu::Buffer, _> {
            limit_check(device, label, bytes.len() as u64)?;
            Ok::<_, RuntimeError>(
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytes,
                    usage: wgpu::BufferUsages::STORAGE | usage,
                }),
            )
        };
        let placements_buffer = buffer(
            "moving object placements",
            bytemuck::cast_slice(&placements),
            wgpu::BufferUsages::COPY_DST,
        )?;
        let csm_buffer = buffer(
            "coherent shadow maps",
            bytemuck::cast_slice(&gpu_csms),
            wgpu::BufferUsages::empty(),
        )?;
        let cells_buffer = buffer(
            "CSM cells",
            bytemuck::cast_slice(&cells),
            wgpu::BufferUsages::empty(),
        )?;
        let offsets_buffer = buffer(
            "CSM run offsets",
            bytemuck::cast_slice(&offsets),
            wgpu::BufferUsages::empty(),
        )?;
        let runs_buffer = buffer(
            "CSM runs",
            bytemuck::cast_slice(&runs),
            wgpu::BufferUsages::empty(),
        )?;
        let bind_group_layout = layout::bind_group_layout(
            device,
            "moving objects",
            &Self::layout_entries(wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::FRAGMENT),
        );
        let bind_group = layout::bind_group(
            device,
            "moving objects",
            &bind_group_layout,
            &[
                placements_buffer.as_entire_binding(),
                csm_buffer.as_entire_binding(),
                cells_buffer.as_entire_binding(),
                offsets_buffer.as_entire_binding(),
                runs_buffer.as_entire_binding(),
                motion.as_entire_binding(),
            ],
        );
        Ok(Self {
            placements: placements_buffer,
            bind_group_layout,
            bind_group,
            baked,
            groups,
            csm_count: csms.len() as u32,
        })
    }

    /// `layouts` followed by this group's layout when the file has moving objects: the
    /// pipeline layout of a pass whose module imports `cssm::moving` (composed for
    /// [`Self::csm_count`]; a static scene's module reads none of the group, and leaving it out
    /// keeps the pass within [`crate::required_limits`]).
    pub fn with_layout<'a>(
        &'a self,
        layouts: &[&'a wgpu::BindGroupLayout],
    ) -> Vec<&'a wgpu::BindGroupLayout> {
        let mut all = layouts.to_vec();
        if self.csm_count > 0 {
            all.push(&self.bind_group_layout);
        }
        all
    }

    /// Binds the group at `index` of `pass` when [`Self::with_layout`] added it.
    pub fn bind(&self, pass: &mut wgpu::ComputePass, index: u32) {
        if self.csm_count > 0 {
            pass.set_bind_group(index, &self.bind_group, &[]);
        }
    }

    /// Places object `index` at `pose` (object to world), as
    /// `cssm_formats::moving::MovingQuery::set_poses` does.
    ///
    /// # Panics
    /// If `index` is not an object of the scene this was built for.
    pub fn set_pose(&self, queue: &wgpu::Queue, index: usize, pose: Affine3A) {
        let placement = Placement::new(self.baked[index], pose, self.groups[index]);
        queue.write_buffer(
            &self.placements,
            (index * std::mem::size_of::<GpuPlacement>()) as u64,
            bytemuck::bytes_of(&GpuPlacement::from(&placement)),
        );
    }
}

/// One end of a [`MovingPair`]: a surface point, the objects posed.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct MovingEnd {
    /// Barycentric coordinates on its triangle.
    pub bary: [f32; 3],
    /// Scene triangle (its atlas coordinates find its texels).
    pub triangle: u32,
    /// Position in world space now.
    pub position: [f32; 3],
    /// Its object.
    pub object: u32,
    /// Unit normal in world space now.
    pub normal: [f32; 3],
    /// Unused.
    pub _pad: u32,
}

impl MovingEnd {
    /// The end at (`triangle`, `bary`) of `object`, at `position` with `normal`.
    pub fn new(triangle: u32, bary: [f32; 3], position: Vec3, normal: Vec3, object: u32) -> Self {
        Self {
            bary,
            triangle,
            position: position.to_array(),
            object,
            normal: normal.to_array(),
            _pad: 0,
        }
    }
}

/// A query between two posed surface points.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct MovingPair {
    /// One end.
    pub a: MovingEnd,
    /// The other.
    pub b: MovingEnd,
}

/// A compute pass answering a batch of [`MovingPair`]s with `moving_visibility_between`: the
/// clear fraction of each, or -1 where neither end has texels.
pub struct MovingQueryKernel {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl MovingQueryKernel {
    /// Builds the kernel for `cssm`'s and `moving`'s layouts.
    pub fn new(gpu: &Gpu, cssm: &CssmGpu, moving: &MovingGpu) -> Self {
        let device = &gpu.device;
        let module = SHADER.create_for_scene(device, cssm.shape(), moving.csm_count);
        let c = wgpu::ShaderStages::COMPUTE;
        let io_layout = layout::bind_group_layout(
            device,
            "moving query io",
            &[layout::storage(0, true, c), layout::storage(1, false, c)],
        );
        let pipeline = layout::compute_pipeline(
            device,
            "moving query",
            &module,
            &moving.with_layout(&[&io_layout, &cssm.bind_group_layout]),
        );
        Self {
            pipeline,
            layout: io_layout,
        }
    }

    /// Answers `pairs` on the GPU and reads the answers back; `timer`, when given, times the
    /// pass (the throughput benchmark, `benches/moving_queries.rs`).
    pub fn run(
        &self,
        gpu: &Gpu,
        cssm: &CssmGpu,
        moving: &MovingGpu,
        pairs: &[MovingPair],
        timer: Option<&mut crate::common::timestamps::PassTimer>,
    ) -> Result<Vec<f32>, RuntimeError> {
        if pairs.is_empty() {
            return Ok(Vec::new());
        }
        let device = &gpu.device;
        limit_check(
            device,
            "the moving query pairs",
            std::mem::size_of_val(pairs) as u64,
        )?;
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("moving query pairs"),
            contents: bytemuck::cast_slice(pairs),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let output = super::answer_buffer(device, "moving query answers", pairs.len());
        let io = layout::bind_group(
            device,
            "moving query io",
            &self.layout,
            &[input.as_entire_binding(), output.as_entire_binding()],
        );
        let mut groups = vec![&io, &cssm.bind_group];
        if moving.csm_count > 0 {
            groups.push(&moving.bind_group);
        }
        let bytes = super::dispatch_and_read(
            gpu,
            "moving query",
            &self.pipeline,
            &groups,
            pairs.len(),
            &output,
            timer,
        )?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}
