//! A frame, pass by pass: the table of contents of the renderer ([`crate::Renderer`]), and the
//! one context every pass reads its shared resources from.
//!
//! Once, and again whenever a light or an object moves (`prepare`):
//!
//! 1. `common::shadow_map` — one depth map per spot light (§4.7), and in the same raster the
//!    reflective shadow map when a method reads [`Slot::Rsm`] (`rsm`)
//! 2. the method's view-independent passes ([`crate::method::GiMethod::prepare`]); for `hrc`,
//!    `lightmap` and `lightcuts` ([`crate::radiosity::AtlasGi`]):
//!    1. `direct::AtlasDirect` — direct light into the atlas texels
//!    2. `radiosity::Radiosity` — the diffuse bounces over the hierarchy (§4.1-§4.3): gather,
//!       then pull, per bounce
//!
//!    for `vct` ([`crate::vct::SparseVoxels`]): `common::voxelize`, the octree's build, the
//!    RSM's flux into its leaves, MIP-mapping and bricks
//!
//! Every frame (`encode`):
//!
//! 3. `common::gbuffer` — position, normal, material, albedo, atlas coordinates per pixel
//! 4. `direct::ScreenDirect` — direct light per pixel (spot lights, PCF shadows)
//! 5. the method's per-frame passes ([`crate::method::GiMethod::encode`]):
//!    `lightmap::AtlasLookup` (`hrc`: nearest texel, `lightmap`: bicubic) or
//!    `lightcuts::FinalGather` (`lightcuts`: the last, glossy bounce per pixel, §4.4), or
//!    `rsm`'s sampling at a reduced resolution, the shared `common::filters` (edge-aware blur,
//!    joint bilateral up-sampling) and its resolve, or `vct`'s cones through the octree, or
//!    `ssil`'s sent light, G-buffer pyramid, frustum voxels, gathers per level and bounce, the
//!    shared filters, temporal filter and resolve, or `vf`'s point proxies and their voxel
//!    grid, the proxies' light as VPLs and harmonics, sparse shadow rays, visibility filter,
//!    gathering, up-sampling and resolve
//! 6. `common::compose` — direct + indirect, or either alone (`--component`)
//! 7. `common::tonemap` — exposure, ACES, sRGB, into the caller's target
//!
//! Each pass declares what it reads and writes ([`PassInfo`], after kajiya's passes), and
//! [`check_schedule`] holds every method's schedule to it: nothing is read before it is written,
//! and nothing view-dependent is read while preparing.

use cssm_formats::{CssmFile, Scene, visibility::QueryOptions};
use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{
        camera::View, gbuffer::GBuffer, shadow_map, shadow_map::ShadowMaps, timestamps::PassTimer,
    },
    gpu_types::GpuView,
    load::{CssmGpu, SceneGpu},
    radiosity::HierarchyGpu,
};

/// A resource that passes read and write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    /// The mesh, materials and albedo textures (an input).
    Scene,
    /// The spot lights (an input).
    Lights,
    /// The `.cssm` buffers and the texel hierarchy (an input).
    Cssm,
    /// The camera and image size (an input).
    View,
    /// One depth map per light.
    ShadowMaps,
    /// The reflective shadow map of every light (the same raster as the shadow maps, made
    /// when a method's pass reads it).
    Rsm,
    /// Position, normal, albedo, atlas coordinates per pixel.
    GBuffer,
    /// Direct radiance per pixel.
    DirectRadiance,
    /// Direct radiance leaving every atlas texel.
    TexelRadiance,
    /// Radiance of every hierarchy node after the bounces.
    NodeRadiance,
    /// Indirect irradiance of every atlas texel.
    TexelIrradiance,
    /// Indirect light at a reduced resolution, before the shared filters (`common::filters`).
    Reduced,
    /// A technique's voxels of the scene and their light: the sparse voxel octree and its
    /// bricks (`vct`), the point proxies' grid, VPLs and harmonics (`vf`).
    Voxels,
    /// The reduced indirect light filtered and up-sampled to the G-buffer's resolution.
    Upsampled,
    /// Indirect radiance per pixel: a method's output.
    Indirect,
    /// Composed linear radiance per pixel.
    Radiance,
    /// The caller's target.
    Target,
}

impl Slot {
    /// What the renderer is given rather than computes.
    pub const INPUTS: [Slot; 4] = [Slot::Scene, Slot::Lights, Slot::Cssm, Slot::View];
}

/// When a pass runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Once, and again after a light or an object moves.
    Prepare,
    /// Every frame.
    Frame,
}

/// A pass: its name (as GPU timings name it), when it runs, what it reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PassInfo {
    /// Name, as in the timings.
    pub name: &'static str,
    /// When it runs.
    pub stage: Stage,
    /// What it reads.
    pub reads: &'static [Slot],
    /// What it writes.
    pub writes: &'static [Slot],
}

/// The renderer's own passes before a method's prepare passes.
pub const SHARED_PREPARE: &[PassInfo] = &[PassInfo {
    name: "shadow maps",
    stage: Stage::Prepare,
    reads: &[Slot::Scene, Slot::Lights],
    writes: &[Slot::ShadowMaps, Slot::Rsm],
}];

/// The renderer's own passes before a method's frame passes.
pub const SHARED_BEFORE: &[PassInfo] = &[
    PassInfo {
        name: "gbuffer",
        stage: Stage::Frame,
        reads: &[Slot::Scene, Slot::View],
        writes: &[Slot::GBuffer],
    },
    PassInfo {
        name: "direct light",
        stage: Stage::Frame,
        reads: &[Slot::GBuffer, Slot::Lights, Slot::ShadowMaps, Slot::View],
        writes: &[Slot::DirectRadiance],
    },
];

/// The renderer's own passes after a method's frame passes.
pub const SHARED_AFTER: &[PassInfo] = &[
    PassInfo {
        name: "compose",
        stage: Stage::Frame,
        reads: &[Slot::DirectRadiance, Slot::Indirect, Slot::View],
        writes: &[Slot::Radiance],
    },
    PassInfo {
        name: "tonemap",
        stage: Stage::Frame,
        reads: &[Slot::Radiance, Slot::View],
        writes: &[Slot::Target],
    },
];

/// A frame's schedule: the shared passes around `method`'s, in the order they are recorded.
pub fn schedule(method: &[PassInfo]) -> Vec<PassInfo> {
    let stage = |s| method.iter().filter(move |p| p.stage == s).copied();
    SHARED_PREPARE
        .iter()
        .copied()
        .chain(stage(Stage::Prepare))
        .chain(SHARED_BEFORE.iter().copied())
        .chain(stage(Stage::Frame))
        .chain(SHARED_AFTER.iter().copied())
        .collect()
}

/// Checks a schedule: every slot read is an input or was written by an earlier pass, and no
/// prepare pass reads what only a frame writes. `has_indirect` says whether the method writes
/// [`Slot::Indirect`] (otherwise the renderer binds zeros, an input).
///
/// # Errors
/// The first pass that reads what nothing wrote before it.
pub fn check_schedule(passes: &[PassInfo], has_indirect: bool) -> Result<(), String> {
    let mut written: Vec<Slot> = Slot::INPUTS.to_vec();
    if !has_indirect {
        written.push(Slot::Indirect);
    }
    let mut framing = false;
    for p in passes {
        if p.stage == Stage::Prepare && framing {
            return Err(format!("prepare pass '{}' after a frame pass", p.name));
        }
        framing |= p.stage == Stage::Frame;
        if let Some(missing) = p.reads.iter().find(|s| !written.contains(s)) {
            return Err(format!(
                "pass '{}' reads {missing:?} before anything writes it",
                p.name
            ));
        }
        written.extend(p.writes);
    }
    Ok(())
}

/// The `.cssm` file in GPU memory: the visibility query's buffers and the texel hierarchy.
pub struct CssmResources {
    /// The query's six bindings ([`crate::visibility`]).
    pub query: CssmGpu,
    /// The moving objects' placements and coherent shadow maps (§3.3,
    /// [`crate::visibility::moving`]); the identity placements and no CSM in a scene without
    /// rigid objects.
    pub moving: crate::visibility::moving::MovingGpu,
    /// The median-cut hierarchy (§4.2).
    pub hierarchy: HierarchyGpu,
    /// With moving objects, the texels and the hierarchy on the CPU, refitted when an object
    /// moves (`Renderer::set_object_transform`); `None` in a file without moving objects.
    pub moving_texels: Option<crate::radiosity::MovingTexels>,
}

/// Settings of a frame that are not a method's own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Multiplier applied to radiance before tone mapping (and by the oracle's tone mapper).
    pub exposure: f32,
    /// Shadow-map resolution in texels per side.
    pub shadow_resolution: u32,
    /// How the CSSM methods query visibility (filters, bias, both ends).
    pub visibility: QueryOptions,
}

impl Default for FrameSettings {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            exposure: 1.0,
            shadow_resolution: shadow_map::DEFAULT_RESOLUTION,
            visibility: QueryOptions::default(),
        }
    }
}

/// Largest image side the renderer accepts.
pub const MAX_SIDE: u32 = 8192;

/// Accepted shadow-map resolutions.
pub const SHADOW_RESOLUTION_RANGE: std::ops::RangeInclusive<u32> = 16..=16384;

impl FrameSettings {
    /// Refuses sizes outside 1 to [`MAX_SIDE`], shadow maps outside
    /// [`SHADOW_RESOLUTION_RANGE`] and exposures that are not finite and positive.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] naming the setting.
    pub fn check(&self) -> Result<(), RuntimeError> {
        check_size(self.width, self.height)?;
        if !SHADOW_RESOLUTION_RANGE.contains(&self.shadow_resolution) {
            return Err(RuntimeError::Unsupported(format!(
                "shadow-resolution {} is out of range {}..={}",
                self.shadow_resolution,
                SHADOW_RESOLUTION_RANGE.start(),
                SHADOW_RESOLUTION_RANGE.end()
            )));
        }
        if !(self.exposure.is_finite() && self.exposure > 0.0) {
            return Err(RuntimeError::Unsupported(format!(
                "exposure multiplier {} must be finite and > 0",
                self.exposure
            )));
        }
        Ok(())
    }
}

/// Bytes per pixel of the frame's own per-pixel storage buffers (one RGBA f32 radiance per
/// pixel): each must fit one storage binding.
pub const FRAME_BYTES_PER_PIXEL: u64 = 16;

impl FrameSettings {
    /// Checks the settings against a device's `limits` before anything is created for a scene
    /// of `lights` lights: the image sides and the shadow maps against the largest 2D texture,
    /// a per-pixel buffer ([`FRAME_BYTES_PER_PIXEL`]) against the largest storage binding, one
    /// shadow-map layer per light against the texture arrays' layers. wgpu would otherwise
    /// refuse the first resource too large with a validation error in its own words.
    ///
    /// ```
    /// use cssm_runtime::frame::FrameSettings;
    /// let limits = wgpu::Limits::default(); // WebGPU's: 128 MiB per storage binding
    /// let huge = FrameSettings { width: 4096, height: 4096, ..Default::default() };
    /// assert!(huge.check_limits(&limits, 1).is_err());
    /// assert!(FrameSettings::default().check_limits(&limits, 1).is_ok());
    /// ```
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] naming the setting, the device's limit and what fits.
    pub fn check_limits(&self, limits: &wgpu::Limits, lights: usize) -> Result<(), RuntimeError> {
        let (w, h) = (self.width, self.height);
        let side = limits.max_texture_dimension_2d;
        if w > side || h > side {
            return Err(RuntimeError::Unsupported(format!(
                "image size {w}x{h}: this GPU's textures are at most {side} pixels a side"
            )));
        }
        let binding = crate::load::storage_binding_bytes(limits);
        let bytes = u64::from(w) * u64::from(h) * FRAME_BYTES_PER_PIXEL;
        if bytes > binding {
            let pixels = binding / FRAME_BYTES_PER_PIXEL;
            // The same aspect ratio at the most pixels that fit.
            let scale = (pixels as f64 / (f64::from(w) * f64::from(h))).sqrt();
            let fit = |v: u32| ((f64::from(v) * scale).floor() as u32).max(1);
            return Err(RuntimeError::Unsupported(format!(
                "image size {w}x{h}: a per-pixel buffer of {} MiB is beyond this GPU's {} MiB \
                 per storage binding; at most {:.1} megapixels here ({}x{} at this aspect)",
                bytes >> 20,
                binding >> 20,
                pixels as f64 / 1e6,
                fit(w),
                fit(h)
            )));
        }
        if self.shadow_resolution > side {
            return Err(RuntimeError::Unsupported(format!(
                "shadow-resolution {}: this GPU's textures are at most {side} texels a side",
                self.shadow_resolution
            )));
        }
        let layers = limits.max_texture_array_layers as usize;
        if lights > layers {
            return Err(RuntimeError::Unsupported(format!(
                "the scene has {lights} lights; this GPU's shadow maps hold at most {layers} (one \
                 texture array layer each)"
            )));
        }
        Ok(())
    }
}

/// Refuses image sizes outside 1 to [`MAX_SIDE`].
pub fn check_size(w: u32, h: u32) -> Result<(), RuntimeError> {
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(RuntimeError::Unsupported(format!(
            "image size {w}x{h}: each side must be 1 to {MAX_SIDE}"
        )));
    }
    Ok(())
}

/// The shared resources every pass reads: one context instead of a list of arguments.
pub struct FrameContext {
    /// The caller's device.
    pub device: wgpu::Device,
    /// The caller's queue.
    pub queue: wgpu::Queue,
    /// [`GpuView`] uniform: camera, image size, light count, exposure.
    pub view: wgpu::Buffer,
    /// The camera as last set.
    pub camera: View,
    /// The scene in GPU memory.
    pub scene: SceneGpu,
    /// Shadow maps and the light buffer.
    pub shadows: ShadowMaps,
    /// The G-buffer of the current size.
    pub gbuffer: GBuffer,
    /// The `.cssm` in GPU memory, when the method needs one.
    pub cssm: Option<CssmResources>,
    /// The frame's settings.
    pub settings: FrameSettings,
}

impl FrameContext {
    /// Places object `index` of the scene's objects at `transform` (object to world; rigid,
    /// with a uniform scale): writes its motion since loading (`SceneGpu::motion`, which the
    /// raster passes and, with moving objects, the atlas texels read: `posed.wgsl`), its
    /// placement for the moving objects' query (§3.3) and refits the hierarchy around the
    /// texels where they are now (`radiosity::MovingTexels`). The caller runs the prepare
    /// passes again (`Renderer::set_object_transform` does).
    ///
    /// # Errors
    /// An index past the scene's objects, or a transform that is not finite or not invertible.
    pub fn place_object(
        &mut self,
        index: usize,
        transform: glam::Affine3A,
    ) -> Result<(), RuntimeError> {
        let scene = &self.scene;
        let Some(loaded) = scene.load_transforms.get(index) else {
            return Err(RuntimeError::Unsupported(format!(
                "object {index}: the scene has {} objects",
                scene.load_transforms.len()
            )));
        };
        let determinant = transform.matrix3.determinant();
        if !(transform.is_finite() && determinant.is_finite() && determinant.abs() > 1e-12) {
            return Err(RuntimeError::Unsupported(format!(
                "object {index}: its transform ({}, determinant {determinant:e}) is not finite \
                 and invertible",
                if transform.is_finite() {
                    "finite"
                } else {
                    "not finite"
                }
            )));
        }
        let motion = transform * loaded.inverse();
        self.queue.write_buffer(
            &scene.motion,
            (index * size_of::<[f32; 16]>()) as u64,
            bytemuck::cast_slice(&glam::Mat4::from(motion).to_cols_array()),
        );
        if let Some(cssm) = &mut self.cssm {
            cssm.moving.set_pose(&self.queue, index, transform);
            // Its texels follow it through the motion above (posed.wgsl); the hierarchy's
            // bounds are refitted around them (§3.3, §4.3).
            if let Some(texels) = &mut cssm.moving_texels {
                texels.place(&self.queue, &cssm.hierarchy, index, motion);
            }
        }
        Ok(())
    }

    /// Uploads `scene` (and `cssm`, if given) and creates the shared resources; the shadow
    /// maps' raster also writes the reflective shadow map when `rsm` (a method reads
    /// [`Slot::Rsm`]).
    ///
    /// # Errors
    /// Unsupported lights or sizes, unreadable textures, buffers beyond the device's limits.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: &Scene,
        cssm: Option<&CssmFile>,
        settings: FrameSettings,
        rsm: bool,
    ) -> Result<Self, RuntimeError> {
        settings.check()?;
        let scene_gpu = SceneGpu::new(device, queue, scene, cssm)?;
        let lights = shadow_map::gpu_lights(scene, settings.shadow_resolution)?;
        let resolution = settings.shadow_resolution;
        let shadows = ShadowMaps::new(device, &scene_gpu, &lights, resolution, rsm);
        let camera = View::of_scene(scene, settings.width, settings.height);
        let view = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("view"),
            contents: bytemuck::bytes_of(&camera.gpu(shadows.light_count, settings.exposure)),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let gbuffer = GBuffer::new(device, &scene_gpu, &view, settings.width, settings.height);
        let emitting = crate::radiosity::emitting_materials(scene);
        let cssm = match cssm {
            Some(file) => Some(CssmResources {
                query: CssmGpu::new(device, queue, file, settings.visibility)?,
                moving: crate::visibility::moving::MovingGpu::new(
                    device,
                    file,
                    scene,
                    &scene_gpu.motion,
                )?,
                hierarchy: HierarchyGpu::new(device, &file.hierarchy, &file.texels, &emitting)?,
                moving_texels: crate::radiosity::MovingTexels::new(
                    file,
                    scene.objects.len(),
                    &emitting,
                ),
            }),
            None => None,
        };
        Ok(Self {
            device: device.clone(),
            queue: queue.clone(),
            view,
            camera,
            scene: scene_gpu,
            shadows,
            gbuffer,
            cssm,
            settings,
        })
    }

    /// The `.cssm` resources; a method whose entry says it needs a `.cssm` always has them.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] when none was loaded.
    pub fn cssm(&self) -> Result<&CssmResources, RuntimeError> {
        self.cssm.as_ref().ok_or_else(|| {
            RuntimeError::Unsupported("this method needs the scene's .cssm file".into())
        })
    }

    /// Image width and height.
    pub fn size(&self) -> (u32, u32) {
        (self.settings.width, self.settings.height)
    }

    /// A storage buffer of one `vec4f` per pixel of the current size, row-major: a method's
    /// indirect radiance ([`crate::method::GiMethod::indirect`]).
    pub fn pixel_buffer(&self, label: &str) -> wgpu::Buffer {
        let (w, h) = self.size();
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: 16 * (w * h) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        })
    }

    /// The view constants as the GPU reads them.
    pub fn gpu_view(&self) -> GpuView {
        self.camera
            .gpu(self.shadows.light_count, self.settings.exposure)
    }

    /// Writes the view constants after the camera, size or exposure changed.
    pub fn upload_view(&self) {
        self.queue
            .write_buffer(&self.view, 0, bytemuck::bytes_of(&self.gpu_view()));
    }
}

/// What a pass records into: the frame's command encoder, the pass timer, and the frame's index
/// since the last restart of progressive accumulation.
pub struct FrameEncoder<'a> {
    /// The caller's encoder.
    pub encoder: &'a mut wgpu::CommandEncoder,
    /// GPU timestamps per pass.
    pub timer: &'a mut PassTimer,
    /// Frames since the camera, a light or an object last moved (0 for the first).
    pub index: u32,
}

impl FrameEncoder<'_> {
    /// Begins a compute pass timed as `name`.
    pub fn compute_pass(&mut self, name: &'static str) -> wgpu::ComputePass<'_> {
        self.encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(name),
                timestamp_writes: self.timer.compute(name),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::method::{Backend, METHODS};

    #[test]
    fn the_shared_schedule_holds_without_a_method() {
        assert_eq!(check_schedule(&schedule(&[]), false), Ok(()));
        // Without a method that writes it, the indirect light is not there to compose.
        assert!(check_schedule(&schedule(&[]), true).is_err());
    }

    #[test]
    fn a_prepare_pass_cannot_read_the_gbuffer() {
        let bad = [PassInfo {
            name: "bad",
            stage: Stage::Prepare,
            reads: &[Slot::GBuffer],
            writes: &[Slot::Indirect],
        }];
        let err = check_schedule(&schedule(&bad), true).unwrap_err();
        assert!(err.contains("'bad' reads GBuffer"), "{err}");
    }

    /// Every GPU method's declared passes fit the frame.
    #[test]
    fn every_method_schedule_is_consistent() {
        for m in METHODS {
            if let Backend::Gpu(_) = m.backend {
                let passes = m.passes;
                let indirect = passes.iter().any(|p| p.writes.contains(&Slot::Indirect));
                check_schedule(&schedule(passes), indirect)
                    .unwrap_or_else(|e| panic!("{}: {e}", m.name));
            }
        }
    }
}
