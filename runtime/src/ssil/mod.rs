//! Hierarchical screen-space indirect illumination with voxel visibility (Soler et al. 2010,
//! "A Fast Deferred Shading Pipeline for Real Time Approximate Indirect Illumination"),
//! `--method ssil`.
//!
//! Every frame ([`ScreenSpaceGi`]):
//! 1. `ssil sender` (`sender.wgsl`): the diffuse direct light leaving every pixel plus the
//!    radiance it emits (the G-buffer's emission, zero where the eye sees an emitter's back:
//!    emission is one-sided), the light the first bounce gathers (§3: the "direct
//!    illumination" G-buffer, diffuse, §5.3);
//! 2. `gbuffer pyramid` (`common::pyramid`, §4, Eq. 5): position, normal and albedo of levels
//!    1 and up, each coarse pixel the child its neighbours agree with most, not an average;
//!    `ssil light pyramid`: the sent light's mean per level;
//! 3. `ssil voxels` (`voxels.wgsl`, §4 after Eisemann and Décoret 2008): with
//!    `visibility=voxels`, the view frustum's solid voxelisation, 128 one-bit slices of view
//!    depth per pixel of the first gathered level, each fragment toggling (XOR) its column
//!    from its depth on; then each coarser level's columns the AND of their children;
//! 4. `ssil gather` (`gather.wgsl`, §3, §4, Eq. 3 and 4), per bounce and per level from the
//!    coarsest (level `start-level + levels - 1`) to the finest gathered (`start-level`):
//!    `samples` samples in the ring between `radius / 2` and `radius` level pixels (the full
//!    disc at the finest), each sending its light through the point-to-disc form factor of the
//!    scene area its share of the ring stands for (the paper's energy factor 2^2k at level k),
//!    counted when the march through the level's voxels from the receiver to it is clear
//!    (`bias` pixels skipped at both ends); glossy receivers gather a lobe-weighted irradiance
//!    from as many more samples importance-sampled around the mirrored view ray's direction on
//!    screen; the coarser levels' result, joint-bilaterally up-sampled, added;
//!    `accumulate`: the bounce's sum at the finest level into the filters' input and, when
//!    another bounce follows, its diffuse light (albedo / pi times the irradiance) that
//!    bounce's senders (§4, "Multi-bounce computation"; `later-visibility` says whether the
//!    later bounces test visibility, which §5.3 suggests dropping);
//! 5. the shared filters (`common::filters`): an edge-aware blur of `blur` taps at the finest
//!    gathered level, guided by that level of the pyramid, and joint bilateral up-sampling to
//!    the G-buffer's resolution;
//! 6. `ssil temporal` (`temporal.wgsl`, §4, Eq. 6): the previous frame's result reprojected
//!    through the frame history (`common::history`: the previous camera and G-buffer) and
//!    blended in with `temporal` (less on glossy pixels as the camera turns);
//! 7. `ssil resolve` (`common::resolve`): albedo / pi times the diffuse irradiance plus Ks
//!    times the lobe-weighted one.
//!
//! What screen space cannot see, by design: light from surfaces outside the image or hidden
//! behind others (they are not in the G-buffer), and occluders outside the view frustum. The
//! voxels need closed geometry: an open surface fills everything behind it along its pixels'
//! rays. Senders are diffuse. `reports/runtime.md` measures it against the path tracer.
//!
//! CPU twin: [`cpu`] (tests in `tests/gpu/ssil.rs`).

pub mod cpu;

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[SENDER_SHADER, VOXELS_SHADER, GATHER_SHADER, TEMPORAL_SHADER],
    libraries: &[],
};

use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{
        converge::{BouncePlan, CONVERGED_FRACTION, ConvergeGpu, ConvergeInputs, Convergence},
        filters::{self, EdgeAwareFilter, FilterOptions, LowGuide},
        layout,
        pyramid::{GBufferPyramid, PyramidLayout, SignalPyramid},
        history::FrameHistory,
        resolve::PlaneResolve,
    },
    direct::{light_entries, light_resources},
    frame::{FrameContext, FrameEncoder, PassInfo, Slot, Stage},
    gpu_types::GpuView,
    load::SceneGpu,
    method::{Backend, Checks, Energy, GiMethod, MethodEntry, MethodSetup, OptionKind, OptionSpec, Resolved},
    shaders,
};

/// `ssil/sender.wgsl`: the diffuse direct light leaving every pixel, and the next bounce's.
pub const SENDER_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("ssil sender", "ssil/sender.wgsl");

/// `ssil/voxels.wgsl`: the view frustum's solid voxels by XOR (`vs_main`, `fs_main`) and their AND
/// down the levels (`and_down`).
pub const VOXELS_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("ssil voxels", "ssil/voxels.wgsl");

/// `ssil/gather.wgsl` with `common/bilateral.wgsl`: one level's gather and the coarser levels up-
/// sampled into it (`gather`), and the bounces' sum (`accumulate`).
pub const GATHER_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("ssil gather", "ssil/gather.wgsl");

/// `ssil/temporal.wgsl`: the reprojected history blended in.
pub const TEMPORAL_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("ssil temporal", "ssil/temporal.wgsl");

/// Slices of view depth per voxel column (`voxels.wgsl`: `SLICES`).
pub const SLICES: u32 = 128;

/// Most bounces (each a gather of every level, every frame).
pub const MAX_BOUNCES: u32 = 4;

/// Most gathered levels.
pub const MAX_LEVELS: u32 = 8;

/// Coarsest first gathered level (3: an eighth of the resolution per side).
pub const MAX_START_LEVEL: u32 = 3;

/// The constant part `alpha` of the glossy samples' importance function (§4: 0.1).
pub const UNIFORM_WEIGHT: f32 = 0.1;

/// How the gather decides whether a sample's light reaches the receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Visibility {
    /// A march through the frustum's solid voxels (§4).
    Voxels,
    /// Every sample visible.
    None,
}

/// Which disc the point-to-disc form factor of a sample takes (Eq. 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormFactor {
    /// The disc of the sample's own level pixel, counted as many times as its share of the
    /// ring holds pixels: the Monte-Carlo estimate of the sum over the level's pixels.
    PixelDisc,
    /// The disc of the whole share, as the paper applies Eq. 4: less noise, but a sample
    /// near its receiver is bounded by one disc where its share holds many pixels.
    SampleDisc,
}

/// The typed options of `ssil`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SsilOptions {
    /// Samples per pixel and level (and as many more for a glossy pixel's lobe).
    pub samples: u32,
    /// Gathered levels.
    pub levels: u32,
    /// The finest gathered level: the G-buffer reduced `2^start_level` times per side.
    pub start_level: u32,
    /// Outer radius of the sampled ring, in pixels of each level.
    pub radius: f32,
    /// The first bounce's visibility.
    pub visibility: Visibility,
    /// Whether the bounces after the first test visibility too.
    pub later_visibility: bool,
    /// Bounces; 0 until converged ([`Self::plan`]).
    pub bounces: u32,
    /// With `bounces` 0: the share of the light a bounce reflects at most to be the last
    /// ([`CONVERGED_FRACTION`], the option table's; tests choose others).
    pub converge: f32,
    /// Level pixels skipped at both ends of a visibility march.
    pub bias: f32,
    /// Taps on each side of the edge-aware blur at the finest gathered level.
    pub blur: u32,
    /// Weight of the reprojected history (Eq. 6's `a`), below 1.
    pub temporal: f32,
    /// The samples' form factor.
    pub form_factor: FormFactor,
}

impl Default for SsilOptions {
    fn default() -> Self {
        Self::from_resolved(&METHOD.resolve(&Default::default()).expect("defaults are valid"))
    }
}

impl SsilOptions {
    /// The typed form of checked options.
    pub fn from_resolved(options: &Resolved) -> Self {
        Self {
            samples: options.count("level-samples"),
            levels: options.count("levels"),
            start_level: options.count("start-level"),
            radius: options.number("radius"),
            visibility: match options.choice("visibility") {
                "none" => Visibility::None,
                _ => Visibility::Voxels,
            },
            later_visibility: options.switch("later-visibility"),
            bounces: options.count("bounces"),
            converge: CONVERGED_FRACTION,
            bias: options.number("bias"),
            blur: options.count("blur"),
            temporal: options.number("temporal"),
            form_factor: match options.choice("form-factor") {
                "sample-disc" => FormFactor::SampleDisc,
                _ => FormFactor::PixelDisc,
            },
        }
    }

    /// Refuses a history weight of 1 or more (the image would never change).
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] naming the value.
    pub fn check(&self) -> Result<(), RuntimeError> {
        if !(0.0..1.0).contains(&self.temporal) {
            return Err(RuntimeError::Unsupported(format!(
                "ssil temporal={} must be at least 0 and below 1",
                self.temporal
            )));
        }
        Ok(())
    }

    /// The coarsest gathered level.
    pub fn last_level(&self) -> u32 {
        self.start_level + self.levels - 1
    }

    /// The bounces: `bounces`, or with `bounces` 0 until one adds at most `converge` of the
    /// light, at most [`MAX_BOUNCES`] ([`crate::common::converge`]).
    pub fn plan(&self) -> BouncePlan {
        match self.bounces {
            0 => BouncePlan {
                max: MAX_BOUNCES,
                fraction: self.converge,
            },
            n => BouncePlan::exactly(n),
        }
    }

    /// Whether bounce `bounce` (0 for the first) tests visibility.
    pub fn visibility_in(&self, bounce: u32) -> bool {
        self.visibility == Visibility::Voxels && (bounce == 0 || self.later_visibility)
    }

    /// The shared filters' settings.
    pub fn filter(&self) -> FilterOptions {
        FilterOptions::reduced(1 << self.start_level, self.blur)
    }
}

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
    /// 1 for [`FormFactor::SampleDisc`].
    pub sample_disc: u32,
    padding: u32,
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
            seed: cpu::hash(seed),
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

/// `voxels.wgsl`'s `VoxelParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct VoxelParams {
    z_near: f32,
    z_far: f32,
    columns: [u32; 2],
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

/// `temporal.wgsl`'s `TemporalParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct TemporalParams {
    previous_view_proj: [[f32; 4]; 4],
    previous_eye: [f32; 3],
    blend: f32,
    history: u32,
    padding: [u32; 3],
}

/// The levels' geometry: the pyramid's layout, the gathered levels, the voxel columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Levels {
    /// The pyramid up to the coarsest gathered level.
    pub pyramid: PyramidLayout,
    /// The finest gathered level.
    pub start: u32,
    /// The coarsest gathered level.
    pub last: u32,
}

impl Levels {
    /// The levels of `options` over a G-buffer of `full` size.
    pub fn new(full: (u32, u32), options: &SsilOptions) -> Self {
        Self {
            pyramid: PyramidLayout {
                full,
                levels: options.last_level(),
            },
            start: options.start_level,
            last: options.last_level(),
        }
    }

    /// Voxel column of `level`'s (0, 0): the columns of the gathered levels, finest first.
    pub fn grid_offset(&self, level: u32) -> u32 {
        (self.start..level)
            .map(|j| {
                let (w, h) = self.pyramid.size(j);
                w * h
            })
            .sum()
    }

    /// Voxel columns of every gathered level.
    pub fn columns(&self) -> u32 {
        self.grid_offset(self.last + 1)
    }

    /// The gather's parameters at `level` in `bounce` of `options`.
    pub fn gather_params(&self, level: u32, bounce: u32, options: &SsilOptions) -> GatherParams {
        let filter = FilterOptions::default();
        let (w, h) = self.pyramid.size(level);
        let coarse = (level < self.last).then(|| level + 1);
        let coarse_size = coarse.map_or((0, 0), |c| self.pyramid.size(c));
        GatherParams {
            full_size: [self.pyramid.full.0, self.pyramid.full.1],
            size: [w, h],
            coarse_size: [coarse_size.0, coarse_size.1],
            level,
            offset: self.pyramid.offset(level),
            coarse_offset: coarse.map_or(0, |c| self.pyramid.offset(c)),
            has_coarse: u32::from(coarse.is_some()),
            samples: options.samples,
            disc: u32::from(level == self.start),
            radius: options.radius,
            visibility: u32::from(options.visibility_in(bounce)),
            bias: options.bias,
            grid_offset: self.grid_offset(level),
            depth_sigma: filter.depth_sigma,
            normal_power: filter.normal_power,
            bounce,
            next_bounce: u32::from(bounce + 1 < options.plan().max),
            pixels: self.pyramid.pixels(),
            uniform_weight: UNIFORM_WEIGHT,
            sample_disc: u32::from(options.form_factor == FormFactor::SampleDisc),
            padding: 0,
        }
    }
}

fn uniform_buffer<T: bytemuck::Pod>(device: &wgpu::Device, label: &str, value: &T) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::bytes_of(value),
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    })
}

fn storage_buffer(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// The pipelines and layouts, created once.
struct Pipelines {
    sender_layout: wgpu::BindGroupLayout,
    sender: wgpu::ComputePipeline,
    voxel_layout: wgpu::BindGroupLayout,
    voxels: wgpu::RenderPipeline,
    and_layout: wgpu::BindGroupLayout,
    and_down: wgpu::ComputePipeline,
    gather_layout: wgpu::BindGroupLayout,
    gather: wgpu::ComputePipeline,
    accumulate_layout: wgpu::BindGroupLayout,
    accumulate: wgpu::ComputePipeline,
    temporal_layout: wgpu::BindGroupLayout,
    temporal: wgpu::ComputePipeline,
}

/// Format of the voxel raster's depth target, which only gives the pass its size (no test, no
/// write).
const VOXEL_TARGET: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

impl Pipelines {
    fn new(device: &wgpu::Device) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let mut entries = light_entries().to_vec();
        entries.extend([
            layout::texture(5, d2, c),
            layout::texture(6, d2, c),
            layout::texture(7, d2, c),
            layout::storage(8, false, c),
            layout::texture(9, d2, c),
        ]);
        let sender_layout = layout::bind_group_layout(device, "ssil sender", &entries);
        let module = SENDER_SHADER.create(device);
        let sender = layout::compute_pipeline(device, "ssil sender", &module, &[&sender_layout]);

        let vf = wgpu::ShaderStages::VERTEX_FRAGMENT;
        let voxel_layout = layout::bind_group_layout(device, "ssil voxels", &[
            layout::uniform(0, vf),
            layout::uniform(1, wgpu::ShaderStages::FRAGMENT),
            layout::storage(2, true, wgpu::ShaderStages::VERTEX),
            layout::storage(3, false, wgpu::ShaderStages::FRAGMENT),
        ]);
        let voxel_module = VOXELS_SHADER.create(device);
        let voxels = Self::voxel_raster(device, &voxel_layout, &voxel_module);
        let and_layout = layout::bind_group_layout(device, "ssil voxel levels", &[
            layout::storage(3, false, c),
            layout::uniform(4, c),
        ]);
        let and_down = layout::compute_pipeline_entry(
            device,
            "ssil voxel levels",
            &voxel_module,
            "and_down",
            &[&and_layout],
        );

        let gather_layout = layout::bind_group_layout(device, "ssil gather", &[
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
        ]);
        let gather_module = GATHER_SHADER.create(device);
        let gather = layout::compute_pipeline_entry(
            device,
            "ssil gather",
            &gather_module,
            "gather",
            &[&gather_layout],
        );
        let accumulate_layout = layout::bind_group_layout(device, "ssil accumulate", &[
            layout::uniform(0, c),
            layout::storage(8, false, c),
            layout::storage(9, false, c),
            layout::storage(10, false, c),
            layout::storage(11, true, c),
        ]);
        let accumulate = layout::compute_pipeline_entry(
            device,
            "ssil accumulate",
            &gather_module,
            "accumulate",
            &[&accumulate_layout],
        );

        let temporal_layout = layout::bind_group_layout(device, "ssil temporal", &[
            layout::uniform(0, c),
            layout::uniform(1, c),
            layout::storage(2, true, c),
            layout::texture(3, d2, c),
            layout::texture(4, d2, c),
            layout::texture(5, d2, c),
            layout::texture(6, d2, c),
            layout::storage(7, true, c),
            layout::storage(8, true, c),
            layout::storage(9, false, c),
        ]);
        let module = TEMPORAL_SHADER.create(device);
        let temporal =
            layout::compute_pipeline(device, "ssil temporal", &module, &[&temporal_layout]);
        Self {
            sender_layout,
            sender,
            voxel_layout,
            voxels,
            and_layout,
            and_down,
            gather_layout,
            gather,
            accumulate_layout,
            accumulate,
            temporal_layout,
            temporal,
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
}

/// What depends on the image size: buffers and bind groups.
struct Sized {
    levels: Levels,
    sender: wgpu::Buffer,
    acc: wgpu::Buffer,
    grid: wgpu::Buffer,
    grid_target: wgpu::Texture,
    blended: wgpu::Buffer,
    history: wgpu::Buffer,
    sender_group: wgpu::BindGroup,
    voxel_group: wgpu::BindGroup,
    and_groups: Vec<wgpu::BindGroup>,
    /// Per bounce, per gathered level from the finest.
    gather_groups: Vec<Vec<wgpu::BindGroup>>,
    accumulate_groups: Vec<wgpu::BindGroup>,
    temporal_group: wgpu::BindGroup,
    /// The test that ends the bounces once converged (with `bounces` 0).
    converge: ConvergeGpu,
}

/// The whole SSIL pipeline over a frame context: the method's engine, which the tests and
/// benchmarks also drive directly.
pub struct ScreenSpaceGi {
    options: SsilOptions,
    bounds: (Vec3, Vec3),
    pipelines: Pipelines,
    pyramid: GBufferPyramid,
    light: SignalPyramid,
    filter: EdgeAwareFilter,
    resolve: PlaneResolve,
    frame_params: wgpu::Buffer,
    voxel_params: wgpu::Buffer,
    temporal_params: wgpu::Buffer,
    sized: Sized,
    frame_history: FrameHistory,
    frames: u32,
}

impl ScreenSpaceGi {
    /// The pipeline of `options` over `ctx`, for a scene within `bounds` (the voxels' depth
    /// range).
    ///
    /// # Errors
    /// Options that [`SsilOptions::check`] or the filters refuse.
    pub fn new(
        ctx: &FrameContext,
        bounds: (Vec3, Vec3),
        options: &SsilOptions,
    ) -> Result<Self, RuntimeError> {
        options.check()?;
        let device = &ctx.device;
        let levels = Levels::new(ctx.size(), options);
        let pipelines = Pipelines::new(device);
        let pyramid = GBufferPyramid::new(device, &ctx.gbuffer, &ctx.view, levels.last);
        let sender = ctx.pixel_buffer("ssil sender");
        let light = SignalPyramid::new(device, levels.pyramid, &sender);
        let filter = EdgeAwareFilter::new(
            device,
            &ctx.gbuffer,
            &ctx.view,
            2,
            options.filter(),
            Self::low_guide(&pyramid, &levels),
        )?;
        let frame_params = uniform_buffer(device, "ssil frame", &FrameParams::default());
        let voxel_params = uniform_buffer(device, "ssil voxels", &VoxelParams {
            z_near: 0.0,
            z_far: 1.0,
            columns: [0; 2],
        });
        let temporal_params = uniform_buffer(device, "ssil temporal", &TemporalParams {
            previous_view_proj: [[0.0; 4]; 4],
            previous_eye: [0.0; 3],
            blend: options.temporal,
            history: 0,
            padding: [0; 3],
        });
        let frame_history = FrameHistory::new(device, ctx.size());
        let sized = Self::bind(
            ctx,
            options,
            &pipelines,
            &pyramid,
            &light,
            &filter,
            [&frame_params, &voxel_params, &temporal_params],
            sender,
            &frame_history,
        );
        let resolve = PlaneResolve::new(ctx, "ssil resolve", &sized.blended);
        Ok(Self {
            options: *options,
            bounds,
            pipelines,
            pyramid,
            light,
            filter,
            resolve,
            frame_params,
            voxel_params,
            temporal_params,
            sized,
            frame_history,
            frames: 0,
        })
    }

    fn low_guide<'a>(pyramid: &'a GBufferPyramid, levels: &Levels) -> LowGuide<'a> {
        LowGuide::Buffers {
            position: &pyramid.position,
            normal: &pyramid.normal,
            offset: levels.pyramid.offset(levels.start),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn bind(
        ctx: &FrameContext,
        options: &SsilOptions,
        pipelines: &Pipelines,
        pyramid: &GBufferPyramid,
        light: &SignalPyramid,
        filter: &EdgeAwareFilter,
        [frame_params, voxel_params, temporal_params]: [&wgpu::Buffer; 3],
        sender: wgpu::Buffer,
        frames: &FrameHistory,
    ) -> Sized {
        let device = &ctx.device;
        let levels = Levels::new(ctx.size(), options);
        let pixels = u64::from(levels.pyramid.pixels());
        let acc = storage_buffer(device, "ssil gathered", 32 * pixels);
        let grid = storage_buffer(device, "ssil voxels", 16 * u64::from(levels.columns()));
        let grid_target = layout::texture_2d(
            device,
            "ssil voxels target",
            levels.pyramid.size(levels.start),
            VOXEL_TARGET,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        );
        let (w, h) = ctx.size();
        let planes = 32 * u64::from(w) * u64::from(h);
        let blended = storage_buffer(device, "ssil blended", planes);
        let history = storage_buffer(device, "ssil history", planes);

        let gbuffer = [&ctx.gbuffer.position, &ctx.gbuffer.normal, &ctx.gbuffer.albedo]
            .map(|t| t.create_view(&Default::default()));
        let mut resources = light_resources(&ctx.view, &ctx.scene, &ctx.shadows).to_vec();
        resources.extend(gbuffer.iter().map(wgpu::BindingResource::TextureView));
        resources.push(sender.as_entire_binding());
        let emission = ctx.gbuffer.emission.create_view(&Default::default());
        resources.push(wgpu::BindingResource::TextureView(&emission));
        let sender_group =
            layout::bind_group(device, "ssil sender", &pipelines.sender_layout, &resources);

        let voxel_group = layout::bind_group(device, "ssil voxels", &pipelines.voxel_layout, &[
            ctx.view.as_entire_binding(),
            voxel_params.as_entire_binding(),
            ctx.scene.motion.as_entire_binding(),
            grid.as_entire_binding(),
        ]);
        let and_groups = (levels.start + 1..=levels.last)
            .map(|level| {
                let (fw, fh) = levels.pyramid.size(level - 1);
                let (cw, ch) = levels.pyramid.size(level);
                let params = uniform_buffer(device, "ssil voxel level", &AndParams {
                    fine_size: [fw, fh],
                    coarse_size: [cw, ch],
                    fine_offset: levels.grid_offset(level - 1),
                    coarse_offset: levels.grid_offset(level),
                    padding: [0; 2],
                });
                layout::bind_group_at(device, "ssil voxel levels", &pipelines.and_layout, &[
                    (3, grid.as_entire_binding()),
                    (4, params.as_entire_binding()),
                ])
            })
            .collect();

        // After the first light pyramid: the light so far; after each later one, the light the
        // bounce before reflects, from the pyramid's top level (every pixel's, box-filtered).
        let top = levels.pyramid.size(levels.last);
        // ssil's gathers are dispatched directly: they read the state and gather nothing once
        // converged, so the arguments the test copies go unused.
        let unused_args = crate::load::storage_buffer(
            device,
            "ssil converge arguments",
            bytemuck::cast_slice(&[1u32, 1, 1]),
        );
        let converge = ConvergeGpu::new(
            device,
            options.plan(),
            &ConvergeInputs {
                solution: [&light.signal, &light.signal],
                held: None,
                mean: (levels.pyramid.offset(levels.last), top.0 * top.1),
                additive: true,
                work_args: (&unused_args, 0),
            },
        );
        let gather_groups = (0..options.plan().max)
            .map(|bounce| {
                (levels.start..=levels.last)
                    .map(|level| {
                        let p = levels.gather_params(level, bounce, options);
                        let params = uniform_buffer(device, "ssil gather level", &p);
                        layout::bind_group_at(device, "ssil gather", &pipelines.gather_layout, &[
                            (0, params.as_entire_binding()),
                            (1, ctx.view.as_entire_binding()),
                            (2, frame_params.as_entire_binding()),
                            (3, ctx.scene.materials.as_entire_binding()),
                            (4, pyramid.position.as_entire_binding()),
                            (5, pyramid.normal.as_entire_binding()),
                            (6, light.signal.as_entire_binding()),
                            (7, grid.as_entire_binding()),
                            (8, acc.as_entire_binding()),
                            (12, converge.state().as_entire_binding()),
                        ])
                    })
                    .collect()
            })
            .collect();
        let accumulate_groups = (0..options.plan().max)
            .map(|bounce| {
                let p = levels.gather_params(levels.start, bounce, options);
                let params = uniform_buffer(device, "ssil accumulate", &p);
                layout::bind_group_at(device, "ssil accumulate", &pipelines.accumulate_layout, &[
                    (0, params.as_entire_binding()),
                    (8, acc.as_entire_binding()),
                    (9, filter.input().as_entire_binding()),
                    (10, light.signal.as_entire_binding()),
                    (11, pyramid.albedo.as_entire_binding()),
                ])
            })
            .collect();
        let texture_views = [
            &ctx.gbuffer.position,
            &ctx.gbuffer.normal,
            &frames.position,
            &frames.normal,
        ]
        .map(|t| t.create_view(&Default::default()));
        let mut resources = vec![
            ctx.view.as_entire_binding(),
            temporal_params.as_entire_binding(),
            ctx.scene.materials.as_entire_binding(),
        ];
        resources.extend(texture_views.iter().map(wgpu::BindingResource::TextureView));
        resources.extend([
            filter.output().as_entire_binding(),
            history.as_entire_binding(),
            blended.as_entire_binding(),
        ]);
        let temporal_group =
            layout::bind_group(device, "ssil temporal", &pipelines.temporal_layout, &resources);
        Sized {
            levels,
            sender,
            acc,
            grid,
            grid_target,
            blended,
            history,
            sender_group,
            voxel_group,
            and_groups,
            gather_groups,
            accumulate_groups,
            temporal_group,
            converge,
        }
    }

    /// Rebuilds what depends on the size after the context's G-buffer was resized; the
    /// history starts again.
    pub fn resize(&mut self, ctx: &FrameContext) {
        let device = &ctx.device;
        let levels = Levels::new(ctx.size(), &self.options);
        self.pyramid.resize(device, &ctx.gbuffer, &ctx.view);
        let sender = ctx.pixel_buffer("ssil sender");
        self.light.resize(device, levels.pyramid, &sender);
        self.filter.resize(
            device,
            &ctx.gbuffer,
            &ctx.view,
            Self::low_guide(&self.pyramid, &levels),
        );
        self.frame_history.resize(device, ctx.size());
        self.sized = Self::bind(
            ctx,
            &self.options,
            &self.pipelines,
            &self.pyramid,
            &self.light,
            &self.filter,
            [&self.frame_params, &self.voxel_params, &self.temporal_params],
            sender,
            &self.frame_history,
        );
        self.resolve.resize(ctx, &self.sized.blended);
    }

    /// The levels' geometry.
    pub fn levels(&self) -> Levels {
        self.sized.levels
    }

    /// The options it was built with.
    pub fn options(&self) -> &SsilOptions {
        &self.options
    }

    /// The G-buffer pyramid.
    pub fn pyramid(&self) -> &GBufferPyramid {
        &self.pyramid
    }

    /// The light the last bounce gathered, per pyramid level (levels 1 and up).
    pub fn light(&self) -> &SignalPyramid {
        &self.light
    }

    /// The full-res diffuse direct light the first bounce sends.
    pub fn sender(&self) -> &wgpu::Buffer {
        &self.sized.sender
    }

    /// The solid voxels: four words per column of every gathered level, finest first.
    pub fn grid(&self) -> &wgpu::Buffer {
        &self.sized.grid
    }

    /// The last bounce's gathered planes per pyramid element (diffuse, then lobe-weighted,
    /// [`PyramidLayout::pixels`] apart), each level holding the coarser levels' too.
    pub fn gathered(&self) -> &wgpu::Buffer {
        &self.sized.acc
    }

    /// The bounces' sum at the finest gathered level: the filters' input (two planes).
    pub fn summed(&self) -> &wgpu::Buffer {
        self.filter.input()
    }

    /// The filters' output at full resolution (two planes), before the temporal filter.
    pub fn filtered(&self) -> &wgpu::Buffer {
        self.filter.output()
    }

    /// The temporally filtered planes at full resolution.
    pub fn blended(&self) -> &wgpu::Buffer {
        &self.sized.blended
    }

    /// The parameters of the last frame encoded.
    pub fn frame_params(&self, ctx: &FrameContext) -> FrameParams {
        FrameParams::new(&ctx.gpu_view(), self.bounds, self.frames.wrapping_sub(1))
    }

    /// The indirect radiance per pixel.
    pub fn indirect(&self) -> &wgpu::Buffer {
        self.resolve.indirect()
    }

    /// How many bounces the last frame gathered (read back; waits for the GPU); with
    /// `bounces` fixed, all of them and never converged (the test is not run, its state zero).
    ///
    /// # Errors
    /// GPU errors of the read-back.
    pub fn convergence(&self, ctx: &FrameContext) -> Result<Convergence, RuntimeError> {
        let ended = self.sized.converge.read(&ctx.device, &ctx.queue)?;
        // The test runs after every bounce but the last: a run that did not stop ran them all.
        Ok(if ended.converged {
            ended
        } else {
            Convergence {
                bounces: self.options.plan().max,
                ..ended
            }
        })
    }

    /// Records a frame: sender, pyramids, voxels, the bounces' gathers, filters, temporal
    /// filter, resolve.
    pub fn encode(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        let view = ctx.gpu_view();
        let params = FrameParams::new(&view, self.bounds, self.frames);
        self.frames = self.frames.wrapping_add(1);
        let levels = self.sized.levels;
        let queue = &ctx.queue;
        queue.write_buffer(&self.frame_params, 0, bytemuck::bytes_of(&params));
        let (cw, ch) = levels.pyramid.size(levels.start);
        queue.write_buffer(
            &self.voxel_params,
            0,
            bytemuck::bytes_of(&VoxelParams {
                z_near: params.z_near,
                z_far: params.z_far,
                columns: [cw, ch],
            }),
        );
        let previous = *self.frame_history.previous().unwrap_or(&view);
        queue.write_buffer(
            &self.temporal_params,
            0,
            bytemuck::bytes_of(&TemporalParams {
                previous_view_proj: previous.view_proj,
                previous_eye: previous.eye,
                blend: self.options.temporal,
                history: u32::from(self.frame_history.previous().is_some()),
                padding: [0; 3],
            }),
        );

        let sized = &self.sized;
        let (w, h) = ctx.size();
        {
            let mut pass = frame.compute_pass("ssil sender");
            pass.set_pipeline(&self.pipelines.sender);
            pass.set_bind_group(0, &sized.sender_group, &[]);
            let (x, y) = shaders::groups_2d((w, h));
            pass.dispatch_workgroups(x, y, 1);
        }
        self.pyramid.run(frame);
        self.light.run(frame, "ssil light pyramid", 1);
        // With a fixed count (the default) the test is not recorded: its state stays as
        // created, zero, and every gather runs.
        let converging = self.options.plan().fraction > 0.0;
        if converging {
            let mut pass = frame.compute_pass("ssil converge");
            sized.converge.start(&mut pass);
        }
        if self.options.visibility == Visibility::Voxels {
            self.voxelize(ctx, frame);
        }
        let bounces = self.options.plan().max as usize;
        for bounce in 0..bounces {
            {
                let mut pass = frame.compute_pass("ssil gather");
                pass.set_pipeline(&self.pipelines.gather);
                for level in (levels.start..=levels.last).rev() {
                    let group = &sized.gather_groups[bounce][(level - levels.start) as usize];
                    pass.set_bind_group(0, group, &[]);
                    let (x, y) = shaders::groups_2d(levels.pyramid.size(level));
                    pass.dispatch_workgroups(x, y, 1);
                }
                pass.set_pipeline(&self.pipelines.accumulate);
                pass.set_bind_group(0, &sized.accumulate_groups[bounce], &[]);
                let (x, y) = shaders::groups_2d((cw, ch));
                pass.dispatch_workgroups(x, y, 1);
            }
            if bounce + 1 < bounces {
                self.light
                    .run(frame, "ssil light pyramid", levels.start + 1);
                // The light this bounce reflects: the next bounces gather nothing once it is at
                // most 1% of the light so far.
                if converging {
                    let mut pass = frame.compute_pass("ssil converge");
                    sized.converge.check(&mut pass, bounce as u32 + 1);
                }
            }
        }
        self.filter.run(frame);
        {
            let mut pass = frame.compute_pass("ssil temporal");
            pass.set_pipeline(&self.pipelines.temporal);
            pass.set_bind_group(0, &sized.temporal_group, &[]);
            let (x, y) = shaders::groups_2d((w, h));
            pass.dispatch_workgroups(x, y, 1);
        }
        self.resolve.run(frame);
        // The history of the next frame.
        frame
            .encoder
            .copy_buffer_to_buffer(&sized.blended, 0, &sized.history, 0, None);
        self.frame_history
            .record(frame.encoder, &ctx.gbuffer, view);
    }

    /// The XOR raster into the finest gathered level's columns, then the AND down the levels.
    fn voxelize(&self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        let sized = &self.sized;
        let levels = sized.levels;
        frame.encoder.clear_buffer(&sized.grid, 0, None);
        let target = sized.grid_target.create_view(&Default::default());
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
            pass.set_pipeline(&self.pipelines.voxels);
            pass.set_bind_group(0, &sized.voxel_group, &[]);
            pass.set_vertex_buffer(0, ctx.scene.vertices.slice(..));
            pass.draw(0..ctx.scene.vertex_count, 0..1);
        }
        if levels.last > levels.start {
            let mut pass = frame.compute_pass("ssil voxel levels");
            pass.set_pipeline(&self.pipelines.and_down);
            for (level, group) in (levels.start + 1..).zip(&sized.and_groups) {
                pass.set_bind_group(0, group, &[]);
                let (x, y) = shaders::groups_2d(levels.pyramid.size(level));
                pass.dispatch_workgroups(x, y, 1);
            }
        }
    }
}

/// `--method ssil`.
// Every check is set here, and `..Checks::DEFAULT` stays so that a new kind of check takes its
// default without editing this method.
#[allow(clippy::needless_update)]
pub const METHOD: MethodEntry = MethodEntry {
    name: "ssil",
    summary: "hierarchical screen-space indirect light with voxel visibility, multi-bounce \
              (Soler et al. 2010)",
    needs_cssm: false,
    options: &[
        OptionSpec {
            name: "level-samples",
            help: "samples per pixel and level, in the ring between radius/2 and radius (§4)",
            kind: OptionKind::Count {
                default: 32,
                min: 1,
                max: 256,
            },
        },
        OptionSpec {
            name: "levels",
            help: "gathered levels of the G-buffer pyramid, each twice as coarse (§4)",
            kind: OptionKind::Count {
                default: 5,
                min: 1,
                max: MAX_LEVELS,
            },
        },
        OptionSpec {
            name: "start-level",
            help: "finest gathered level: 1 half, 2 quarter, 3 an eighth of the resolution (§4)",
            kind: OptionKind::Count {
                default: 1,
                min: 1,
                max: MAX_START_LEVEL,
            },
        },
        OptionSpec {
            name: "radius",
            help: "outer radius of the sampled ring, in pixels of each level (§4: 40 at 1280x720)",
            kind: OptionKind::Number {
                default: 32.0,
                min: 1.0,
            },
        },
        OptionSpec {
            name: "visibility",
            help: "voxels: march through the frustum's solid voxelisation (§4); none: every \
                   sample visible",
            kind: OptionKind::Choice {
                default: "voxels",
                choices: &["voxels", "none"],
            },
        },
        OptionSpec {
            name: "later-visibility",
            help: "test visibility in the bounces after the first too (§5.3 suggests not)",
            kind: OptionKind::Switch { default: false },
        },
        OptionSpec {
            name: "bounces",
            help: "indirect bounces, each gathering the previous one's light (§4); 0: until a \
                   bounce adds at most 1% of the light, at most 4, decided every frame (the \
                   default is the paper's 2: each bounce costs every frame's time)",
            kind: OptionKind::Count {
                default: 2,
                min: 0,
                max: MAX_BOUNCES,
            },
        },
        OptionSpec {
            name: "bias",
            help: "level pixels skipped at both ends of a visibility march (§4)",
            kind: OptionKind::Number {
                default: 1.0,
                min: 0.0,
            },
        },
        filters::blur_option(
            "taps on each side of the edge-aware blur at the finest gathered level",
            2,
        ),
        OptionSpec {
            name: "temporal",
            help: "weight of the reprojected previous frame, 0 to below 1 (§4, Eq. 6)",
            kind: OptionKind::Number {
                default: 0.8,
                min: 0.0,
            },
        },
        OptionSpec {
            name: "form-factor",
            help: "pixel-disc: each sample the point-to-disc form factor of its own pixel, \
                   times the pixels it stands for; sample-disc: of a disc of all of them (Eq. 4 \
                   as the paper applies it)",
            kind: OptionKind::Choice {
                default: "pixel-disc",
                choices: &["pixel-disc", "sample-disc"],
            },
        },
    ],
    passes: &[
        PassInfo {
            name: "ssil sender",
            stage: Stage::Frame,
            reads: &[Slot::GBuffer, Slot::Lights, Slot::ShadowMaps, Slot::View],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "gbuffer pyramid",
            stage: Stage::Frame,
            reads: &[Slot::GBuffer, Slot::View],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil light pyramid",
            stage: Stage::Frame,
            reads: &[Slot::Reduced],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil converge",
            stage: Stage::Frame,
            reads: &[Slot::Reduced],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil voxels",
            stage: Stage::Frame,
            reads: &[Slot::Scene, Slot::View],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil voxel levels",
            stage: Stage::Frame,
            reads: &[Slot::Reduced],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil gather",
            stage: Stage::Frame,
            reads: &[Slot::Reduced, Slot::Scene, Slot::View],
            writes: &[Slot::Reduced],
        },
        filters::PASSES[0],
        filters::PASSES[1],
        PassInfo {
            name: "ssil temporal",
            stage: Stage::Frame,
            reads: &[Slot::Upsampled, Slot::GBuffer, Slot::View],
            writes: &[Slot::Upsampled],
        },
        PassInfo {
            name: "ssil resolve",
            stage: Stage::Frame,
            reads: &[Slot::Upsampled, Slot::GBuffer, Slot::Scene, Slot::View],
            writes: &[Slot::Indirect],
        },
    ],
    backend: Backend::Gpu(SsilMethod::build),
    checks: Checks {
        energy: Energy::OnScreenOnly,
        golden_flip: 0.01,
        emissive: Energy::OnScreenOnly,
        ..Checks::DEFAULT
    },
};

/// The `ssil` method.
struct SsilMethod {
    gi: ScreenSpaceGi,
}

impl SsilMethod {
    fn build(setup: &MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError> {
        let options = SsilOptions::from_resolved(setup.options);
        let gi = ScreenSpaceGi::new(setup.ctx, setup.scene.bounds(), &options)?;
        Ok(Box::new(Self { gi }))
    }
}

impl GiMethod for SsilMethod {
    fn encode(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.gi.encode(ctx, frame);
    }

    fn indirect(&self) -> Option<&wgpu::Buffer> {
        Some(self.gi.indirect())
    }

    fn resize(&mut self, ctx: &FrameContext) -> Result<(), RuntimeError> {
        self.gi.resize(ctx);
        Ok(())
    }

    /// The last frame's bounces.
    fn convergence(&self, ctx: &FrameContext) -> Option<Result<Convergence, RuntimeError>> {
        Some(self.gi.convergence(ctx))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_layouts_match_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::GATHER_SHADER);
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
        crate::shaders::tests::check_struct(&module, "FrameParams", size_of::<FrameParams>(), &[
            ("seed", offset_of!(FrameParams, seed)),
            ("z_near", offset_of!(FrameParams, z_near)),
            ("z_far", offset_of!(FrameParams, z_far)),
            ("pixel_area", offset_of!(FrameParams, pixel_area)),
        ]);
        let module = crate::shaders::tests::module(super::VOXELS_SHADER);
        crate::shaders::tests::check_struct(&module, "VoxelParams", size_of::<VoxelParams>(), &[
            ("z_near", offset_of!(VoxelParams, z_near)),
            ("z_far", offset_of!(VoxelParams, z_far)),
            ("columns", offset_of!(VoxelParams, columns)),
        ]);
        crate::shaders::tests::check_struct(&module, "AndParams", size_of::<AndParams>(), &[
            ("fine_size", offset_of!(AndParams, fine_size)),
            ("coarse_size", offset_of!(AndParams, coarse_size)),
            ("fine_offset", offset_of!(AndParams, fine_offset)),
            ("coarse_offset", offset_of!(AndParams, coarse_offset)),
        ]);
        let module = crate::shaders::tests::module(super::TEMPORAL_SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "TemporalParams",
            size_of::<TemporalParams>(),
            &[
                (
                    "previous_view_proj",
                    offset_of!(TemporalParams, previous_view_proj),
                ),
                ("previous_eye", offset_of!(TemporalParams, previous_eye)),
                ("blend", offset_of!(TemporalParams, blend)),
                ("history", offset_of!(TemporalParams, history)),
            ],
        );
    }

    /// The rings of the levels cover the screen once: level k's ring, `r/2` to `r` of its
    /// pixels, is `2^(k-1) r` to `2^k r` full-res pixels, where level k - 1's ends.
    #[test]
    fn levels_follow_each_other() {
        let options = SsilOptions {
            start_level: 2,
            levels: 3,
            ..Default::default()
        };
        let levels = Levels::new((640, 480), &options);
        assert_eq!((levels.start, levels.last), (2, 4));
        assert_eq!(levels.grid_offset(2), 0);
        assert_eq!(levels.grid_offset(3), 160 * 120);
        assert_eq!(levels.columns(), 160 * 120 + 80 * 60 + 40 * 30);
        let first = levels.gather_params(2, 0, &options);
        assert_eq!((first.disc, first.has_coarse, first.coarse_size), (1, 1, [80, 60]));
        let last = levels.gather_params(4, 1, &options);
        assert_eq!((last.disc, last.has_coarse, last.next_bounce), (0, 0, 0));
        assert_eq!(last.visibility, 0, "later bounces skip visibility by default");
        assert_eq!(levels.gather_params(4, 0, &options).visibility, 1);
    }

    #[test]
    fn pixel_area_is_the_frustum_over_the_pixels() {
        let proj = glam::camera::rh::proj::directx::perspective(
            60f32.to_radians(),
            4.0 / 3.0,
            0.1,
            10.0,
        );
        let view = glam::camera::rh::view::look_at_mat4(Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO, Vec3::Y);
        let tan = (30f32).to_radians().tan();
        let expected = 4.0 * tan * (tan * 4.0 / 3.0) / (640.0 * 480.0);
        let area = pixel_area(&(proj * view), (640, 480));
        assert!((area - expected).abs() < 1e-6 * expected, "{area} {expected}");
    }

    #[test]
    fn temporal_weight_below_one() {
        let mut options = SsilOptions::default();
        assert!(options.check().is_ok());
        options.temporal = 1.0;
        let err = options.check().unwrap_err().to_string();
        assert!(err.contains("temporal=1"), "{err}");
    }
}
