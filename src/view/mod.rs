//! `cssm view`: a window over the runtime's persistent [`Renderer`]. Every frame is rendered
//! exactly as `cssm render` renders it, into an offscreen `Rgba8Unorm` image (the same
//! settings, [`crate::render::renderer_settings`]), then copied onto the window's surface by a
//! fullscreen triangle (`blit.wgsl`). A screenshot (F12, `--screenshot`) is that image read
//! back, so it is byte for byte what `cssm render` writes for the same camera, light, method,
//! size and frame count: `tests/view.rs` checks it under Xvfb.
//!
//! The camera and light controls are [`controls`]; accumulation restarts whenever the renderer
//! is given a new camera or light (`Renderer::set_camera`, `Renderer::set_light`).

mod controls;

use std::{
    path::PathBuf,
    process::ExitCode,
    sync::Arc,
    time::{Duration, Instant},
};

use cssm::{formats, runtime};
use formats::{Camera, CssmFile, Scene, scene::SpotLight};
use runtime::{
    Gpu, Renderer, RendererSettings,
    common::{compose::Component, readback},
    method::{MethodEntry, OptionValue, OptionValues},
};
use winit::{
    application::ApplicationHandler,
    dpi::{PhysicalPosition, PhysicalSize},
    event::{ElementState, KeyEvent, MouseButton, MouseScrollDelta, WindowEvent},
    event_loop::{ActiveEventLoop, EventLoop},
    keyboard::{Key, KeyCode, ModifiersState, NamedKey, PhysicalKey},
    window::{Window, WindowId},
};

use crate::{
    CliResult, check_writable,
    cli::ViewConfig,
    load_scene,
    render::{render_cssm, renderer_settings, save_rgba_png},
    scene_dir,
};

/// Frames accumulated before the window stops rendering until something changes: the methods
/// that jitter have converged long before, and the others draw the same image every frame.
const ACCUMULATE_FRAMES: u32 = 1024;

/// Runs `cssm view`: the window until Esc or close, or until the `--screenshot` is written.
pub fn run_view(config: ViewConfig) -> CliResult {
    let dir = scene_dir(config.render.scene.clone())?;
    let scene = load_scene(&dir)?;
    let mut inputs = scene.input_files();
    inputs.extend(config.render.cssm.clone());
    if let Some(shot) = &config.screenshot {
        check_writable(shot, &inputs)?;
    }
    let settings = renderer_settings(&config.render, &scene, &dir)?;
    // The display first: without one nothing else (a bake) is worth doing.
    let event_loop = EventLoop::new().map_err(|e| no_window(&e))?;
    // The .cssm given, else one baked when the first method needs it; without one, Tab skips
    // the methods that need it.
    let cssm = if config.render.cssm.is_some() || config.render.method.needs_cssm {
        Some(render_cssm(&config.render, &scene)?)
    } else {
        None
    };
    let mut app = App {
        state: None,
        outcome: None,
        view: ViewState {
            screenshot: config.screenshot.clone(),
            frames: config.render.frames,
            ..ViewState::new(
                scene,
                cssm,
                settings,
                config.render.method,
                config.render.values.clone(),
            )
        },
    };
    event_loop.run_app(&mut app).map_err(|e| no_window(&e))?;
    app.outcome.unwrap_or_else(|| {
        Err("cssm view: the window system closed the event loop before a window opened".into())
    })
}

/// The error of a missing or refusing display.
fn no_window(e: &dyn std::fmt::Display) -> String {
    // winit's OS errors start with the location in winit's source: not the user's concern.
    let text = e.to_string();
    let cause = text
        .strip_prefix("os error at ")
        .and_then(|rest| rest.split_once(": "))
        .map_or(text.as_str(), |(_, cause)| cause);
    format!(
        "cssm view: cannot open a window: {cause} (no display? run under Xvfb: `xvfb-run -a \
         cssm view ...`, or write images with `cssm render`)"
    )
}

/// What the window shows, apart from the GPU objects: kept across renderer rebuilds.
struct ViewState {
    scene: Scene,
    cssm: Option<CssmFile>,
    settings: RendererSettings,
    method: &'static MethodEntry,
    values: OptionValues,
    camera: Camera,
    light: Option<SpotLight>,
    screenshot: Option<PathBuf>,
    frames: u32,
    /// The renderer must be rebuilt (method, component or option changed).
    rebuild: bool,
    /// F12 was pressed: write a screenshot after the next frame.
    shot_requested: bool,
    camera_moved: bool,
    light_moved: bool,
    /// The mouse: where it was, which buttons are down, the modifiers.
    cursor: Option<PhysicalPosition<f64>>,
    left: bool,
    right: bool,
    modifiers: ModifiersState,
    /// GPU time of the last frame (sum of its passes) and when the passes were last printed.
    frame_ms: f64,
    last_print: Instant,
}

impl ViewState {
    /// An interactive view of `scene` with `method` (no `--screenshot`).
    fn new(
        scene: Scene,
        cssm: Option<CssmFile>,
        settings: RendererSettings,
        method: &'static MethodEntry,
        values: OptionValues,
    ) -> Self {
        Self {
            cssm,
            settings,
            method,
            values,
            camera: scene.camera.clone(),
            light: scene.lights.first().cloned(),
            screenshot: None,
            frames: 1,
            scene,
            rebuild: false,
            shot_requested: false,
            camera_moved: false,
            light_moved: false,
            cursor: None,
            left: false,
            right: false,
            modifiers: ModifiersState::empty(),
            frame_ms: 0.0,
            last_print: Instant::now(),
        }
    }

    /// A renderer of the current method, options and component, looking through the current
    /// camera at the current light. The scene's own camera and light are not set again, so a
    /// window that nothing moved renders exactly what `cssm render` renders.
    fn build(&self, gpu: &Gpu) -> Result<Renderer, String> {
        let scene = &self.scene;
        let fail = |e: runtime::RuntimeError| format!("{}: {e}", scene.path.display());
        let mut renderer = Renderer::new(
            &gpu.device,
            &gpu.queue,
            scene,
            self.cssm.as_ref(),
            self.method,
            &self.values,
            &self.settings,
        )
        .map_err(fail)?;
        if self.camera != scene.camera {
            renderer.set_camera(&self.camera).map_err(fail)?;
        }
        if let Some(light) = &self.light
            && Some(light) != scene.lights.first()
        {
            renderer.set_light(0, light).map_err(fail)?;
        }
        Ok(renderer)
    }

    /// "scene, method (options), component": the title's and the messages' description.
    fn describe(&self) -> String {
        let options: Vec<String> = self
            .method
            .resolve(&self.values)
            .map(|r| r.iter().map(|(k, v)| format!("{k} {v}")).collect())
            .unwrap_or_default();
        format!(
            "{} - {}{} - {}",
            self.scene.name,
            self.method,
            if options.is_empty() {
                String::new()
            } else {
                format!(" ({})", options.join(", "))
            },
            self.settings.component.name()
        )
    }

    /// The next (`step` 1) or previous (-1) GPU method of the table the window can build: one
    /// needing a `.cssm` only when one is loaded.
    fn cycle_method(&mut self, step: isize) {
        let table = runtime::method::METHODS;
        let here = table
            .iter()
            .position(|m| m.name == self.method.name)
            .unwrap_or(0) as isize;
        let n = table.len() as isize;
        for k in 1..n {
            let candidate = &table[(here + step * k).rem_euclid(n) as usize];
            if !candidate.on_gpu() {
                continue;
            }
            if candidate.needs_cssm && self.cssm.is_none() {
                eprintln!(
                    "skipping {candidate}: it needs the scene's .cssm (start with --cssm FILE, \
                     or with a method that needs one to bake one)"
                );
                continue;
            }
            self.method = candidate;
            // Each method starts from its defaults; the window accumulates, so the methods
            // that jitter do (as `cssm render --frames N`).
            self.values = OptionValues::default();
            if candidate.option("jitter").is_some() {
                self.values.set("jitter", OptionValue::Switch(true));
            }
            self.rebuild = true;
            return;
        }
    }

    /// Sets option `name` to `value` if the method has it and takes the value; says why not
    /// otherwise.
    fn set_option(&mut self, name: &str, value: impl Fn(OptionValue) -> Option<OptionValue>) {
        let Some(spec) = self.method.option(name) else {
            eprintln!("method {} has no option '{name}'", self.method);
            return;
        };
        let current = self.values.get(name).unwrap_or_else(|| spec.kind.default());
        let Some(next) = value(current) else { return };
        match spec.check(next) {
            Ok(()) => {
                self.values.set(name, next);
                self.rebuild = true;
            }
            Err(e) => eprintln!("{name}: {e}"),
        }
    }
}

/// The window and what draws into it, created once the event loop resumes.
struct Gfx {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    gpu: Gpu,
    renderer: Renderer,
    /// The renderer's target: what a screenshot reads back.
    image: wgpu::Texture,
    blit: Blit,
    /// The next F12 screenshot's number.
    shots: u32,
}

struct App {
    state: Option<Gfx>,
    outcome: Option<CliResult>,
    view: ViewState,
}

impl App {
    /// Ends the event loop with `outcome` (the first one given wins).
    fn finish(&mut self, event_loop: &ActiveEventLoop, outcome: CliResult) {
        self.outcome.get_or_insert(outcome);
        event_loop.exit();
    }

    fn open(&self, event_loop: &ActiveEventLoop) -> Result<Gfx, String> {
        let (width, height) = (
            self.view.settings.frame.width,
            self.view.settings.frame.height,
        );
        let attributes = Window::default_attributes()
            .with_title(format!("cssm view - {}", self.view.describe()))
            .with_inner_size(PhysicalSize::new(width, height));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| no_window(&e))?,
        );
        let mut descriptor = wgpu::InstanceDescriptor::new_with_display_handle(Box::new(
            event_loop.owned_display_handle(),
        ));
        descriptor.backends = wgpu::Backends::PRIMARY;
        let instance = wgpu::Instance::new(descriptor.with_env());
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| no_window(&e))?;
        let gpu = Gpu::for_surface(&instance, Some(&surface)).map_err(|e| e.to_string())?;
        let caps = surface.get_capabilities(&gpu.adapter);
        // A plain format shows the image's bytes as they are; an sRGB one needs them decoded
        // first (the blit does).
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| {
                matches!(
                    f,
                    wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Rgba8Unorm
                )
            })
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| {
                format!(
                    "cssm view: the GPU ({}) cannot present to this window",
                    gpu.describe()
                )
            })?;
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            color_space: wgpu::SurfaceColorSpace::Auto,
            width: size.width.max(1),
            height: size.height.max(1),
            desired_maximum_frame_latency: 2,
            // A script's screenshot waits for no vertical blank.
            present_mode: if self.view.screenshot.is_some() {
                wgpu::PresentMode::AutoNoVsync
            } else {
                wgpu::PresentMode::AutoVsync
            },
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: vec![],
        };
        surface.configure(&gpu.device, &config);
        let renderer = self.view.build(&gpu)?;
        let image = readback::offscreen_target(&gpu.device, width, height);
        let blit = Blit::new(&gpu.device, format, &image);
        eprintln!(
            "viewing {} on {} (Esc quits; `cssm view --help` lists the keys)",
            self.view.describe(),
            gpu.describe()
        );
        Ok(Gfx {
            window,
            surface,
            config,
            gpu,
            renderer,
            image,
            blit,
            shots: 0,
        })
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_some() {
            return;
        }
        match self.open(event_loop) {
            Ok(gfx) => {
                gfx.window.request_redraw();
                self.state = Some(gfx);
            }
            Err(e) => self.finish(event_loop, Err(e)),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        if self.state.is_none() {
            return;
        }
        match event {
            WindowEvent::CloseRequested => self.finish(event_loop, Ok(ExitCode::SUCCESS)),
            WindowEvent::Resized(size) => self.resize(size),
            WindowEvent::ModifiersChanged(m) => self.view.modifiers = m.state(),
            WindowEvent::KeyboardInput { event, .. } => self.key(event_loop, &event),
            WindowEvent::MouseInput { state, button, .. } => {
                let down = state == ElementState::Pressed;
                match button {
                    MouseButton::Left => self.view.left = down,
                    MouseButton::Right => self.view.right = down,
                    _ => {}
                }
            }
            WindowEvent::CursorMoved { position, .. } => self.mouse_moved(position),
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.view.camera = controls::dolly(&self.view.camera, lines, &self.view.scene);
                self.view.camera_moved = true;
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.finish(event_loop, Err(e));
                }
            }
            _ => {}
        }
        self.request_frame();
    }
}

impl App {
    /// Asks for the next frame while there is anything to draw: a change, or accumulation not
    /// yet done.
    fn request_frame(&self) {
        let Some(gfx) = &self.state else { return };
        let view = &self.view;
        // A script's screenshot may ask for more frames than a window accumulates.
        let frames = match view.screenshot {
            Some(_) => view.frames,
            None => ACCUMULATE_FRAMES,
        };
        if view.rebuild
            || view.shot_requested
            || view.camera_moved
            || view.light_moved
            || gfx.renderer.frames_accumulated() < frames
        {
            gfx.window.request_redraw();
        }
    }

    fn resize(&mut self, size: PhysicalSize<u32>) {
        let Some(gfx) = &mut self.state else { return };
        if size.width == 0 || size.height == 0 {
            return;
        }
        gfx.config.width = size.width;
        gfx.config.height = size.height;
        gfx.surface.configure(&gfx.gpu.device, &gfx.config);
        // A script's image keeps the size it asked for (the window manager may not grant it);
        // an interactive window renders at the window's size.
        if self.view.screenshot.is_some() {
            return;
        }
        match gfx.renderer.resize(size.width, size.height) {
            Ok(()) => {
                self.view.settings.frame.width = size.width;
                self.view.settings.frame.height = size.height;
                gfx.image = readback::offscreen_target(&gfx.gpu.device, size.width, size.height);
                gfx.blit.bind(&gfx.gpu.device, &gfx.image);
            }
            Err(e) => eprintln!("cannot render at {}x{}: {e}", size.width, size.height),
        }
    }

    fn mouse_moved(&mut self, position: PhysicalPosition<f64>) {
        let view = &mut self.view;
        let last = view.cursor.replace(position);
        let Some(last) = last else { return };
        let (dx, dy) = ((position.x - last.x) as f32, (position.y - last.y) as f32);
        if view.left {
            view.camera = controls::orbit(&view.camera, dx, dy);
            view.camera_moved = true;
        } else if view.right
            && let Some(light) = &view.light
        {
            view.light = Some(if view.modifiers.shift_key() {
                controls::move_light(light, &view.camera, dx, dy, &view.scene)
            } else {
                controls::aim_light(light, &view.camera, dx, dy)
            });
            view.light_moved = true;
        }
    }

    fn key(&mut self, event_loop: &ActiveEventLoop, event: &KeyEvent) {
        if event.state != ElementState::Pressed {
            return;
        }
        let view = &mut self.view;
        let shift = view.modifiers.shift_key();
        // The fly keys by their place on the keyboard (WASD on any layout); key repeat flies on.
        if let PhysicalKey::Code(code) = event.physical_key {
            let step = match code {
                KeyCode::KeyW => Some((1.0, 0.0, 0.0)),
                KeyCode::KeyS => Some((-1.0, 0.0, 0.0)),
                KeyCode::KeyD => Some((0.0, 1.0, 0.0)),
                KeyCode::KeyA => Some((0.0, -1.0, 0.0)),
                KeyCode::KeyE => Some((0.0, 0.0, 1.0)),
                KeyCode::KeyQ => Some((0.0, 0.0, -1.0)),
                _ => None,
            };
            if let Some((forward, right, up)) = step {
                view.camera = controls::fly(&view.camera, forward, right, up, &view.scene);
                view.camera_moved = true;
                return;
            }
        }
        match &event.logical_key {
            Key::Named(NamedKey::Escape) => self.finish(event_loop, Ok(ExitCode::SUCCESS)),
            Key::Named(NamedKey::Tab) if !event.repeat => {
                view.cycle_method(if shift { -1 } else { 1 })
            }
            // After the next frame, so that the image holds every change made before F12.
            Key::Named(NamedKey::F12) if !event.repeat => view.shot_requested = true,
            Key::Character(c) => match c.as_str() {
                "c" | "C" if !event.repeat => {
                    let all = Component::ALL;
                    let here = all
                        .iter()
                        .position(|c| *c == view.settings.component)
                        .unwrap_or(0);
                    view.settings.component = all[(here + 1) % all.len()];
                    view.rebuild = true;
                }
                "[" => view.set_option("bounces", |v| match v {
                    OptionValue::Count(n) => n.checked_sub(1).map(OptionValue::Count),
                    _ => None,
                }),
                "]" => view.set_option("bounces", |v| match v {
                    OptionValue::Count(n) => Some(OptionValue::Count(n + 1)),
                    _ => None,
                }),
                "-" => view.set_option("threshold", |v| match v {
                    OptionValue::Number(x) => Some(OptionValue::Number(x * 0.5)),
                    _ => None,
                }),
                "=" | "+" => view.set_option("threshold", |v| match v {
                    OptionValue::Number(x) => Some(OptionValue::Number(x * 2.0)),
                    _ => None,
                }),
                _ => {}
            },
            _ => {}
        }
    }

    /// Applies what changed, renders a frame into the image, copies it onto the surface, and
    /// writes the `--screenshot` once its frames are done.
    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
        let view = &mut self.view;
        let Some(gfx) = &mut self.state else {
            return Ok(());
        };
        let fail = |e: runtime::RuntimeError| format!("{}: {e}", view.scene.path.display());
        if view.rebuild {
            view.rebuild = false;
            match view.build(&gfx.gpu) {
                Ok(renderer) => {
                    gfx.renderer = renderer;
                    eprintln!("now {}", view.describe());
                }
                // The old renderer stays: a method this device cannot build is no reason to
                // close the window.
                Err(e) => eprintln!("cannot switch to {}: {e}", view.describe()),
            }
        }
        if std::mem::take(&mut view.camera_moved) {
            gfx.renderer.set_camera(&view.camera).map_err(fail)?;
        }
        if std::mem::take(&mut view.light_moved)
            && let Some(light) = &view.light
            && let Err(e) = gfx.renderer.set_light(0, light)
        {
            // A light the shadow maps cannot hold (aimed away from the scene): keep the last.
            eprintln!("{e}");
        }
        let device = gfx.gpu.device.clone();
        let image_view = gfx.image.create_view(&Default::default());
        let mut encoder = device.create_command_encoder(&Default::default());
        gfx.renderer.render(&mut encoder, &image_view);
        let surface_texture = match gfx.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => Some(t),
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                gfx.surface.configure(&device, &gfx.config);
                None
            }
            // Hidden, busy or refused: the image is still rendered (and accumulates); it shows
            // at the next frame.
            _ => None,
        };
        if let Some(texture) = &surface_texture {
            let target = texture.texture.create_view(&Default::default());
            gfx.blit.run(&mut encoder, &target);
        }
        gfx.gpu.queue.submit([encoder.finish()]);
        if let Some(texture) = surface_texture {
            gfx.window.pre_present_notify();
            gfx.gpu.queue.present(texture);
        }
        // Timings read back as `cssm render` reads them, every frame (this waits for the GPU,
        // which also keeps the window from queueing frames ahead of the input).
        let timings = gfx.renderer.read_timings().map_err(fail)?;
        gfx.gpu.wait().map_err(fail)?;
        view.frame_ms = timings.iter().map(|(_, ms)| ms).sum();
        let accumulated = gfx.renderer.frames_accumulated();
        gfx.window.set_title(&format!(
            "cssm view - {} - {:.2} ms - {accumulated} frames",
            view.describe(),
            view.frame_ms
        ));
        if view.last_print.elapsed() >= Duration::from_secs(1) && !timings.is_empty() {
            view.last_print = Instant::now();
            let passes: Vec<String> = timings
                .iter()
                .map(|(pass, ms)| format!("{pass} {ms:.3}"))
                .collect();
            eprintln!(
                "{accumulated} frames, {:.3} ms: {}",
                view.frame_ms,
                passes.join(", ")
            );
        }
        if std::mem::take(&mut view.shot_requested)
            && let Err(e) = self.screenshot(None)
        {
            // A failed F12 (a full disk) is no reason to close the window.
            eprintln!("{e}");
        }
        if let Some(path) = self.view.screenshot.clone()
            && accumulated >= self.view.frames
        {
            self.screenshot(Some(path))?;
            self.finish(event_loop, Ok(ExitCode::SUCCESS));
        }
        Ok(())
    }

    /// Writes the last frame's image: to `path`, or (F12) to the first free
    /// `cssm-view-NNNN.png` in the current directory.
    fn screenshot(&mut self, path: Option<PathBuf>) -> Result<(), String> {
        let Some(gfx) = &mut self.state else {
            return Ok(());
        };
        let path = match path {
            Some(path) => path,
            None => loop {
                let candidate = PathBuf::from(format!("cssm-view-{:04}.png", gfx.shots));
                gfx.shots += 1;
                if !candidate.exists() {
                    break candidate;
                }
            },
        };
        let (w, h) = (gfx.image.width(), gfx.image.height());
        let rgba = readback::read_texture(&gfx.gpu.device, &gfx.gpu.queue, &gfx.image, 4)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        save_rgba_png(&path, w, h, rgba)?;
        eprintln!(
            "wrote {} ({}, {} frames)",
            path.display(),
            self.view.describe(),
            gfx.renderer.frames_accumulated()
        );
        Ok(())
    }
}

/// The copy of the image onto the surface (`blit.wgsl`).
struct Blit {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    bind_group: wgpu::BindGroup,
}

impl Blit {
    fn new(device: &wgpu::Device, format: wgpu::TextureFormat, image: &wgpu::Texture) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("view blit"),
            source: wgpu::ShaderSource::Wgsl(include_str!("blit.wgsl").into()),
        });
        let stage = wgpu::ShaderStages::FRAGMENT;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("view blit"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: stage,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: stage,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("view blit"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("view blit"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(if format.is_srgb() {
                    "fs_srgb"
                } else {
                    "fs_unorm"
                }),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        // Nearest texels: a window of the image's size shows its pixels unblurred.
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("view blit"),
            ..Default::default()
        });
        let bind_group = Self::bind_group(device, &layout, &sampler, image);
        Self {
            pipeline,
            layout,
            sampler,
            bind_group,
        }
    }

    fn bind_group(
        device: &wgpu::Device,
        layout: &wgpu::BindGroupLayout,
        sampler: &wgpu::Sampler,
        image: &wgpu::Texture,
    ) -> wgpu::BindGroup {
        let view = image.create_view(&Default::default());
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("view blit"),
            layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(sampler),
                },
            ],
        })
    }

    /// Samples `image` from now on (after a resize).
    fn bind(&mut self, device: &wgpu::Device, image: &wgpu::Texture) {
        self.bind_group = Self::bind_group(device, &self.layout, &self.sampler, image);
    }

    fn run(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::TextureView) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("view blit"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cornell(method: &str) -> ViewState {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
        let scene = Scene::load(&dir).expect("the Cornell box loads");
        let method = runtime::method::find(method).unwrap();
        ViewState::new(
            scene,
            None,
            RendererSettings::default(),
            method,
            OptionValues::default(),
        )
    }

    #[test]
    fn tab_cycles_the_gpu_methods_that_need_no_cssm_and_comes_back() {
        let mut view = cornell("direct");
        let mut seen = vec![view.method.name];
        loop {
            view.cycle_method(1);
            assert!(std::mem::take(&mut view.rebuild));
            if view.method.name == "direct" {
                break;
            }
            assert!(
                view.method.on_gpu() && !view.method.needs_cssm,
                "{}",
                view.method
            );
            seen.push(view.method.name);
            assert!(seen.len() <= runtime::method::METHODS.len(), "{seen:?}");
        }
        let expected: Vec<&str> = runtime::method::METHODS
            .iter()
            .filter(|m| m.on_gpu() && !m.needs_cssm)
            .map(|m| m.name)
            .collect();
        assert_eq!(seen, expected);
        // Shift + Tab goes back the same way.
        view.cycle_method(-1);
        assert_eq!(view.method.name, *expected.last().unwrap());
    }

    #[test]
    fn bounces_change_within_the_methods_range_and_only_where_it_exists() {
        let mut view = cornell("vct");
        let up = |v: OptionValue| match v {
            OptionValue::Count(n) => Some(OptionValue::Count(n + 1)),
            _ => None,
        };
        let down = |v: OptionValue| match v {
            OptionValue::Count(n) => n.checked_sub(1).map(OptionValue::Count),
            _ => None,
        };
        let default = view.method.option("bounces").unwrap().kind.default();
        view.set_option("bounces", up);
        assert!(std::mem::take(&mut view.rebuild));
        assert_ne!(view.values.get("bounces"), Some(default));
        view.set_option("bounces", down);
        assert!(std::mem::take(&mut view.rebuild));
        assert_eq!(view.values.get("bounces"), Some(default));
        // Down to the table's least bounce count, and no further: refused, nothing rebuilt.
        let runtime::method::OptionKind::Count { min, .. } =
            view.method.option("bounces").unwrap().kind
        else {
            panic!("bounces is a count")
        };
        for _ in 0..=runtime::method::MAX_BOUNCES {
            view.set_option("bounces", down);
        }
        assert_eq!(view.values.get("bounces"), Some(OptionValue::Count(min)));
        view.rebuild = false;
        view.set_option("bounces", down);
        assert!(!view.rebuild);
        assert_eq!(view.values.get("bounces"), Some(OptionValue::Count(min)));
        let mut direct = cornell("direct");
        direct.set_option("bounces", |_| Some(OptionValue::Count(2)));
        assert!(!direct.rebuild && direct.values.get("bounces").is_none());
    }
}
