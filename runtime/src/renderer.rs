//! The persistent renderer: built once from the caller's device and queue, a scene, an
//! optional `.cssm` and a method of [`crate::method::METHODS`]; then camera and light updates,
//! resizes, and one `render` per frame into the caller's target. Pipelines, bind groups and
//! buffers are created once (and again on resize for what depends on the size); a frame records
//! only the per-frame passes ([`crate::frame`] lists them in order). Read-back and image files
//! are the caller's (the command line's: [`crate::common::readback::render_image`]).

use cssm_formats::{Camera, CssmFile, Scene, scene::SpotLight};
use glam::Vec3;

use crate::{
    RuntimeError,
    common::{
        camera::View, compose::Component, compose::Compose, shadow_map, timestamps::PassTimer,
        tonemap::Tonemap,
    },
    direct::ScreenDirect,
    frame::{self, FrameContext, FrameEncoder, FrameSettings},
    method::{Backend, GiMethod, MethodEntry, MethodSetup, OptionValues, Resolved},
};

/// What the renderer draws, beside the method's own options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RendererSettings {
    /// Image size, exposure, shadow-map resolution.
    pub frame: FrameSettings,
    /// Which light paths the image holds.
    pub component: Component,
    /// Format of the targets [`Renderer::render`] draws into (`Rgba8Unorm` for an offscreen
    /// image whose bytes are the CPU tone mapping's; a swapchain's format for a window).
    pub target_format: wgpu::TextureFormat,
}

impl Default for RendererSettings {
    fn default() -> Self {
        Self {
            frame: FrameSettings::default(),
            component: Component::Full,
            target_format: wgpu::TextureFormat::Rgba8Unorm,
        }
    }
}

/// The error of a renderer's resources that wgpu refused: a method's buffer beyond the
/// storage binding limit (a method may hold more per pixel than the frame's
/// [`frame::FRAME_BYTES_PER_PIXEL`]) said in words; anything else as wgpu says it.
fn build_error(e: &wgpu::Error, method: &MethodEntry, frame: &FrameSettings) -> RuntimeError {
    let text = e.to_string();
    if text.contains("max_*_buffer_binding_size") || text.contains("max_buffer_size") {
        RuntimeError::Unsupported(format!(
            "image size {}x{}: method '{method}' needs a GPU buffer beyond this device's \
             storage binding limit at this size; render a smaller image (wgpu: {})",
            frame.width,
            frame.height,
            text.lines().last().unwrap_or_default().trim()
        ))
    } else {
        RuntimeError::Gpu(text)
    }
}

/// A scene and a method on the GPU, ready to render frame after frame (see the module docs).
///
/// ```no_run
/// # fn demo(device: &wgpu::Device, queue: &wgpu::Queue, target: &wgpu::TextureView)
/// #     -> Result<(), cssm_runtime::RuntimeError> {
/// use cssm_runtime::{Renderer, RendererSettings, load::read_cssm, method};
/// let scene = cssm_formats::Scene::load("scenes/cornell-box".as_ref())?;
/// let cssm = read_cssm("cornell-box.cssm".as_ref(), &scene)?;
/// let mut renderer = Renderer::new(
///     device, queue, &scene, Some(&cssm),
///     method::find("lightmap")?, &Default::default(), &RendererSettings::default(),
/// )?;
/// let mut encoder = device.create_command_encoder(&Default::default());
/// renderer.render(&mut encoder, target);
/// queue.submit([encoder.finish()]);
/// # Ok(()) }
/// ```
pub struct Renderer {
    ctx: FrameContext,
    entry: &'static MethodEntry,
    options: Resolved,
    method: Box<dyn GiMethod>,
    direct: ScreenDirect,
    no_indirect: wgpu::Buffer,
    compose: Compose,
    tonemap: Tonemap,
    timer: PassTimer,
    scene_name: String,
    camera: Camera,
    bounds: (Vec3, Vec3),
    lights: Vec<SpotLight>,
    needs_prepare: bool,
    accumulated: u32,
}

impl Renderer {
    /// Uploads `scene` (and `cssm`, when the method needs it) and builds every pipeline of
    /// `method` with `options`. GPU validation errors during creation come back as errors,
    /// whatever error handler the caller's device has.
    ///
    /// # Errors
    /// A CPU method, options out of range, a missing `.cssm` for a method that needs one,
    /// unsupported lights or sizes, unreadable textures, device limits, GPU validation errors.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: &Scene,
        cssm: Option<&CssmFile>,
        method: &'static MethodEntry,
        options: &OptionValues,
        settings: &RendererSettings,
    ) -> Result<Self, RuntimeError> {
        let Backend::Gpu(build) = method.backend else {
            return Err(RuntimeError::Unsupported(format!(
                "method '{method}' runs on the CPU, not in the GPU renderer (`cssm render \
                 --method {method}` runs it)"
            )));
        };
        let options = method.resolve(options)?;
        let cssm = match (method.needs_cssm, cssm) {
            (true, None) => {
                return Err(RuntimeError::Unsupported(format!(
                    "method '{method}' needs the scene's .cssm file"
                )));
            }
            (true, Some(file)) => {
                crate::load::check_scene("the .cssm file".as_ref(), file, scene)?;
                Some(file)
            }
            (false, _) => None,
        };
        settings
            .frame
            .check_limits(&device.limits(), scene.lights.len())?;
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let built = Self::build(device, queue, scene, cssm, method, options, settings, build);
        let errors = [memory.pop(), validation.pop()].map(pollster::block_on);
        if let Some(e) = errors.into_iter().flatten().next() {
            return Err(build_error(&e, method, &settings.frame));
        }
        built
    }

    #[allow(clippy::too_many_arguments)]
    fn build(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        scene: &Scene,
        cssm: Option<&CssmFile>,
        entry: &'static MethodEntry,
        options: Resolved,
        settings: &RendererSettings,
        build: fn(&MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError>,
    ) -> Result<Self, RuntimeError> {
        let rsm = entry.reads(frame::Slot::Rsm);
        let ctx = FrameContext::new(device, queue, scene, cssm, settings.frame, rsm)?;
        let method = build(&MethodSetup {
            ctx: &ctx,
            scene,
            cssm,
            options: &options,
        })?;
        let direct = ScreenDirect::new(&ctx);
        let no_indirect = zero_indirect(&ctx);
        let indirect = method.indirect().unwrap_or(&no_indirect);
        let compose = Compose::new(&ctx, &direct.radiance, indirect, settings.component);
        let tonemap = Tonemap::new(&ctx, &compose.radiance, settings.target_format);
        let timer = PassTimer::new(device, queue);
        Ok(Self {
            ctx,
            entry,
            options,
            method,
            direct,
            no_indirect,
            compose,
            tonemap,
            timer,
            scene_name: scene.name.clone(),
            camera: scene.camera.clone(),
            bounds: scene.bounds(),
            lights: scene.lights.clone(),
            needs_prepare: true,
            accumulated: 0,
        })
    }

    /// Records a frame into `encoder`, drawn into `target` (the renderer's size, of the
    /// format given at creation). After a change of camera, light, size, or at the first frame,
    /// progressive accumulation restarts; after a change of light the view-independent passes
    /// run first, in the same encoder.
    pub fn render(&mut self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::TextureView) {
        self.timer.begin_frame();
        let ctx = &self.ctx;
        let mut frame = FrameEncoder {
            encoder,
            timer: &mut self.timer,
            index: self.accumulated,
        };
        if self.needs_prepare {
            ctx.shadows.render(&mut frame, &ctx.scene);
            self.method.prepare(ctx, &mut frame);
            self.needs_prepare = false;
        }
        ctx.gbuffer.render(&mut frame, &ctx.scene);
        self.direct.run(&mut frame);
        self.method.encode(ctx, &mut frame);
        self.compose.run(&mut frame);
        self.tonemap.run(&mut frame, target);
        self.timer.resolve(encoder);
        self.accumulated = self.accumulated.saturating_add(1);
    }

    /// GPU milliseconds per pass of the last frame rendered (its command buffer submitted),
    /// empty when the device has no timestamp queries. Waits for the GPU.
    ///
    /// # Errors
    /// A failed read-back.
    pub fn read_timings(&mut self) -> Result<Vec<(&'static str, f64)>, RuntimeError> {
        self.timer.read(&self.ctx.device, &self.ctx.queue)
    }

    /// Renders at `width` x `height` from now on (new G-buffer and per-pixel resources; the
    /// pipelines stay).
    ///
    /// # Errors
    /// Sizes outside 1 to [`frame::MAX_SIDE`]; device limits.
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), RuntimeError> {
        frame::check_size(width, height)?;
        if (width, height) == self.ctx.size() {
            return Ok(());
        }
        let ctx = &mut self.ctx;
        ctx.settings.width = width;
        ctx.settings.height = height;
        ctx.camera = View::new(&self.camera, self.bounds, width, height);
        ctx.upload_view();
        ctx.gbuffer.resize(&ctx.device, width, height);
        let ctx = &self.ctx;
        self.direct.resize(ctx);
        self.no_indirect = zero_indirect(ctx);
        self.method.resize(ctx)?;
        let indirect = self.method.indirect().unwrap_or(&self.no_indirect);
        self.compose.resize(ctx, &self.direct.radiance, indirect);
        self.tonemap.resize(ctx, &self.compose.radiance);
        self.accumulated = 0;
        Ok(())
    }

    /// Looks through `camera` from now on (its `resolution` is ignored: [`Self::resize`] sets
    /// the size); progressive accumulation restarts.
    ///
    /// # Errors
    /// A camera that is not finite, or that looks nowhere.
    pub fn set_camera(&mut self, camera: &Camera) -> Result<(), RuntimeError> {
        let finite = camera.position.is_finite()
            && camera.target.is_finite()
            && camera.up.is_finite()
            && camera.fov_y_deg.is_finite();
        if !finite
            || camera.position == camera.target
            || !(camera.fov_y_deg > 0.0 && camera.fov_y_deg < 180.0)
        {
            return Err(RuntimeError::Unsupported(format!(
                "camera at {} looking at {} with a field of view of {} degrees: needs a finite \
                 position, a distinct target and a field of view between 0 and 180 degrees",
                point(camera.position),
                point(camera.target),
                camera.fov_y_deg
            )));
        }
        let (w, h) = self.ctx.size();
        self.ctx.camera = View::new(camera, self.bounds, w, h);
        self.camera = camera.clone();
        self.ctx.upload_view();
        self.accumulated = 0;
        Ok(())
    }

    /// Replaces spot light `index` (the scene's order); its shadow map and the method's
    /// view-independent passes run again before the next frame.
    ///
    /// # Errors
    /// An index past the scene's lights, or a light the shadow maps cannot hold.
    pub fn set_light(&mut self, index: usize, light: &SpotLight) -> Result<(), RuntimeError> {
        if index >= self.lights.len() {
            return Err(RuntimeError::Unsupported(format!(
                "light {index}: the scene has {} lights",
                self.lights.len()
            )));
        }
        let resolution = self.ctx.settings.shadow_resolution;
        shadow_map::gpu_light(&self.scene_name, light, self.bounds, resolution)?;
        self.lights[index] = light.clone();
        let gpu: Result<Vec<_>, _> = self
            .lights
            .iter()
            .map(|l| shadow_map::gpu_light(&self.scene_name, l, self.bounds, resolution))
            .collect();
        self.ctx.shadows.update(&self.ctx.queue, &gpu?);
        self.needs_prepare = true;
        self.accumulated = 0;
        Ok(())
    }

    /// Places object `index` of `Scene::objects` at `transform` (object space to world space,
    /// as `SceneObject::transform`: rigid, with a uniform scale). The raster passes (shadow maps,
    /// G-buffer) draw it there from the next frame on, the shadow maps and the method's
    /// view-independent passes run again, and accumulation restarts.
    ///
    /// With a `.cssm` that has moving objects, a rigid object moves with everything the
    /// renderer knows of it (§3.3; [`FrameContext::place_object`]): its own maps test its
    /// visibility in its baked frame and its coherent shadow map tests it for everything else,
    /// and its atlas texels move with it, so the light it receives (direct light into the
    /// atlas) and sends and receives in the bounces (radiosity, final gather) are computed where
    /// it stands, over a hierarchy refitted around it. The CPU references render the scene as
    /// loaded, or posed as the caller poses it (`Scene::posed`, `radiosity::cpu::TwinScene`).
    /// A static object moved this way moves in the raster passes and the atlas, but its maps
    /// were baked with the whole static part and its visibility stays the baked scene's.
    ///
    /// # Errors
    /// An index past the scene's objects, or a transform that is not finite or not invertible.
    pub fn set_object_transform(
        &mut self,
        index: usize,
        transform: glam::Affine3A,
    ) -> Result<(), RuntimeError> {
        self.ctx.place_object(index, transform)?;
        self.needs_prepare = true;
        self.accumulated = 0;
        Ok(())
    }

    /// The composed linear radiance of the last frame (`Rgba32Float`, the image size;
    /// `COPY_SRC`, for read-back or OpenEXR).
    pub fn radiance(&self) -> &wgpu::Texture {
        &self.compose.radiance
    }

    /// The shared resources (device, view, scene, shadow maps, G-buffer, `.cssm`).
    pub fn context(&self) -> &FrameContext {
        &self.ctx
    }

    /// The method rendering.
    pub fn method(&self) -> &'static MethodEntry {
        self.entry
    }

    /// The method's options as resolved (defaults filled in).
    pub fn options(&self) -> &Resolved {
        &self.options
    }

    /// How many bounces the method's last view-independent pass ran, for a method whose
    /// bounces stop once converged (read back: waits for the GPU); `None` for the others.
    ///
    /// # Errors
    /// GPU errors of the read-back.
    pub fn convergence(
        &self,
    ) -> Option<Result<crate::common::converge::Convergence, RuntimeError>> {
        self.method.convergence(&self.ctx)
    }

    /// Frames rendered since accumulation last restarted.
    pub fn frames_accumulated(&self) -> u32 {
        self.accumulated
    }

    /// The format [`Self::render`] draws into.
    pub fn target_format(&self) -> wgpu::TextureFormat {
        self.tonemap.format()
    }
}

/// A zero indirect-light buffer for methods without indirect light.
fn zero_indirect(ctx: &FrameContext) -> wgpu::Buffer {
    let (w, h) = ctx.size();
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("no indirect light"),
        size: 16 * (w * h) as u64,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    })
}

/// A point as `(x, y, z)`, for messages.
fn point(p: glam::Vec3) -> String {
    format!("({}, {}, {})", p.x, p.y, p.z)
}
