//! The window's overlay (H shows and hides it): egui over the window's surface, never in the
//! renderer's image. It shows the current settings, camera and light, the GPU milliseconds of
//! every pass of the last frame (the renderer's timestamp queries) and the CPU wall time
//! between frames, and has menus that switch the method, component and bounces. Its controls
//! do nothing of their own: each returns an [`Action`], which the window applies through the
//! same [`ViewState`] calls as the keys.

use egui_wgpu::ScreenDescriptor;
use winit::{event::WindowEvent, window::Window};

use super::ViewState;
use cssm::runtime::{
    self,
    common::compose::Component,
    method::{MethodEntry, OptionKind, OptionValue},
};

/// What a control of the overlay asks the window to change.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Action {
    /// Switch to this method (Tab's switch).
    Method(&'static MethodEntry),
    /// Show this component (C's switch).
    Component(Component),
    /// Set the option `bounces` ([ and ]).
    Bounces(u32),
    /// Scale the option `threshold` (- and =).
    ScaleThreshold(f32),
}

/// The figures of the last frame the overlay shows.
pub struct Stats<'a> {
    /// GPU milliseconds per pass of the last rendered frame; empty without timestamp queries.
    pub timings: &'a [(&'static str, f64)],
    /// Whether the device has timestamp queries at all.
    pub timestamps: bool,
    /// CPU wall milliseconds between the last two frames.
    pub frame_ms: f64,
    /// Frames accumulated since the camera, light or renderer last changed.
    pub accumulated: u32,
    /// The adapter.
    pub gpu: &'a str,
}

/// egui's context, its winit input state and its wgpu painter.
pub struct Overlay {
    ctx: egui::Context,
    state: egui_winit::State,
    renderer: egui_wgpu::Renderer,
    /// Shown (H toggles).
    pub visible: bool,
    /// egui asked for another frame (a hover, a menu opening).
    pub wants_frame: bool,
    /// The last [`Overlay::run`]'s output, drawn by [`Overlay::draw`].
    pending: Option<egui::FullOutput>,
    /// The texture updates (the font atlas) of every run since the last draw: a run whose
    /// output is never drawn (hidden, or run twice between draws) must not lose them, or the
    /// painter would never get the atlas.
    deltas: egui::TexturesDelta,
}

/// Updates never applied are dropped on purpose with the painter they were for (egui asserts
/// in debug builds that a delta is applied or cleared).
impl Drop for Overlay {
    fn drop(&mut self) {
        self.deltas.clear();
        if let Some(output) = self.pending.as_mut() {
            output.textures_delta.clear();
        }
    }
}

impl Overlay {
    /// An overlay for `window`, drawn onto surfaces of `format`.
    pub fn new(window: &Window, device: &wgpu::Device, format: wgpu::TextureFormat) -> Self {
        let ctx = egui::Context::default();
        let state = egui_winit::State::new(
            ctx.clone(),
            egui::ViewportId::ROOT,
            window,
            Some(window.scale_factor() as f32),
            window.theme(),
            Some(device.limits().max_texture_dimension_2d as usize),
        );
        let renderer = egui_wgpu::Renderer::new(device, format, Default::default());
        Self {
            ctx,
            state,
            renderer,
            visible: true,
            wants_frame: true,
            pending: None,
            deltas: Default::default(),
        }
    }

    /// Offers a window event to egui (only while shown); true when egui takes it for itself (a
    /// click on the overlay), so that it does not also turn the camera.
    pub fn on_event(&mut self, window: &Window, event: &WindowEvent) -> bool {
        if !self.visible {
            return false;
        }
        let response = self.state.on_window_event(window, event);
        self.wants_frame |= response.repaint;
        response.consumed
    }

    /// Whether egui wants the keys (a text field has focus; the overlay has none, but a key
    /// typed into one must not also fly the camera).
    pub fn wants_keyboard(&self) -> bool {
        self.visible && self.ctx.egui_wants_keyboard_input()
    }

    /// Lays the overlay out for this frame; returns what its controls asked for.
    pub fn run(&mut self, window: &Window, view: &ViewState, stats: &Stats) -> Vec<Action> {
        self.wants_frame = false;
        if !self.visible {
            self.pending = None;
            return Vec::new();
        }
        let input = self.state.take_egui_input(window);
        let mut actions = Vec::new();
        let output = self.ctx.run_pass(input, |ctx| {
            egui::Window::new("cssm view")
                .default_pos([8.0, 8.0])
                .resizable(false)
                // A small window scrolls the overlay rather than cut it off; its title bar
                // folds it away.
                .vscroll(true)
                .show(ctx, |ui| panel(ui, view, stats, &mut actions));
        });
        let output = {
            let mut output = output;
            self.state
                .handle_platform_output(window, std::mem::take(&mut output.platform_output));
            self.deltas
                .append(std::mem::take(&mut output.textures_delta));
            output
        };
        // egui asks for an immediate repaint while something animates (a menu opening).
        self.wants_frame |= output
            .viewport_output
            .get(&egui::ViewportId::ROOT)
            .is_some_and(|v| v.repaint_delay.is_zero());
        self.pending = Some(output);
        actions
    }

    /// Records the drawing of the last [`Overlay::run`] onto `target` (the surface, after the
    /// blit), `size` pixels.
    pub fn draw(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        size: [u32; 2],
    ) {
        let Some(output) = self.pending.take() else {
            return;
        };
        let screen = ScreenDescriptor {
            size_in_pixels: size,
            pixels_per_point: output.pixels_per_point,
        };
        let jobs = self.ctx.tessellate(output.shapes, output.pixels_per_point);
        let mut textures = std::mem::take(&mut self.deltas);
        for (id, deltas) in &textures.set {
            for delta in deltas {
                self.renderer.update_texture(device, queue, *id, delta);
            }
        }
        let extra = self
            .renderer
            .update_buffers(device, queue, encoder, &jobs, &screen);
        // egui's own paint callbacks would record work here; the overlay has none.
        debug_assert!(extra.is_empty());
        {
            let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("view overlay"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        // Over the blitted image.
                        load: wgpu::LoadOp::Load,
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            self.renderer
                .render(&mut pass.forget_lifetime(), &jobs, &screen);
        }
        for id in &textures.free {
            self.renderer.free_texture(id);
        }
        // Applied: what egui's drop check asks of a delta handled.
        textures.clear();
    }
}

/// The overlay's contents.
fn panel(ui: &mut egui::Ui, view: &ViewState, stats: &Stats, actions: &mut Vec<Action>) {
    ui.label(format!("{} on {}", view.scene.name, stats.gpu));
    egui::ComboBox::from_label("method")
        .selected_text(view.method.name)
        .show_ui(ui, |ui| {
            for method in runtime::method::METHODS.iter().filter(|m| m.on_gpu()) {
                // Those needing a .cssm only when one is loaded, as Tab.
                let usable = !method.needs_cssm || view.cssm.is_some();
                let label = ui
                    .add_enabled_ui(usable, |ui| {
                        ui.selectable_label(method.name == view.method.name, method.name)
                    })
                    .inner
                    .on_hover_text(method.summary)
                    .on_disabled_hover_text("needs the scene's .cssm (--cssm FILE)");
                if label.clicked() && method.name != view.method.name {
                    actions.push(Action::Method(method));
                }
            }
        });
    egui::ComboBox::from_label("component")
        .selected_text(view.settings.component.name())
        .show_ui(ui, |ui| {
            for component in Component::ALL {
                if ui
                    .selectable_label(component == view.settings.component, component.name())
                    .clicked()
                    && component != view.settings.component
                {
                    actions.push(Action::Component(component));
                }
            }
        });
    if let Some(spec) = view.method.option("bounces")
        && let OptionKind::Count { min, max, .. } = spec.kind
    {
        let bounces = match view.values.get("bounces") {
            Some(OptionValue::Count(n)) => n,
            _ => match spec.kind.default() {
                OptionValue::Count(n) => n,
                _ => min,
            },
        };
        ui.horizontal(|ui| {
            ui.label("bounces");
            if ui
                .add_enabled(bounces > min, egui::Button::new("-"))
                .clicked()
            {
                actions.push(Action::Bounces(bounces - 1));
            }
            // 0: until converged (`runtime::common::converge`).
            ui.label(if bounces == 0 {
                "auto".to_string()
            } else {
                bounces.to_string()
            });
            if ui
                .add_enabled(bounces < max, egui::Button::new("+"))
                .clicked()
            {
                actions.push(Action::Bounces(bounces + 1));
            }
        });
    }
    if view.method.option("threshold").is_some() {
        ui.horizontal(|ui| {
            ui.label("threshold");
            if ui.button("x 1/2").clicked() {
                actions.push(Action::ScaleThreshold(0.5));
            }
            if ui.button("x 2").clicked() {
                actions.push(Action::ScaleThreshold(2.0));
            }
        });
    }
    // Every option of the method, the given ones and the defaults, as the table resolves them.
    if let Ok(resolved) = view.method.resolve(&view.values) {
        for (name, value) in resolved.iter() {
            ui.label(format!("{name} = {value}"));
        }
    }
    ui.separator();
    let c = &view.camera;
    ui.label(format!(
        "camera {:.3} {:.3} {:.3} -> {:.3} {:.3} {:.3}",
        c.position.x, c.position.y, c.position.z, c.target.x, c.target.y, c.target.z
    ));
    match &view.light {
        Some(l) => ui.label(format!(
            "light {:.3} {:.3} {:.3} dir {:.3} {:.3} {:.3}",
            l.position.x, l.position.y, l.position.z, l.direction.x, l.direction.y, l.direction.z
        )),
        None => ui.label("no spot light"),
    };
    ui.label(view.playback.describe());
    ui.separator();
    ui.label(format!(
        "frame {:.2} ms (CPU wall), {} frames accumulated",
        stats.frame_ms, stats.accumulated
    ));
    if stats.timings.is_empty() {
        ui.label(if stats.timestamps {
            "GPU: no frame timed yet"
        } else {
            "GPU: no timestamp queries on this adapter"
        });
    } else {
        egui::Grid::new("timings").striped(true).show(ui, |ui| {
            for (pass, ms) in stats.timings {
                ui.label(*pass);
                ui.label(format!("{ms:.3} ms"));
                ui.end_row();
            }
            ui.label("GPU total");
            ui.label(format!(
                "{:.3} ms",
                stats.timings.iter().map(|(_, ms)| ms).sum::<f64>()
            ));
            ui.end_row();
        });
    }
    ui.weak("H hides this; `cssm view --help` lists the keys");
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every text the overlay laid out (no GPU: egui's shapes before tessellation).
    fn texts(view: &ViewState, stats: &Stats) -> String {
        let ctx = egui::Context::default();
        let mut actions = Vec::new();
        let mut out = String::new();
        // egui measures the first pass and draws on the second.
        for _ in 0..2 {
            let mut output = ctx.run_pass(egui::RawInput::default(), |ctx| {
                egui::Window::new("cssm view").show(ctx, |ui| panel(ui, view, stats, &mut actions));
            });
            // No renderer takes the font atlas here: dropped unapplied, egui asserts in debug.
            output.textures_delta.clear();
            out.clear();
            let mut shapes: Vec<egui::Shape> = output.shapes.into_iter().map(|s| s.shape).collect();
            while let Some(shape) = shapes.pop() {
                match shape {
                    egui::Shape::Text(text) => {
                        out.push_str(text.galley.text());
                        out.push('\n');
                    }
                    egui::Shape::Vec(inner) => shapes.extend(inner),
                    _ => {}
                }
            }
        }
        assert!(actions.is_empty(), "nothing was clicked");
        out
    }

    #[test]
    fn the_overlay_shows_the_settings_and_the_gpu_time_or_why_not() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
        let scene = cssm::formats::Scene::load(&dir).unwrap();
        let view = ViewState::new(
            scene,
            None,
            Default::default(),
            runtime::method::find("vct").unwrap(),
            Default::default(),
        );
        let timings = [("gbuffer", 1.25), ("cone tracing", 3.5)];
        let shown = texts(
            &view,
            &Stats {
                timings: &timings,
                timestamps: true,
                frame_ms: 16.5,
                accumulated: 7,
                gpu: "test adapter",
            },
        );
        for expected in [
            "vct",
            "full",
            "bounces",
            "gbuffer",
            "3.500 ms",
            "4.750 ms",
            "16.50 ms (CPU wall), 7 frames",
            "camera ",
            "light ",
            "animation: nothing to move",
        ] {
            assert!(shown.contains(expected), "'{expected}' not in:\n{shown}");
        }
        let shown = texts(
            &view,
            &Stats {
                timings: &[],
                timestamps: false,
                frame_ms: 1.0,
                accumulated: 1,
                gpu: "test adapter",
            },
        );
        assert!(
            shown.contains("no timestamp queries on this adapter"),
            "{shown}"
        );
    }
}
