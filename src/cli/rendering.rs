//! `cssm render` and `cssm view`: the flags they share, the render configuration they make
//! ([`RenderConfig`]), `--animate`'s options, and the method options the flags set.

use super::*;

/// `cssm render --help`'s text after the options: the method table, then examples.
pub(super) fn render_after_help() -> String {
    format!(
        "Methods and their options (--set NAME=VALUE; --bounces, --threshold and --samples are \
         short for those options):\n{}\n\
         Every method marked [needs .cssm] takes the scene's .cssm: --cssm FILE, else one is \
         baked first (atlas 64, cube 32; a few seconds for the Cornell box).\n\n\
         Examples:\n  cssm render --out cornell.png\n  \
         cssm bake -o cornell-box.cssm && cssm render --cssm cornell-box.cssm --method lightcuts --bounces 2 --out gi.png\n  \
         cssm render scenes/cornell-glossy --method lightcuts --frames 16 --out glossy.png\n  \
         cssm render --method lightmap --component indirect --exr indirect.exr\n  \
         cssm render --method reference --bounces 3 --samples 1024 --exr truth.exr\n  \
         cssm render --method rsm --component indirect --set visibility=none --out rsm-no-visibility.png\n  \
         cssm render scenes/cornell-glossy --method vct --set resolution=64 --out vct.png\n  \
         cssm render --method ssil --frames 16 --set visibility=none --out ssil.png\n  \
         cssm render scenes/cornell-glossy --method direct --out glossy.png --exr glossy.exr --size 1280x720 --timings\n  \
         cssm render --camera=400,300,-700,278,273,0 --light=278,540,279.5,0.2,-1,0 --out moved.png   # cssm view prints these\n  \
         cssm render scenes/my-scene --cssm my-scene.cssm --method lightcuts --animate --frames 48 --out frames/   # frames/frame-0000.png ... and frames/animation.gif",
        runtime::method::describe_methods()
    )
}

/// `cssm view --help`'s text after the options: the keys, then examples.
pub(super) fn view_after_help() -> String {
    "Mouse and keys:\n  \
     left drag            orbit about the point the camera looks at\n  \
     wheel                dolly towards it and away\n  \
     W A S D / Q E        fly forward, left, back, right / down, up (a press steps; held, the \
     camera flies on every frame)\n  \
     right drag           aim the first spot light\n  \
     shift + right drag   move the first spot light (in the view plane)\n  \
     Tab / shift + Tab    next / previous method of the table (`cssm render --help` lists them; \
     those needing a .cssm are skipped when none is loaded)\n  \
     C                    cycle the component: direct, indirect, full\n  \
     P                    play / pause the objects' animation ([objects.animation], else each \
     rigid object turning about the vertical, as `cssm render --animate`), at the frame time\n  \
     [ / ]                one bounce fewer / more (methods with a `bounces` option)\n  \
     - / =                halve / double the oracle threshold (methods with `threshold`)\n  \
     F12                  write a screenshot, cssm-view-NNNN.png in the current directory \
     (and .exr with --shot-exr), and print the `cssm render` flags of the same image\n  \
     H                    show / hide the overlay: settings, camera, light, GPU time per pass, \
     frame time; menus for method, component and bounces (never in a screenshot)\n  \
     Esc                  quit\n\n\
     Script (--script FILE): one step a line, one step per frame, # starts a comment; each \
     step goes through the window's own mouse and key handling (DX, DY are pixels of mouse \
     motion).\n  \
     orbit DX DY          left drag by DX, DY pixels\n  \
     drag-light DX DY     right drag (aim the light)\n  \
     move-light DX DY     shift + right drag (move the light)\n  \
     dolly LINES          turn the wheel LINES lines (negative: away)\n  \
     key KEY              press and release KEY: a character (c, [, ], -, =, h, w, ...), or \
     Tab, F12, Escape; shift+KEY holds shift\n  \
     hold KEY N           press KEY, let N frames render, release it (W A S D Q E fly)\n  \
     wait N               let N frames render before the next step (they accumulate)\n  \
     animate SECONDS      move the objects' animation SECONDS on (exactly; P plays it at the \
     frame time)\n  \
     screenshot PATH      write the last frame: PNG, or with .exr the linear radiance; print \
     the `cssm render` flags of the same image\n  \
     quit                 close the window (at the end of the file it stays open)\n\n\
     Examples:\n  cssm view\n  \
     cssm bake -o cornell-box.cssm && cssm view --cssm cornell-box.cssm --method lightcuts\n  \
     cssm view scenes/cornell-glossy --method vct --size 800x600\n  \
     xvfb-run -a cssm view --method direct --size 64x48 --screenshot shot.png --frames 1\n  \
     printf 'orbit 40 0\\nkey Tab\\nwait 2\\nscreenshot a.png\\nquit\\n' > s.txt && xvfb-run -a cssm view --size 64x48 --script s.txt"
        .to_string()
}

/// The flags `cssm render` and `cssm view` share: what the image shows and from where, spelled
/// and documented once.
#[derive(clap::Args)]
pub struct ImageFlags {
    /// Image size WIDTHxHEIGHT (`cssm view`: the window's too). Default: the scene camera's
    /// resolution.
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Shadow-map resolution in texels per side.
    #[arg(long, default_value_t = runtime::common::shadow_map::DEFAULT_RESOLUTION)]
    shadow_resolution: u32,
    /// CSSM methods: ask only the receiver's cube maps for each sender, as the paper does,
    /// instead of both ends' answers combined (the default; see `cssm check --one-end`).
    #[arg(long)]
    one_end: bool,
    /// Indirect bounces (the option `bounces`; lightcuts: the final gather is the last).
    /// Default: the method's.
    #[arg(long)]
    bounces: Option<u32>,
    /// Oracle threshold (the option `threshold`, §4.3): a sender is refined while the
    /// tone-mapped upper bound of what it sends is above this; smaller is slower and closer.
    #[arg(long, allow_negative_numbers = true, value_parser = finite_f32)]
    threshold: Option<f32>,
    /// Set a method option, NAME=VALUE (`cssm render --help` lists them); repeatable.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    set: Vec<String>,
    /// Which light the image holds: direct, indirect or full (C switches in `cssm view`'s
    /// window).
    #[arg(long, default_value = "full")]
    component: Component,
    /// The camera's eye and target, EX,EY,EZ,TX,TY,TZ, instead of the scene's (its up and
    /// field of view stay); `cssm view` prints the camera it ends with in this form.
    #[arg(long, value_name = "EYE,TARGET", allow_hyphen_values = true, value_parser = parse_pose)]
    camera: Option<Pose>,
    /// The first spot light's position and direction, PX,PY,PZ,DX,DY,DZ, instead of the
    /// scene's (its cone and intensity stay); `cssm view` prints the light it ends with.
    #[arg(long, value_name = "POSITION,DIRECTION", allow_hyphen_values = true, value_parser = parse_pose)]
    light: Option<Pose>,
}

#[derive(clap::Args)]
pub struct ViewArgs {
    /// Scene directory or mesh file (.obj, .gltf, .glb). Default: the built-in Cornell box.
    scene: Option<PathBuf>,
    /// Method to start with (`cssm render --help` lists them; Tab switches in the window).
    /// The default, lightmap, is `cssm render`'s.
    #[arg(long, default_value = "lightmap", value_parser = parse_method)]
    method: &'static MethodEntry,
    #[command(flatten)]
    image: ImageFlags,
    /// The scene's baked CSSM (`cssm bake`), for the methods that need one. Default: bake one
    /// in memory at atlas 64 (or the smallest larger page that holds the charts), cube 32 when
    /// the first method needs it; without one, Tab skips the methods that need it.
    #[arg(long)]
    cssm: Option<PathBuf>,
    /// Exposure in stops (radiance is scaled by 2^EV before tone mapping). Fixed in the window
    /// (`cssm render` meters its own when not given one; a screenshot prints the flag).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = stops)]
    exposure: f32,
    /// For scripts: render --frames frames in the window, write this image and exit: a PNG
    /// (what F12 writes: byte for byte what `cssm render --out` writes for the same options),
    /// or with the extension .exr the linear radiance (what `cssm render --exr` writes).
    #[arg(long, value_name = "PATH")]
    screenshot: Option<PathBuf>,
    /// Frames to render before the --screenshot, 1 to 4096 (as `cssm render --frames`).
    #[arg(long, default_value_t = 1, requires = "screenshot")]
    frames: u32,
    /// Feed the window the input steps of this file, one per frame (the format is below);
    /// its screenshots print the `cssm render` flags of the same image.
    #[arg(long, value_name = "FILE", conflicts_with = "screenshot")]
    script: Option<PathBuf>,
    /// F12 also writes the linear radiance, cssm-view-NNNN.exr (what `cssm render --exr`
    /// writes).
    #[arg(long)]
    shot_exr: bool,
}

/// `cssm view`, checked: the render configuration `cssm render` would use (its `out` is the
/// screenshot), and whether the window closes after the screenshot.
pub struct ViewConfig {
    /// What the window renders, as `cssm render` would.
    pub render: RenderConfig,
    /// `--screenshot`: write the image after `render.frames` frames and exit.
    pub screenshot: Option<PathBuf>,
    /// `--script`: input steps to feed the window.
    pub script: Option<PathBuf>,
    /// `--shot-exr`: F12 also writes the radiance as OpenEXR.
    pub shot_exr: bool,
}

impl ViewArgs {
    /// The render configuration of the first method, checked as `cssm render` checks it.
    pub fn config(self) -> Result<ViewConfig, String> {
        if !(1..=MAX_FRAMES).contains(&self.frames) {
            return Err(format!(
                "--frames {} is out of range 1..={MAX_FRAMES}",
                self.frames
            ));
        }
        // An interactive window accumulates without end: the methods that jitter do (as
        // `cssm render --frames N` with N > 1); a screenshot takes exactly `cssm render`'s
        // options for its frame count.
        let jitter_frames = if self.screenshot.is_some() {
            self.frames
        } else {
            MAX_FRAMES
        };
        let values = option_values(
            self.method,
            [
                ("bounces", self.image.bounces.map(OptionValue::Count)),
                ("threshold", self.image.threshold.map(OptionValue::Number)),
                ("samples", None),
            ],
            jitter_frames,
            &self.image.set,
        )?;
        let resolved = self.method.resolve(&values).map_err(|e| e.to_string())?;
        if !self.method.on_gpu() {
            return Err(format!(
                "method '{}' runs on the CPU, not in the window; `cssm render --method {}` \
                 runs it",
                self.method, self.method
            ));
        }
        Ok(ViewConfig {
            render: RenderConfig {
                scene: self.scene,
                method: self.method,
                values,
                resolved,
                out: self
                    .screenshot
                    .clone()
                    .unwrap_or_else(|| PathBuf::from("cssm-view.png")),
                exr: None,
                size: self.image.size,
                exposure: Some(self.exposure),
                shadow_resolution: self.image.shadow_resolution,
                visibility: QueryOptions {
                    both_ends: !self.image.one_end,
                    ..QueryOptions::default()
                },
                timings: false,
                stats: false,
                cssm: self.cssm,
                frames: self.frames,
                component: self.image.component,
                camera: self.image.camera,
                light: self.image.light,
                animate: None,
                time: None,
            },
            screenshot: self.screenshot,
            script: self.script,
            shot_exr: self.shot_exr,
        })
    }
}

#[derive(clap::Args)]
pub struct RenderArgs {
    /// Scene directory or mesh file (.obj, .gltf, .glb). Default: the built-in Cornell box.
    scene: Option<PathBuf>,
    /// Rendering method (see the list below). The default, lightmap, is the hierarchical
    /// radiosity's converged solution looked up per pixel (a .cssm baked first when none is
    /// given); direct is instant but holds the lights' direct light only.
    #[arg(long, default_value = "lightmap", value_parser = parse_method)]
    method: &'static MethodEntry,
    #[command(flatten)]
    image: ImageFlags,
    /// Output PNG (tone-mapped sRGB), default render.png. With --animate: the directory the
    /// frames go into (created if missing; required).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Also write linear radiance to this OpenEXR file.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Exposure in stops (radiance is scaled by 2^EV before tone mapping). Default: automatic,
    /// the log-average luminance of the image's lit pixels at middle grey (with --animate, the
    /// first frame's for every frame), printed so that --exposure can fix it; the CSSM methods'
    /// oracle meters at 0 then.
    #[arg(long, allow_negative_numbers = true, value_parser = stops)]
    exposure: Option<f32>,
    /// Print GPU milliseconds per pass (timestamp queries): the first frame, which also runs
    /// the view-independent passes, and the last (one more frame is rendered to time it warm).
    #[arg(long)]
    timings: bool,
    /// Print what the passes do, counted by their CPU twins on a sample of their receivers (the
    /// radiosity gather of hrc, lightmap and lightcuts, lightcuts' far field (with gather=atlas)
    /// and final gather): nodes visited
    /// and queried per receiver, CSSM taps, search steps and bytes, the threads against the
    /// device's, their warps replayed (lane efficiency, 32-byte sectors per load), and the GPU
    /// milliseconds a cost model of the NVIDIA H200 predicts from them (reports/runtime.md).
    #[arg(long)]
    stats: bool,
    /// The scene's baked CSSM (`cssm bake`), for the methods that need one. Default: bake one
    /// in memory at atlas 64 (or the smallest larger page that holds the scene's charts),
    /// cube 32.
    #[arg(long)]
    cssm: Option<PathBuf>,
    /// Paths per pixel of `--method reference` (the option `samples`).
    #[arg(long)]
    samples: Option<u32>,
    /// Frames to render and average, 1 to 4096, default 1 (lightcuts: every frame jitters
    /// its senders over their nodes' surfaces, §4.5, so the average converges for glossy
    /// scenes; ssil: every frame draws new samples and its temporal filter blends them into the
    /// history). With --animate: the number of animation frames, 1 to 4096 (default: --fps
    /// times the duration).
    #[arg(long)]
    frames: Option<u32>,
    /// Render the scene's animation (scene.toml's [objects.animation], docs/scene-format.md)
    /// into the directory --out: frame-0000.png, frame-0001.png, ... and animation.gif, with one
    /// renderer that moves the objects between frames (set_object_transform; nothing is
    /// reloaded). Frame i shows the time i x duration / frames, so a looping animation's last
    /// frame leads back into its first; each frame is rendered once (no averaging). Where
    /// some objects have an animation, the others stand still; a scene whose objects have none
    /// gets each rigid [[objects]] entry spun one full turn about the vertical axis (the
    /// camera's up) through the centre of its bounding box, over --duration (default 4 s).
    /// The objects' shadows, visibility and atlas texels follow them, so the light they
    /// receive and send moves with them. Existing frames are not overwritten
    /// without --overwrite; every file is written under a temporary name and renamed, so none
    /// is ever half-written.
    #[arg(long)]
    animate: bool,
    /// --animate: frames per second, default 24 (sets the frame count from the duration, or,
    /// with --frames, the duration from the frame count; the GIF plays at this rate).
    #[arg(long, requires = "animate", value_parser = positive_f32)]
    fps: Option<f32>,
    /// --animate: seconds of animation to render from time 0. Default: the scene's animation's
    /// duration (its longest object's: the last keyframe's time, twice that for ping-pong, or
    /// one full spin), 4 s for the default spin. At most two of --frames, --fps and --duration.
    #[arg(long, requires = "animate", value_parser = positive_f32)]
    duration: Option<f32>,
    /// --animate: replace the frames and animation.gif already in --out.
    #[arg(long, requires = "animate")]
    overwrite: bool,
    /// --animate: write the PNG frames only, no animation.gif.
    #[arg(long, requires = "animate")]
    no_gif: bool,
    /// Place the moving objects where the animation has them after SECONDS (the scene's
    /// [objects.animation], else the default spin of --animate) and render that one image;
    /// `cssm view` prints it once its animation has moved.
    #[arg(long, value_name = "SECONDS", conflicts_with = "animate", allow_negative_numbers = true, value_parser = finite_f32)]
    time: Option<f32>,
}

/// `cssm render`, checked: the method's options resolved by its table; the image size and the
/// shadow-map resolution are checked by the runtime's frame settings once the scene (its
/// camera) is loaded.
pub struct RenderConfig {
    /// Scene directory or mesh file; `None`: the built-in Cornell box.
    pub scene: Option<PathBuf>,
    /// The method.
    pub method: &'static MethodEntry,
    /// The method options the user gave.
    pub values: OptionValues,
    /// Every option of the method, the given ones and the defaults, checked by its table.
    pub resolved: Resolved,
    /// Output PNG.
    pub out: PathBuf,
    /// Output OpenEXR.
    pub exr: Option<PathBuf>,
    /// Image size; `None`: the scene camera's.
    pub size: Option<(u32, u32)>,
    /// Exposure in stops; `None`: automatic ([`runtime::common::tonemap::auto_exposure_stops`]).
    pub exposure: Option<f32>,
    /// Shadow-map resolution.
    pub shadow_resolution: u32,
    /// How the CSSM methods query visibility (`--one-end`).
    pub visibility: QueryOptions,
    /// `--timings`.
    pub timings: bool,
    /// `--stats`.
    pub stats: bool,
    /// The scene's `.cssm`; `None`: baked in memory where the method needs one.
    pub cssm: Option<PathBuf>,
    /// Frames to average, 1..=[`MAX_FRAMES`].
    pub frames: u32,
    /// Which light the image holds.
    pub component: Component,
    /// `--camera EYE,TARGET`: the camera's eye and target instead of the scene's (its up and
    /// field of view stay).
    pub camera: Option<Pose>,
    /// `--light POSITION,DIRECTION`: the first spot light's instead of the scene's (its cone
    /// and intensity stay).
    pub light: Option<Pose>,
    /// `--animate`: render the scene's animation into the directory `out`.
    pub animate: Option<AnimateOptions>,
    /// `--time SECONDS`: the moving objects placed where the animation has them then.
    pub time: Option<f32>,
}

/// `cssm render --animate`'s options, as given: the frame count, rate and duration are resolved
/// against the scene's animation by [`AnimateOptions::plan`].
#[derive(Clone, Debug, PartialEq)]
pub struct AnimateOptions {
    /// `--frames`.
    pub frames: Option<u32>,
    /// `--fps`, finite and above 0.
    pub fps: Option<f32>,
    /// `--duration` in seconds, finite and above 0.
    pub duration: Option<f32>,
    /// `--overwrite`.
    pub overwrite: bool,
    /// Write `animation.gif` (no `--no-gif`).
    pub gif: bool,
}

/// Frames per second of `--animate` without `--fps`.
pub const DEFAULT_FPS: f32 = 24.0;

impl AnimateOptions {
    /// The frame count and the seconds they span, for an animation of `scene_duration` seconds
    /// (the scene's, or the default spin's): at most two of `--frames`, `--fps` and `--duration`
    /// are given, the others follow (`--fps` defaults to [`DEFAULT_FPS`], `--duration` to
    /// `scene_duration`), and the count is 1 to [`MAX_FRAMES`].
    pub fn plan(&self, scene_duration: f32) -> Result<(u32, f32), String> {
        let (frames, duration) = match (self.frames, self.fps, self.duration) {
            (Some(_), Some(_), Some(_)) => {
                return Err(
                    "--animate takes at most two of --frames, --fps and --duration \
                            (the third follows from them)"
                        .into(),
                );
            }
            (Some(n), Some(fps), None) => (n as f64, n as f64 / fps as f64),
            (Some(n), None, duration) => (n as f64, duration.unwrap_or(scene_duration) as f64),
            (None, fps, duration) => {
                let duration = duration.unwrap_or(scene_duration) as f64;
                let fps = fps.unwrap_or(DEFAULT_FPS) as f64;
                ((duration * fps).round().max(1.0), duration)
            }
        };
        if !(1.0..=MAX_FRAMES as f64).contains(&frames) {
            return Err(format!(
                "--animate: {frames} frames is out of range 1..={MAX_FRAMES} (lower --fps or \
                 --duration, or give --frames)"
            ));
        }
        if !(duration.is_finite() && duration > 0.0 && duration <= f32::MAX as f64) {
            return Err(format!(
                "--animate: the animation lasts {duration} s; give --duration"
            ));
        }
        Ok((frames as u32, duration as f32))
    }
}

impl RenderArgs {
    /// The method's options from the flags, resolved by the runtime's method table, and the
    /// frame count checked.
    pub fn config(self) -> Result<RenderConfig, String> {
        // With --animate, --frames counts the animation's frames, each rendered once.
        let frames = if self.animate {
            1
        } else {
            self.frames.unwrap_or(1)
        };
        if let Some(n) = self.frames
            && !(1..=MAX_FRAMES).contains(&n)
        {
            return Err(format!("--frames {n} is out of range 1..={MAX_FRAMES}"));
        }
        let animate = self.animate.then_some(AnimateOptions {
            frames: self.frames,
            fps: self.fps,
            duration: self.duration,
            overwrite: self.overwrite,
            gif: !self.no_gif,
        });
        if animate.is_some() {
            if self.out.is_none() {
                return Err("--animate writes its frames into a directory: give --out DIR".into());
            }
            for (given, flag) in [(self.exr.is_some(), "--exr"), (self.timings, "--timings")] {
                if given {
                    return Err(format!(
                        "{flag} is for one image and does not go with --animate"
                    ));
                }
            }
        }
        let values = self.option_values(frames)?;
        let resolved = self.method.resolve(&values).map_err(|e| e.to_string())?;
        Ok(RenderConfig {
            scene: self.scene,
            method: self.method,
            values,
            resolved,
            out: self.out.unwrap_or_else(|| PathBuf::from("render.png")),
            exr: self.exr,
            size: self.image.size,
            exposure: self.exposure,
            shadow_resolution: self.image.shadow_resolution,
            visibility: QueryOptions {
                both_ends: !self.image.one_end,
                ..QueryOptions::default()
            },
            timings: self.timings,
            stats: self.stats,
            cssm: self.cssm,
            frames,
            component: self.image.component,
            camera: self.image.camera,
            light: self.image.light,
            animate,
            time: self.time,
        })
    }

    /// The method options the user gave: the short flags, then `--set` in order. A short flag
    /// for an option the method does not have is ignored with a warning (`--bounces` with
    /// `direct`); `--set` of an unknown option is an error, from the method table.
    fn option_values(&self, frames: u32) -> Result<OptionValues, String> {
        option_values(
            self.method,
            [
                ("bounces", self.image.bounces.map(OptionValue::Count)),
                ("threshold", self.image.threshold.map(OptionValue::Number)),
                ("samples", self.samples.map(OptionValue::Count)),
            ],
            frames,
            &self.image.set,
        )
    }
}

/// The method options the user gave (`cssm render` and `cssm view`): the short flags, then
/// `--set` in order; see [`RenderArgs::option_values`].
fn option_values(
    method: &'static MethodEntry,
    short: [(&str, Option<OptionValue>); 3],
    frames: u32,
    set: &[String],
) -> Result<OptionValues, String> {
    let mut values = OptionValues::default();
    for (name, value) in short {
        let Some(value) = value else { continue };
        if method.option(name).is_some() {
            values.set(name, value);
        } else {
            eprintln!("warning: --{name} has no effect on method {method}");
        }
    }
    // Several frames of lightcuts jitter unless told otherwise (§4.5).
    if frames > 1 && method.option("jitter").is_some() {
        values.set("jitter", OptionValue::Switch(true));
    }
    for assignment in set {
        let (name, text) = assignment
            .split_once('=')
            .ok_or_else(|| format!("--set {assignment}: expected NAME=VALUE"))?;
        let spec = method.option(name.trim()).ok_or_else(|| {
            let known: Vec<&str> = method.options.iter().map(|o| o.name).collect();
            format!(
                "--set {assignment}: method {method} has no option '{}' (its options: {})",
                name.trim(),
                if known.is_empty() {
                    "none".into()
                } else {
                    known.join(", ")
                }
            )
        })?;
        values.set(spec.name, spec.parse(text)?);
    }
    Ok(values)
}
