//! The window and what draws into it: opening the surface, resizing, a frame of the renderer
//! copied onto the surface ([`Blit`], `blit.wgsl`) with the overlay over it.

use super::*;

impl App {
    pub(super) fn open(&self, event_loop: &ActiveEventLoop) -> Result<Gfx, String> {
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

    /// Asks for the next frame while there is anything to draw: a change, accumulation not
    /// yet done, a script step, a key held, the overlay's own.
    pub(super) fn request_frame(&self) {
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
    pub(super) fn scene_frame_needed(&self) -> bool {
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

    pub(super) fn resize(&mut self, size: PhysicalSize<u32>) {
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

    /// Lays out the overlay and applies its controls, applies what changed, renders a frame
    /// into the image when anything changed or accumulation goes on, copies the image onto
    /// the surface with the overlay over it, writes the screenshots due, and runs the next
    /// script step.
    pub(super) fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), String> {
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
}

impl Blit {
    pub(super) fn new(
        device: &wgpu::Device,
        format: wgpu::TextureFormat,
        image: &wgpu::Texture,
    ) -> Self {
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

    pub(super) fn bind_group(
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
    pub(super) fn bind(&mut self, device: &wgpu::Device, image: &wgpu::Texture) {
        self.bind_group = Self::bind_group(device, &self.layout, &self.sampler, image);
    }

    pub(super) fn run(&self, encoder: &mut wgpu::CommandEncoder, target: &wgpu::TextureView) {
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
