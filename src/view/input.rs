//! The inputs the window acts on, from the window system or a `--script` step: the mouse, the
//! keys (one handler for both), and the script's steps.

use super::*;

impl App {
    /// Handles one input, from the window system or a script.
    pub(super) fn input(&mut self, event_loop: &ActiveEventLoop, input: Input) {
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

    pub(super) fn mouse_moved(&mut self, position: PhysicalPosition<f64>) {
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

    pub(super) fn key(&mut self, event_loop: &ActiveEventLoop, event: &KeyPress) {
        let view = &mut self.view;
        // The fly keys by their place on the keyboard (WASD on any layout): a press moves one
        // step, and while held the camera flies on every frame, scaled by the frame time (key
        // repeat, which comes at the keyboard's rate, is ignored).
        if let PhysicalKey::Code(code) = event.physical
            && let Some((forward, right, up)) = super::state::fly_direction(code)
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

    /// At a frame's end: the next step of the `--script`, unless a `wait` still runs. Each
    /// step becomes the inputs a person's hand would make, handled as the window's own.
    pub(super) fn script_step(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
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
}
