//! What the window shows, apart from the GPU objects ([`ViewState`], [`Playback`]): the method
//! and its options, the camera and light, the animation's time, and the `cssm render` flags of
//! the same image.

use super::*;

impl Playback {
    /// The playback of `scene`'s motion, paused at 0 s, nothing applied.
    pub(super) fn of(scene: &Scene) -> Playback {
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
    pub(super) fn poses(&self, scene: &Scene) -> Vec<(usize, glam::Affine3A)> {
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
    pub(super) fn new(
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
    pub(super) fn build(&self, gpu: &Gpu) -> Result<Renderer, String> {
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
    pub(super) fn toggle_playing(&mut self) {
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
    pub(super) fn describe(&self) -> String {
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
    pub(super) fn render_flags(&self, frames: u32) -> String {
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
    pub(super) fn cycle_method(&mut self, step: isize) {
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
    pub(super) fn select_method(&mut self, method: &'static MethodEntry) {
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
    pub(super) fn set_component(&mut self, component: Component) {
        if component != self.settings.component {
            self.settings.component = component;
            self.rebuild = true;
        }
    }

    /// Sets option `name` to `value` if the method has it and takes the value; says why not
    /// otherwise.
    pub(super) fn set_option(
        &mut self,
        name: &str,
        value: impl Fn(OptionValue) -> Option<OptionValue>,
    ) {
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
    pub(super) fn apply(&mut self, action: overlay::Action) {
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
    pub(super) fn fly_held(&mut self, seconds: f32) {
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
pub(super) fn fly_direction(code: KeyCode) -> Option<(f32, f32, f32)> {
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
