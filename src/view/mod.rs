//! `cssm view`: a window over the runtime's persistent [`Renderer`]. Every frame is rendered
//! exactly as `cssm render` renders it, into an offscreen `Rgba8Unorm` image (the same
//! settings, [`crate::render::renderer_settings`]), then copied onto the window's surface by a
//! fullscreen triangle (`blit.wgsl`), and the [`overlay`] (egui; H toggles it) is drawn over
//! that copy only. A screenshot (F12, `--screenshot`, a script's `screenshot`) is that image
//! read back, so it is byte for byte what `cssm render` writes for the same camera, light,
//! method, size and frame count, which the screenshot prints as `cssm render` flags:
//! `tests/view.rs` checks it under Xvfb.
//!
//! The camera and light controls are [`controls`]; accumulation restarts whenever the renderer
//! is given a new camera or light (`Renderer::set_camera`, `Renderer::set_light`). Window
//! events and the steps of a `--script` ([`script`]) become the same [`Input`]s, handled by
//! one [`App::input`].

mod controls;
mod overlay;
mod script;

use std::{
    collections::{HashSet, VecDeque},
    path::{Path, PathBuf},
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
    event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent},
    event_loop::{ActiveEventLoop, EventLoop},
    keyboard::{Key, KeyCode, ModifiersState, NamedKey, PhysicalKey},
    window::{Window, WindowId},
};

use crate::{
    CliResult, check_writable,
    cli::{Pose, ViewConfig},
    load_scene,
    render::{posed, render_cssm, renderer_settings, save_radiance_exr, save_rgba_png},
    scene_dir,
};

/// Frames accumulated before the window stops rendering until something changes: the methods
/// that jitter have converged long before, and the others draw the same image every frame.
const ACCUMULATE_FRAMES: u32 = 1024;

/// Scene diagonals per second a held fly key moves the camera.
const FLY_SPEED: f32 = 0.25;

/// Runs `cssm view`: the window until Esc or close, or until the `--screenshot` is written or
/// the `--script` quits.
pub fn run_view(config: ViewConfig) -> CliResult {
    let dir = scene_dir(config.render.scene.clone())?;
    let scene = load_scene(&dir)?;
    let mut inputs = scene.input_files();
    inputs.extend(config.render.cssm.clone());
    if let Some(shot) = &config.screenshot {
        check_writable(shot, &inputs)?;
    }
    // The whole script is read and checked before a window opens: a typo on its last line
    // should not cost a bake and a tour.
    let script = match &config.script {
        Some(path) => {
            let lines = script::load(path)?;
            inputs.push(path.clone());
            for line in &lines {
                let at = |problem: String| format!("{}:{}: {problem}", path.display(), line.number);
                match &line.step {
                    script::Step::Screenshot(shot) => check_writable(shot, &inputs).map_err(at)?,
                    script::Step::Drag {
                        button: MouseButton::Right,
                        ..
                    } if scene.lights.is_empty() => {
                        return Err(at(format!("{} has no spot light to drag", scene.name)));
                    }
                    script::Step::Animate(_) => {
                        crate::animate::Motion::of(&scene).map_err(at)?;
                    }
                    _ => {}
                }
            }
            Some(ScriptRun {
                path: path.clone(),
                steps: lines.into(),
                waiting: 0,
                held: None,
            })
        }
        None => None,
    };
    let settings = renderer_settings(&config.render, &scene, &dir)?;
    let (camera, light) = posed(&config.render, &scene)?;
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
        script,
        view: ViewState {
            screenshot: config.screenshot.clone(),
            frames: config.render.frames,
            scripted: config.screenshot.is_some() || config.script.is_some(),
            shot_exr: config.shot_exr,
            fixed_flags: fixed_flags(&config),
            camera,
            light,
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

/// The `cssm render` flags of what the window cannot change: the `.cssm`, exposure, shadow
/// resolution, visibility query.
fn fixed_flags(config: &ViewConfig) -> Vec<String> {
    let render = &config.render;
    let mut flags = Vec::new();
    if let Some(cssm) = &render.cssm {
        flags.push(format!("--cssm {}", cssm.display()));
    }
    // Always: the window's exposure is fixed, where `cssm render`'s default is automatic.
    if let Some(exposure) = render.exposure {
        flags.push(format!("--exposure {exposure}"));
    }
    if render.shadow_resolution != runtime::common::shadow_map::DEFAULT_RESOLUTION {
        flags.push(format!("--shadow-resolution {}", render.shadow_resolution));
    }
    if !render.visibility.both_ends {
        flags.push("--one-end".into());
    }
    flags
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
    /// Driven by `--screenshot` or `--script`: the image keeps its size and no frame waits
    /// for a vertical blank.
    scripted: bool,
    /// F12 also writes the radiance as OpenEXR.
    shot_exr: bool,
    /// The `cssm render` flags of the settings the window does not change.
    fixed_flags: Vec<String>,
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
    /// The fly keys held down (W A S D Q E), which move the camera every frame.
    held: HashSet<KeyCode>,
    /// GPU milliseconds per pass of the last rendered frame, their sum, and when the passes
    /// were last printed.
    timings: Vec<(&'static str, f64)>,
    frame_ms: f64,
    last_print: Instant,
    /// When the last frame started, and the CPU wall milliseconds between the last two.
    last_frame: Option<Instant>,
    cpu_ms: f64,
    /// The objects' animation: P plays and pauses it, a script's `animate SECONDS` steps it.
    pub(crate) playback: Playback,
}

/// The window's place in the scene's animation (`[objects.animation]`, or `cssm render
/// --animate`'s default spin): the time, whether it plays, and whether the renderer holds the
/// poses of that time.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Playback {
    /// How the objects move; `None` when the scene has no rigid object to move.
    pub(crate) motion: Option<crate::animate::Motion>,
    /// Seconds into the animation.
    pub(crate) time: f32,
    /// P toggled it on: the time advances by the frame time.
    pub(crate) playing: bool,
    /// The objects stand at their poses of `time` (false until the animation first plays or
    /// steps: the scene as loaded, the image `cssm render` writes).
    pub(crate) applied: bool,
    /// The poses must be set on the renderer before the next frame.
    moved: bool,
}

impl Playback {
    /// The playback of `scene`'s motion, paused at 0 s, nothing applied.
    fn of(scene: &Scene) -> Playback {
        Playback {
            motion: crate::animate::Motion::of(scene).ok(),
            time: 0.0,
            playing: false,
            applied: false,
            moved: false,
        }
    }

    /// Moves the animation `seconds` on (back, when negative); nothing without a motion.
    pub(crate) fn advance(&mut self, seconds: f32) {
        if self.motion.is_some() {
            self.time += seconds;
            self.applied = true;
            self.moved = true;
        }
    }

    /// The moving objects' poses now, as `cssm render --animate` places them at this time.
    fn poses(&self, scene: &Scene) -> Vec<(usize, glam::Affine3A)> {
        match (&self.motion, self.applied) {
            (Some(motion), true) => motion.poses_at(scene, self.time),
            _ => Vec::new(),
        }
    }

    /// What the overlay and the messages say about it.
    pub(crate) fn describe(&self) -> String {
        match (&self.motion, self.playing) {
            (None, _) => "animation: nothing to move (no [[objects]] entry)".into(),
            (Some(_), true) => format!("animation {:.2} s, playing (P pauses)", self.time),
            (Some(_), false) => format!("animation {:.2} s, paused (P plays)", self.time),
        }
    }
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
            scripted: false,
            shot_exr: false,
            fixed_flags: Vec::new(),
            rebuild: false,
            shot_requested: false,
            camera_moved: false,
            light_moved: false,
            cursor: None,
            left: false,
            right: false,
            modifiers: ModifiersState::empty(),
            held: HashSet::new(),
            timings: Vec::new(),
            frame_ms: 0.0,
            last_print: Instant::now(),
            last_frame: None,
            cpu_ms: 0.0,
            playback: Playback::of(&scene),
            scene,
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
        for (object, pose) in self.playback.poses(scene) {
            renderer.set_object_transform(object, pose).map_err(fail)?;
        }
        Ok(renderer)
    }

    /// P: plays or pauses the animation.
    fn toggle_playing(&mut self) {
        let playback = &mut self.playback;
        if playback.motion.is_none() {
            eprintln!("P: {} has no [[objects]] entry to move", self.scene.name);
            return;
        }
        playback.playing = !playback.playing;
        if playback.playing {
            // Playing from the start shows the animation's first pose at once.
            playback.advance(0.0);
        }
        eprintln!("{}", playback.describe());
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

    /// The flags after `cssm render SCENE` that render the image of `frames` accumulated
    /// frames as the window holds it now: every option of the method as the table resolves
    /// it, the size, and the camera and light as they are (their shortest exact decimals).
    fn render_flags(&self, frames: u32) -> String {
        let mut flags = self.fixed_flags.clone();
        flags.push(format!("--method {}", self.method.name));
        if let Ok(resolved) = self.method.resolve(&self.values) {
            flags.extend(resolved.iter().map(|(k, v)| format!("--set {k}={v}")));
        }
        flags.push(format!(
            "--component {} --size {}x{} --frames {frames}",
            self.settings.component.name(),
            self.settings.frame.width,
            self.settings.frame.height
        ));
        // `=`: a value starting with a minus sign is not taken for a flag.
        flags.push(format!(
            "--camera={}",
            Pose {
                position: self.camera.position,
                aim: self.camera.target,
            }
        ));
        if let Some(light) = &self.light {
            flags.push(format!(
                "--light={}",
                Pose {
                    position: light.position,
                    aim: light.direction,
                }
            ));
        }
        if self.playback.applied {
            flags.push(format!("--time={}", self.playback.time));
        }
        flags.join(" ")
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
            self.select_method(candidate);
            return;
        }
    }

    /// Switches to `method` (Tab, the overlay's menu), from its defaults.
    fn select_method(&mut self, method: &'static MethodEntry) {
        if !method.on_gpu() || (method.needs_cssm && self.cssm.is_none()) {
            eprintln!("cannot switch to {method}: it runs on the CPU or needs a .cssm");
            return;
        }
        self.method = method;
        // Each method starts from its defaults; the window accumulates, so the methods that
        // jitter do (as `cssm render --frames N`).
        self.values = OptionValues::default();
        if method.option("jitter").is_some() {
            self.values.set("jitter", OptionValue::Switch(true));
        }
        self.rebuild = true;
    }

    /// The next component (C, the overlay's menu).
    fn set_component(&mut self, component: Component) {
        if component != self.settings.component {
            self.settings.component = component;
            self.rebuild = true;
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

    /// Applies what one of the overlay's controls asked for.
    fn apply(&mut self, action: overlay::Action) {
        match action {
            overlay::Action::Method(method) => self.select_method(method),
            overlay::Action::Component(component) => self.set_component(component),
            overlay::Action::Bounces(n) => {
                self.set_option("bounces", |_| Some(OptionValue::Count(n)))
            }
            overlay::Action::ScaleThreshold(f) => self.set_option("threshold", |v| match v {
                OptionValue::Number(x) => Some(OptionValue::Number(x * f)),
                _ => None,
            }),
        }
    }

    /// Moves the camera for the fly keys held, `seconds` after the last frame.
    fn fly_held(&mut self, seconds: f32) {
        let (mut forward, mut right, mut up) = (0.0, 0.0, 0.0);
        for code in &self.held {
            if let Some((f, r, u)) = fly_direction(*code) {
                forward += f;
                right += r;
                up += u;
            }
        }
        if (forward, right, up) == (0.0, 0.0, 0.0) {
            return;
        }
        // `fly`'s step is 2% of the scene's diagonal; FLY_SPEED diagonals a second.
        let steps = FLY_SPEED / 0.02 * seconds;
        self.camera = controls::fly(
            &self.camera,
            forward * steps,
            right * steps,
            up * steps,
            &self.scene,
        );
        self.camera_moved = true;
    }
}

/// The fly direction of a fly key (by its place on the keyboard: WASD on any layout):
/// forward, right, up.
fn fly_direction(code: KeyCode) -> Option<(f32, f32, f32)> {
    match code {
        KeyCode::KeyW => Some((1.0, 0.0, 0.0)),
        KeyCode::KeyS => Some((-1.0, 0.0, 0.0)),
        KeyCode::KeyD => Some((0.0, 1.0, 0.0)),
        KeyCode::KeyA => Some((0.0, -1.0, 0.0)),
        KeyCode::KeyE => Some((0.0, 0.0, 1.0)),
        KeyCode::KeyQ => Some((0.0, 0.0, -1.0)),
        _ => None,
    }
}

/// One input, from the window system or a script step: what the controls act on.
#[derive(Clone, Debug, PartialEq)]
enum Input {
    Modifiers(ModifiersState),
    Button { button: MouseButton, down: bool },
    Cursor(PhysicalPosition<f64>),
    Wheel(f32),
    Key(KeyPress),
}

/// A key going down or up (winit's `KeyEvent`, which only winit can make, reduced to what the
/// controls read).
#[derive(Clone, Debug, PartialEq)]
struct KeyPress {
    physical: PhysicalKey,
    logical: Key,
    down: bool,
    repeat: bool,
}

/// A `--script` being run.
struct ScriptRun {
    path: PathBuf,
    steps: VecDeque<script::Line>,
    /// Frames still to render before the next step (`wait`, `hold`).
    waiting: u32,
    /// The key a `hold` holds, released when its frames are done.
    held: Option<KeyPress>,
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
    overlay: overlay::Overlay,
    /// The device has timestamp queries (the overlay says so where not).
    timestamps: bool,
    /// The adapter, described.
    gpu_name: String,
    /// The next F12 screenshot's number.
    shots: u32,
}

struct App {
    state: Option<Gfx>,
    outcome: Option<CliResult>,
    view: ViewState,
    script: Option<ScriptRun>,
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
            present_mode: if self.view.scripted {
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
        let overlay = overlay::Overlay::new(&window, &gpu.device, format);
        eprintln!(
            "viewing {} on {} (Esc quits, H hides the overlay; `cssm view --help` lists the \
             keys)",
            self.view.describe(),
            gpu.describe()
        );
        Ok(Gfx {
            window,
            surface,
            config,
            timestamps: gpu
                .device
                .features()
                .contains(wgpu::Features::TIMESTAMP_QUERY),
            gpu_name: gpu.describe(),
            gpu,
            renderer,
            image,
            blit,
            overlay,
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
        let Some(gfx) = &mut self.state else {
            return;
        };
        // The overlay sees every event first; a click or drag on it is its own. A release
        // still reaches the controls (a drag that ends over the overlay ends), and so do the
        // keys, unless the overlay has a text field in focus (egui takes Tab for itself).
        let taken = gfx.overlay.on_event(&gfx.window, &event);
        let keys_taken = gfx.overlay.wants_keyboard();
        let input = match event {
            WindowEvent::CloseRequested => {
                self.finish(event_loop, Ok(ExitCode::SUCCESS));
                None
            }
            WindowEvent::Resized(size) => {
                self.resize(size);
                None
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.finish(event_loop, Err(e));
                }
                None
            }
            // A key released while another window had the focus never comes: nothing flies on.
            WindowEvent::Focused(false) => {
                self.view.held.clear();
                None
            }
            WindowEvent::ModifiersChanged(m) => Some(Input::Modifiers(m.state())),
            WindowEvent::KeyboardInput { event, .. } if !keys_taken => Some(Input::Key(KeyPress {
                physical: event.physical_key,
                logical: event.logical_key.clone(),
                down: event.state == ElementState::Pressed,
                repeat: event.repeat,
            })),
            WindowEvent::MouseInput { state, button, .. }
                if !taken || state == ElementState::Released =>
            {
                Some(Input::Button {
                    button,
                    down: state == ElementState::Pressed,
                })
            }
            // The cursor's place is always followed, so that a drag starting off the overlay
            // does not jump; the motion turns nothing while egui drags one of its own.
            WindowEvent::CursorMoved { position, .. } => {
                if taken {
                    self.view.cursor = Some(position);
                    None
                } else {
                    Some(Input::Cursor(position))
                }
            }
            WindowEvent::MouseWheel { delta, .. } if !taken => Some(Input::Wheel(match delta {
                MouseScrollDelta::LineDelta(_, y) => y,
                MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
            })),
            _ => None,
        };
        if let Some(input) = input {
            self.input(event_loop, input);
        }
        self.request_frame();
    }
}

impl App {
    /// Asks for the next frame while there is anything to draw: a change, accumulation not
    /// yet done, a script step, a key held, the overlay's own.
    fn request_frame(&self) {
        let Some(gfx) = &self.state else { return };
        let view = &self.view;
        if self.script.is_some()
            || gfx.overlay.wants_frame
            || !view.held.is_empty()
            || self.scene_frame_needed()
        {
            gfx.window.request_redraw();
        }
    }

    /// Whether the next frame renders the scene: something changed, or accumulation is not
    /// done. A frame for the overlay alone, or a screenshot, shows the last image again.
    fn scene_frame_needed(&self) -> bool {
        let Some(gfx) = &self.state else {
            return false;
        };
        let view = &self.view;
        // A script's screenshot may ask for more frames than a window accumulates; a script
        // renders every frame, as `cssm render --frames N` does.
        let frames = match view.screenshot {
            Some(_) => view.frames,
            None => ACCUMULATE_FRAMES,
        };
        self.script.is_some()
            || view.rebuild
            || view.camera_moved
            || view.light_moved
            || view.playback.moved
            || view.playback.playing
            || !view.held.is_empty()
            || gfx.renderer.frames_accumulated() < frames
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
        if self.view.scripted {
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

    /// Handles one input, from the window system or a script.
    fn input(&mut self, event_loop: &ActiveEventLoop, input: Input) {
        let view = &mut self.view;
        match input {
            Input::Modifiers(m) => view.modifiers = m,
            Input::Button { button, down } => match button {
                MouseButton::Left => view.left = down,
                MouseButton::Right => view.right = down,
                _ => {}
            },
            Input::Wheel(lines) => {
                view.camera = controls::dolly(&view.camera, lines, &view.scene);
                view.camera_moved = true;
            }
            Input::Cursor(position) => self.mouse_moved(position),
            Input::Key(key) => self.key(event_loop, &key),
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

    fn key(&mut self, event_loop: &ActiveEventLoop, event: &KeyPress) {
        let view = &mut self.view;
        // The fly keys by their place on the keyboard (WASD on any layout): a press moves one
        // step, and while held the camera flies on every frame, scaled by the frame time (key
        // repeat, which comes at the keyboard's rate, is ignored).
        if let PhysicalKey::Code(code) = event.physical
            && let Some((forward, right, up)) = fly_direction(code)
        {
            if !event.down {
                view.held.remove(&code);
            } else if !event.repeat {
                view.held.insert(code);
                view.camera = controls::fly(&view.camera, forward, right, up, &view.scene);
                view.camera_moved = true;
            }
            return;
        }
        if !event.down {
            return;
        }
        let shift = view.modifiers.shift_key();
        match &event.logical {
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
                    view.set_component(all[(here + 1) % all.len()]);
                }
                "p" | "P" if !event.repeat => view.toggle_playing(),
                "h" | "H" if !event.repeat => {
                    if let Some(gfx) = &mut self.state {
                        gfx.overlay.visible = !gfx.overlay.visible;
                        gfx.overlay.wants_frame = true;
                    }
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

    /// Lays out the overlay and applies its controls, applies what changed, renders a frame
    /// into the image when anything changed or accumulation goes on, copies the image onto
    /// the surface with the overlay over it, writes the screenshots due, and runs the next
    /// script step.
    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
        let now = Instant::now();
        let since_last = self
            .view
            .last_frame
            .replace(now)
            .map(|t| now.duration_since(t));
        if let Some(elapsed) = since_last {
            self.view.cpu_ms = elapsed.as_secs_f64() * 1e3;
            // A long pause (a window at rest) is no flight time: at most a tenth of a second.
            let seconds = elapsed.min(Duration::from_millis(100)).as_secs_f32();
            self.view.fly_held(seconds);
            // The animation plays at the frame time, as slowly as the renderer draws.
            if self.view.playback.playing {
                self.view.playback.advance(seconds);
            }
        }
        let render_scene = self.scene_frame_needed();
        let view = &mut self.view;
        let Some(gfx) = &mut self.state else {
            return Ok(());
        };
        let actions = gfx.overlay.run(
            &gfx.window,
            view,
            &overlay::Stats {
                timings: &view.timings,
                timestamps: gfx.timestamps,
                frame_ms: view.cpu_ms,
                accumulated: gfx.renderer.frames_accumulated(),
                gpu: &gfx.gpu_name,
            },
        );
        for action in actions {
            view.apply(action);
        }
        let render_scene = render_scene || view.rebuild;
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
        if std::mem::take(&mut view.playback.moved) {
            for (object, pose) in view.playback.poses(&view.scene) {
                gfx.renderer
                    .set_object_transform(object, pose)
                    .map_err(fail)?;
            }
        }
        if std::mem::take(&mut view.light_moved)
            && let Some(light) = &view.light
            && let Err(e) = gfx.renderer.set_light(0, light)
        {
            // A light the shadow maps cannot hold (aimed away from the scene): keep the last.
            eprintln!("{e}");
        }
        let device = gfx.gpu.device.clone();
        let mut encoder = device.create_command_encoder(&Default::default());
        if render_scene {
            let image_view = gfx.image.create_view(&Default::default());
            gfx.renderer.render(&mut encoder, &image_view);
        }
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
            // Over the surface only: the image (what screenshots read) never holds it.
            gfx.overlay.draw(
                &device,
                &gfx.gpu.queue,
                &mut encoder,
                &target,
                [gfx.config.width, gfx.config.height],
            );
        }
        gfx.gpu.queue.submit([encoder.finish()]);
        if let Some(texture) = surface_texture {
            gfx.window.pre_present_notify();
            gfx.gpu.queue.present(texture);
        }
        // Timings read back as `cssm render` reads them, every frame (this waits for the GPU,
        // which also keeps the window from queueing frames ahead of the input).
        if render_scene {
            view.timings = gfx.renderer.read_timings().map_err(fail)?;
            view.frame_ms = view.timings.iter().map(|(_, ms)| ms).sum();
        }
        gfx.gpu.wait().map_err(fail)?;
        let accumulated = gfx.renderer.frames_accumulated();
        gfx.window.set_title(&format!(
            "cssm view - {} - {:.2} ms - {accumulated} frames",
            view.describe(),
            view.frame_ms
        ));
        if render_scene
            && view.last_print.elapsed() >= Duration::from_secs(1)
            && !view.timings.is_empty()
        {
            view.last_print = Instant::now();
            let passes: Vec<String> = view
                .timings
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
            && let Err(e) = self.f12()
        {
            // A failed F12 (a full disk) is no reason to close the window.
            eprintln!("{e}");
        }
        if let Some(path) = self.view.screenshot.clone()
            && accumulated >= self.view.frames
        {
            self.screenshot(&path)?;
            self.finish(event_loop, Ok(ExitCode::SUCCESS));
            return Ok(());
        }
        self.script_step(event_loop)
    }

    /// At a frame's end: the next step of the `--script`, unless a `wait` still runs. Each
    /// step becomes the inputs a person's hand would make, handled as the window's own.
    fn script_step(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
        let Some(script) = &mut self.script else {
            return Ok(());
        };
        if script.waiting > 0 {
            script.waiting -= 1;
            if script.waiting > 0 {
                return Ok(());
            }
        }
        // A `hold` ends with its key's release, at this frame boundary; the next step at the
        // next one.
        if let Some(key) = script.held.take() {
            self.input(event_loop, Input::Key(key));
            return Ok(());
        }
        let Some(line) = script.steps.pop_front() else {
            // The end of the file: the window is the user's from here.
            eprintln!("{}: done; the window stays open", script.path.display());
            self.script = None;
            return Ok(());
        };
        let at = format!("{}:{}", script.path.display(), line.number);
        let modifiers = self.view.modifiers;
        let with_shift = |shift: bool| {
            Input::Modifiers(if shift {
                ModifiersState::SHIFT
            } else {
                ModifiersState::empty()
            })
        };
        let inputs = match line.step {
            script::Step::Drag {
                button,
                shift,
                dx,
                dy,
            } => {
                // From where the cursor is (the middle of the window before it ever moved).
                let from = self.view.cursor.unwrap_or(PhysicalPosition::new(
                    self.view.settings.frame.width as f64 / 2.0,
                    self.view.settings.frame.height as f64 / 2.0,
                ));
                vec![
                    with_shift(shift),
                    Input::Cursor(from),
                    Input::Button { button, down: true },
                    Input::Cursor(PhysicalPosition::new(from.x + dx, from.y + dy)),
                    Input::Button {
                        button,
                        down: false,
                    },
                    Input::Modifiers(modifiers),
                ]
            }
            script::Step::Dolly(lines) => vec![Input::Wheel(lines)],
            script::Step::Key(key) => {
                let press = |down| {
                    Input::Key(KeyPress {
                        physical: key.physical,
                        logical: key.logical.clone(),
                        down,
                        repeat: false,
                    })
                };
                vec![
                    with_shift(key.shift),
                    press(true),
                    press(false),
                    Input::Modifiers(modifiers),
                ]
            }
            script::Step::Hold(key, frames) => {
                let press = KeyPress {
                    physical: key.physical,
                    logical: key.logical.clone(),
                    down: true,
                    repeat: false,
                };
                script.held = Some(KeyPress {
                    down: false,
                    ..press.clone()
                });
                script.waiting = frames;
                vec![
                    with_shift(key.shift),
                    Input::Key(press),
                    Input::Modifiers(modifiers),
                ]
            }
            script::Step::Wait(n) => {
                script.waiting = n;
                Vec::new()
            }
            script::Step::Animate(seconds) => {
                self.view.playback.advance(seconds);
                Vec::new()
            }
            script::Step::Screenshot(path) => {
                self.screenshot(&path).map_err(|e| format!("{at}: {e}"))?;
                Vec::new()
            }
            script::Step::Quit => {
                self.finish(event_loop, Ok(ExitCode::SUCCESS));
                Vec::new()
            }
        };
        for input in inputs {
            self.input(event_loop, input);
        }
        Ok(())
    }

    /// F12: the first free `cssm-view-NNNN.png` in the current directory (and `.exr` with
    /// `--shot-exr`).
    fn f12(&mut self) -> Result<(), String> {
        let Some(gfx) = &mut self.state else {
            return Ok(());
        };
        let (png, exr) = loop {
            let stem = format!("cssm-view-{:04}", gfx.shots);
            gfx.shots += 1;
            let (png, exr) = (
                PathBuf::from(format!("{stem}.png")),
                PathBuf::from(format!("{stem}.exr")),
            );
            if !png.exists() && !exr.exists() {
                break (png, exr);
            }
        };
        self.screenshot(&png)?;
        if self.view.shot_exr {
            self.screenshot(&exr)?;
        }
        Ok(())
    }

    /// Writes the last frame's image to `path`: the tone-mapped PNG, or with the extension
    /// `.exr` the linear radiance as `cssm render --exr` writes it; then prints the flags with
    /// which `cssm render` writes the same file.
    fn screenshot(&mut self, path: &Path) -> Result<(), String> {
        let Some(gfx) = &mut self.state else {
            return Ok(());
        };
        let (w, h) = (gfx.image.width(), gfx.image.height());
        let fail = |e: runtime::RuntimeError| format!("{}: {e}", path.display());
        let exr = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        if exr {
            let bytes = readback::read_texture(
                &gfx.gpu.device,
                &gfx.gpu.queue,
                gfx.renderer.radiance(),
                16,
            )
            .map_err(fail)?;
            let radiance: Vec<[f32; 4]> = readback::vec4s(&bytes)
                .iter()
                .map(|v| v.to_array())
                .collect();
            save_radiance_exr(path, w, h, &radiance)?;
        } else {
            let rgba = readback::read_texture(&gfx.gpu.device, &gfx.gpu.queue, &gfx.image, 4)
                .map_err(fail)?;
            save_rgba_png(path, w, h, rgba)?;
        }
        let frames = gfx.renderer.frames_accumulated();
        eprintln!(
            "wrote {} ({}, {frames} frames)",
            path.display(),
            self.view.describe(),
        );
        eprintln!(
            "render flags for {}: {} --{} {}",
            path.display(),
            self.view.render_flags(frames),
            if exr { "exr" } else { "out" },
            path.display()
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
    fn the_overlays_actions_change_what_the_keys_change() {
        let mut view = cornell("direct");
        let rsm = runtime::method::find("rsm").unwrap();
        view.apply(overlay::Action::Method(rsm));
        assert_eq!(view.method.name, "rsm");
        assert!(std::mem::take(&mut view.rebuild));
        // A method needing a .cssm is refused without one, as Tab skips it.
        view.apply(overlay::Action::Method(
            runtime::method::find("lightmap").unwrap(),
        ));
        assert_eq!(view.method.name, "rsm");
        assert!(!view.rebuild);
        view.apply(overlay::Action::Component(Component::Indirect));
        assert_eq!(view.settings.component, Component::Indirect);
        assert!(std::mem::take(&mut view.rebuild));
        let mut vct = cornell("vct");
        vct.apply(overlay::Action::Bounces(2));
        assert_eq!(vct.values.get("bounces"), Some(OptionValue::Count(2)));
        // Out of the table's range: refused, as `]` past the maximum.
        vct.rebuild = false;
        vct.apply(overlay::Action::Bounces(runtime::method::MAX_BOUNCES + 1));
        assert_eq!(vct.values.get("bounces"), Some(OptionValue::Count(2)));
        assert!(!vct.rebuild);
    }

    #[test]
    fn held_fly_keys_move_by_the_frame_time() {
        let mut view = cornell("direct");
        let start = view.camera.clone();
        view.fly_held(0.1);
        assert_eq!(view.camera, start, "nothing held, nothing moves");
        assert!(!view.camera_moved);
        view.held.insert(KeyCode::KeyW);
        view.fly_held(0.1);
        let (lo, hi) = view.scene.bounds();
        let moved = (view.camera.position - start.position).length();
        let expected = FLY_SPEED * 0.1 * (hi - lo).length();
        assert!(
            (moved - expected).abs() < expected * 1e-3,
            "{moved} vs {expected}"
        );
        // Forward: towards the target, which moves along.
        let forward = (start.target - start.position).normalize();
        assert!(
            (view.camera.position - start.position)
                .normalize()
                .dot(forward)
                > 0.999
        );
        assert_eq!(
            view.camera.target - view.camera.position,
            start.target - start.position
        );
        assert!(view.camera_moved);
        // W and S together cancel.
        view.held.insert(KeyCode::KeyS);
        let here = view.camera.clone();
        view.fly_held(0.1);
        assert_eq!(view.camera, here);
    }

    #[test]
    fn render_flags_hold_every_option_the_camera_and_the_light() {
        let mut view = cornell("vct");
        view.camera = controls::orbit(&view.camera, 37.0, -11.0);
        let flags = view.render_flags(5);
        assert!(flags.starts_with("--method vct --set "), "{flags}");
        for (name, value) in view.method.resolve(&view.values).unwrap().iter() {
            assert!(flags.contains(&format!("--set {name}={value}")), "{flags}");
        }
        assert!(flags.contains("--frames 5"), "{flags}");
        let camera = flags
            .split_whitespace()
            .find_map(|f| f.strip_prefix("--camera="))
            .unwrap();
        let numbers: Vec<f32> = camera.split(',').map(|v| v.parse().unwrap()).collect();
        // The exact floats, not a rounding of them.
        assert_eq!(numbers[..3], view.camera.position.to_array());
        assert_eq!(numbers[3..], view.camera.target.to_array());
        assert!(flags.contains("--light="), "{flags}");
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
