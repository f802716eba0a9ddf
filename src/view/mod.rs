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
mod draw;
mod input;
mod overlay;
mod screenshot;
mod script;
mod state;

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
    render::{posed, render_cssm, renderer_settings},
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

/// The copy of the image onto the surface (`blit.wgsl`).
struct Blit {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    bind_group: wgpu::BindGroup,
}

impl App {
    /// Ends the event loop with `outcome` (the first one given wins).
    fn finish(&mut self, event_loop: &ActiveEventLoop, outcome: CliResult) {
        self.outcome.get_or_insert(outcome);
        event_loop.exit();
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
