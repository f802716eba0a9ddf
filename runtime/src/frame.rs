//! A frame, pass by pass: the table of contents of the renderer. Every method runs the shared
//! passes it needs in this order:
//!
//! 1. `common::shadow_map` — one depth map per spot light (§4.7)
//! 2. `common::gbuffer` — position, normal, material, albedo, atlas coordinates per pixel
//! 3. `direct::ScreenDirect` — direct light per pixel (spot lights, PCF shadows)
//! 4. the method's indirect light, for `hrc`, `lightmap` and `lightcuts`:
//!    1. `direct::AtlasDirect` — direct light into the atlas texels
//!    2. `radiosity::Radiosity` — the diffuse bounces over the hierarchy (§4.1-§4.3): gather,
//!       then pull, per bounce
//!    3. `lightmap::AtlasLookup` (`hrc`: nearest texel, `lightmap`: bicubic) or
//!       `lightcuts::FinalGather` (`lightcuts`: the last, glossy bounce per pixel, §4.4)
//! 5. `common::compose` — direct + indirect, or either alone (`--component`)
//! 6. `common::tonemap` — exposure, ACES, sRGB
//!
//! `reference` is the CPU path tracer (`reference`), the ground truth; [`render_atlas_direct`]
//! runs 1 and `direct::AtlasDirect` alone.

use std::{fmt, path::Path, str::FromStr};

use cssm_formats::{CssmFile, Scene, visibility::QueryOptions};
use wgpu::util::DeviceExt;

pub use crate::common::compose::Component;
use crate::{
    Gpu, RuntimeError,
    common::{
        camera::View, compose::Compose, gbuffer::GBuffer, readback, shadow_map,
        shadow_map::ShadowMaps, timestamps::PassTimer, tonemap::Tonemap,
    },
    direct::{AtlasDirect, ScreenDirect},
    lightcuts::FinalGather,
    lightmap::{AtlasLookup, Filter},
    load::{CssmGpu, SceneGpu},
    radiosity::{HierarchyGpu, Radiosity, RadiosityOptions},
};

/// A rendering method: what `cssm render --method` picks from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Direct light from the spot lights with shadow maps, no indirect light.
    Direct,
    /// GPU hierarchical radiosity, shown directly: each pixel takes its atlas texel's indirect
    /// light (§4.1-§4.3).
    Hrc,
    /// GPU hierarchical radiosity with a final gather per pixel, lightcuts-style (§4.4, §4.5).
    Lightcuts,
    /// GPU hierarchical radiosity looked up per pixel with a bicubic filter (§5, Fig. 17).
    Lightmap,
    /// The CPU path tracer (`reference`), ground truth: no GPU, no CSSM.
    Reference,
}

impl Method {
    /// Every method, in the order `--help` lists them.
    pub const ALL: [Method; 5] = [
        Method::Direct,
        Method::Hrc,
        Method::Lightcuts,
        Method::Lightmap,
        Method::Reference,
    ];

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Method::Direct => "direct",
            Method::Hrc => "hrc",
            Method::Lightcuts => "lightcuts",
            Method::Lightmap => "lightmap",
            Method::Reference => "reference",
        }
    }

    /// One line on what it computes.
    pub fn describe(self) -> &'static str {
        match self {
            Method::Direct => "direct light from spot lights, PCF shadow maps (no indirect light)",
            Method::Hrc => {
                "GPU hierarchical radiosity over the atlas, each pixel showing its texel (§4.1-4.3)"
            }
            Method::Lightcuts => {
                "hierarchical radiosity, then a final gather per pixel with a glossy last bounce (§4.4)"
            }
            Method::Lightmap => {
                "hierarchical radiosity looked up per pixel with a bicubic filter (§5, Fig. 17)"
            }
            Method::Reference => {
                "CPU path tracer with exact ray casts (obvhs, rayon): ground truth"
            }
        }
    }

    /// Whether the method needs a `.cssm` file (the indirect light).
    pub fn needs_cssm(self) -> bool {
        !matches!(self, Method::Direct | Method::Reference)
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
                format!("unknown method '{s}' (available: {})", names.join(", "))
            })
    }
}

/// Options of a frame.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Multiplier applied to radiance before tone mapping.
    pub exposure: f32,
    /// Shadow-map resolution.
    pub shadow_resolution: u32,
    /// Frames rendered; GPU timings are those of the last (the first warms caches up). The
    /// final gather averages them (progressive refinement of a still camera, §4.5).
    pub frames: u32,
    /// Indirect bounces (`hrc`, `lightmap`: radiosity iterations; `lightcuts`: iterations + 1,
    /// the final gather being the last bounce).
    pub bounces: u32,
    /// Oracle threshold (§4.3): refine while a sender's tone-mapped bound exceeds it.
    pub threshold: f32,
    /// Jitter every sender over its node's texels (§4.5), a new draw each frame.
    pub jitter: bool,
    /// Which light paths the image holds.
    pub component: Component,
    /// Paths per pixel of the `reference` path tracer.
    pub samples: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            exposure: 1.0,
            shadow_resolution: shadow_map::DEFAULT_RESOLUTION,
            frames: 1,
            bounces: 1,
            threshold: crate::radiosity::DEFAULT_THRESHOLD,
            jitter: false,
            component: Component::Full,
            samples: 256,
        }
    }
}

/// Most bounces `render` accepts.
pub const MAX_BOUNCES: u32 = 8;

/// A rendered frame.
pub struct Frame {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Linear radiance, RGBA, row-major, row 0 at the top.
    pub radiance: Vec<[f32; 4]>,
    /// Tone-mapped sRGB, RGBA8.
    pub display: Vec<u8>,
    /// GPU milliseconds per pass of the last frame, empty when the adapter has no timestamps.
    pub timings: Vec<(&'static str, f64)>,
}

/// Largest image side `render` accepts.
pub const MAX_SIDE: u32 = 8192;

/// Refuses image sizes outside 1 to [`MAX_SIDE`].
fn check_size(w: u32, h: u32) -> Result<(), RuntimeError> {
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(RuntimeError::Unsupported(format!(
            "image size {w}x{h}: each side must be 1 to {MAX_SIDE}"
        )));
    }
    Ok(())
}

/// The view constants of a `w`x`h` image of `scene` as a uniform buffer.
fn view_buffer(
    device: &wgpu::Device,
    scene: &Scene,
    w: u32,
    h: u32,
    lights: u32,
    exposure: f32,
) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("view"),
        contents: bytemuck::bytes_of(&View::of_scene(scene, w, h).gpu(lights, exposure)),
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

/// Renders `scene` with `method`; `file` is the scene's baked CSSM, which every method but
/// `direct` needs.
///
/// # Errors
/// Unsupported lights, sizes or bounces, a missing or mismatched `.cssm`, unreadable textures,
/// GPU errors.
pub fn render(
    gpu: &Gpu,
    scene: &Scene,
    file: Option<&CssmFile>,
    method: Method,
    options: &RenderOptions,
) -> Result<Frame, RuntimeError> {
    let (w, h) = (options.width, options.height);
    check_size(w, h)?;
    if options.bounces > MAX_BOUNCES {
        return Err(RuntimeError::Unsupported(format!(
            "{} bounces: at most {MAX_BOUNCES}",
            options.bounces
        )));
    }
    if !(options.threshold.is_finite() && options.threshold >= 0.0) {
        return Err(RuntimeError::Unsupported(format!(
            "threshold {}: must be finite and >= 0",
            options.threshold
        )));
    }
    if method == Method::Reference {
        return render_reference(scene, options, &|_, _| {});
    }
    let file = match (method.needs_cssm(), file) {
        (true, None) => {
            return Err(RuntimeError::Unsupported(format!(
                "method '{method}' needs the scene's .cssm file"
            )));
        }
        (true, Some(f)) => Some(f),
        (false, _) => None,
    };
    let device = &gpu.device;
    let scene_gpu = SceneGpu::new(device, &gpu.queue, scene, file)?;
    let lights = shadow_map::gpu_lights(scene, options.shadow_resolution)?;
    let shadows = ShadowMaps::new(device, &lights, options.shadow_resolution);
    let view_buffer = view_buffer(device, scene, w, h, lights.len() as u32, options.exposure);
    let gbuffer = GBuffer::new(device, &scene_gpu, &view_buffer, w, h);
    let direct = ScreenDirect::new(device, &view_buffer, &scene_gpu, &shadows, &gbuffer);
    let indirect = match file {
        Some(file) => Some(Indirect::new(
            gpu,
            scene,
            &view_buffer,
            &scene_gpu,
            &shadows,
            &gbuffer,
            file,
            method,
            options,
        )?),
        None => None,
    };
    let no_indirect;
    let indirect_buffer = match &indirect {
        Some(i) => i.output(),
        None => {
            no_indirect = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("no indirect light"),
                size: 16 * (w * h) as u64,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            });
            &no_indirect
        }
    };
    let compose = Compose::new(
        device,
        &view_buffer,
        &direct.radiance,
        indirect_buffer,
        options.component,
    );
    let tonemap = Tonemap::new(device, &view_buffer, &compose.radiance);
    let mut timer = PassTimer::new(gpu);
    let mut timings = Vec::new();
    for frame in 0..options.frames.max(1) {
        let mut encoder = device.create_command_encoder(&Default::default());
        shadows.render(&mut encoder, &scene_gpu, &mut timer);
        gbuffer.render(&mut encoder, &scene_gpu, &mut timer);
        direct.run(&mut encoder, &mut timer);
        if let Some(i) = &indirect {
            i.run(gpu, &mut encoder, &mut timer, frame);
        }
        compose.run(&mut encoder, &mut timer);
        tonemap.run(&mut encoder, &mut timer);
        timer.resolve(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        gpu.wait()?;
        timings = timer.read(gpu)?;
    }
    let radiance = readback::read_texture(gpu, &compose.radiance, 16)?;
    let display = readback::read_texture(gpu, &tonemap.ldr, 4)?;
    Ok(Frame {
        width: w,
        height: h,
        radiance: bytemuck::cast_slice(&radiance).to_vec(),
        display,
        timings,
    })
}

/// Renders `scene` with the CPU path tracer ([`crate::reference`]): `options.samples` paths
/// per pixel, `options.bounces` indirect bounces, tone-mapped on the CPU with the GPU's curve.
/// `progress(done, total)` is called as rows complete.
///
/// # Errors
/// Unsupported sizes or an unreadable texture.
pub fn render_reference(
    scene: &Scene,
    options: &RenderOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<Frame, RuntimeError> {
    let (w, h) = (options.width, options.height);
    check_size(w, h)?;
    let (materials, textures) = crate::load::cpu_materials(scene)?;
    let bvh = cssm_bake::raycast::SceneBvh::new(scene);
    let view = View::of_scene(scene, w, h);
    let reference = crate::reference::ReferenceOptions {
        samples_per_pixel: options.samples.max(1),
        bounces: options.bounces,
        component: options.component,
        ..Default::default()
    };
    let image = crate::reference::render_reference(
        scene, &view, &materials, &textures, &bvh, &reference, progress,
    );
    let radiance: Vec<[f32; 4]> = image.iter().map(|c| [c.x, c.y, c.z, 1.0]).collect();
    let display = radiance
        .iter()
        .flat_map(|c| {
            let [r, g, b] = crate::common::tonemap::tonemap([c[0], c[1], c[2]], options.exposure);
            [r, g, b, 255]
        })
        .collect();
    Ok(Frame {
        width: w,
        height: h,
        radiance,
        display,
        timings: Vec::new(),
    })
}

/// Diffuse albedo of every texel of `file` (Kd of its material; textures are not sampled in
/// the atlas), as the radiosity iteration takes it.
pub fn texel_albedo(scene: &Scene, file: &CssmFile) -> Vec<[f32; 4]> {
    file.texels
        .iter()
        .map(|t| {
            let kd = scene.materials[t.material as usize].kd;
            [kd[0], kd[1], kd[2], 0.0]
        })
        .collect()
}

/// The view-independent part of the indirect light: the direct light into the atlas texels,
/// then the radiosity iteration over the hierarchy.
struct AtlasGi {
    cssm: CssmGpu,
    hierarchy: HierarchyGpu,
    atlas: AtlasDirect,
    radiosity: Radiosity,
}

impl AtlasGi {
    #[allow(clippy::too_many_arguments)]
    fn new(
        gpu: &Gpu,
        scene: &Scene,
        view_buffer: &wgpu::Buffer,
        scene_gpu: &SceneGpu,
        shadows: &ShadowMaps,
        file: &CssmFile,
        options: RadiosityOptions,
    ) -> Result<Self, RuntimeError> {
        let device = &gpu.device;
        let cssm = CssmGpu::new(device, &gpu.queue, file, QueryOptions::default())?;
        let hierarchy = HierarchyGpu::new(device, &file.hierarchy)?;
        let atlas = AtlasDirect::new(device, view_buffer, scene_gpu, shadows, &cssm);
        let radiosity = Radiosity::new(
            device,
            &cssm,
            &hierarchy,
            &atlas.texel_radiance,
            &texel_albedo(scene, file),
            options,
        )?;
        Ok(Self {
            cssm,
            hierarchy,
            atlas,
            radiosity,
        })
    }

    fn run(&self, encoder: &mut wgpu::CommandEncoder, timer: &mut PassTimer, iterations: u32) {
        self.atlas.run(encoder, timer);
        self.radiosity.run(encoder, &self.cssm, timer, iterations);
    }
}

/// The indirect-light passes of a frame.
struct Indirect {
    gi: AtlasGi,
    iterations: u32,
    per_pixel: PerPixel,
    jitter: bool,
}

enum PerPixel {
    Lookup(AtlasLookup),
    Gather(FinalGather),
}

impl Indirect {
    #[allow(clippy::too_many_arguments)]
    fn new(
        gpu: &Gpu,
        scene: &Scene,
        view_buffer: &wgpu::Buffer,
        scene_gpu: &SceneGpu,
        shadows: &ShadowMaps,
        gbuffer: &GBuffer,
        file: &CssmFile,
        method: Method,
        options: &RenderOptions,
    ) -> Result<Self, RuntimeError> {
        let device = &gpu.device;
        let radiosity_options = RadiosityOptions {
            threshold: options.threshold,
            exposure: options.exposure,
        };
        let gi = AtlasGi::new(
            gpu,
            scene,
            view_buffer,
            scene_gpu,
            shadows,
            file,
            radiosity_options,
        )?;
        let (iterations, per_pixel) = match method {
            Method::Lightcuts => {
                let iterations = options.bounces.saturating_sub(1);
                let gather = FinalGather::new(
                    device,
                    view_buffer,
                    scene_gpu,
                    gbuffer,
                    &gi.cssm,
                    &gi.hierarchy,
                    gi.radiosity.radiance(iterations),
                    options.threshold,
                    options.exposure,
                );
                (iterations, PerPixel::Gather(gather))
            }
            _ => {
                let filter = if method == Method::Hrc {
                    Filter::Nearest
                } else {
                    Filter::Bicubic
                };
                let lookup = AtlasLookup::new(
                    device,
                    view_buffer,
                    gbuffer,
                    &gi.cssm,
                    &gi.radiosity.texel_irradiance,
                    filter,
                );
                (options.bounces, PerPixel::Lookup(lookup))
            }
        };
        Ok(Self {
            gi,
            iterations,
            per_pixel,
            jitter: options.jitter,
        })
    }

    fn output(&self) -> &wgpu::Buffer {
        match &self.per_pixel {
            PerPixel::Lookup(l) => &l.indirect,
            PerPixel::Gather(g) => &g.indirect,
        }
    }

    fn run(
        &self,
        gpu: &Gpu,
        encoder: &mut wgpu::CommandEncoder,
        timer: &mut PassTimer,
        frame: u32,
    ) {
        self.gi.run(encoder, timer, self.iterations);
        let cssm = &self.gi.cssm;
        match &self.per_pixel {
            PerPixel::Lookup(l) => l.run(encoder, cssm, timer),
            PerPixel::Gather(g) => g.run(&gpu.queue, encoder, cssm, timer, frame, self.jitter),
        }
    }
}

/// Direct light in the atlas texels of `file` (baked from `scene`): diffuse radiance leaving
/// each texel, in texel order.
pub fn render_atlas_direct(
    gpu: &Gpu,
    scene: &Scene,
    file: &CssmFile,
    shadow_resolution: u32,
) -> Result<Vec<[f32; 4]>, RuntimeError> {
    Ok(atlas_radiosity(
        gpu,
        scene,
        file,
        shadow_resolution,
        0,
        RadiosityOptions::default(),
    )?
    .direct)
}

/// The radiosity solution in the atlas, read back (what the view-independent part of a frame
/// computes).
#[derive(Clone, Debug)]
pub struct AtlasRadiosity {
    /// Direct radiance leaving every texel (texel order, rgb).
    pub direct: Vec<[f32; 4]>,
    /// Indirect irradiance of every texel after the iterations (texel order, rgb).
    pub irradiance: Vec<[f32; 4]>,
    /// Mean radiance of every hierarchy node after the iterations (rgb).
    pub node_radiance: Vec<[f32; 4]>,
    /// GPU milliseconds per pass, empty without timestamps.
    pub timings: Vec<(&'static str, f64)>,
}

/// Runs the direct light into the atlas and `iterations` radiosity bounces (§4.1-§4.3) on
/// `file` (baked from `scene`).
pub fn atlas_radiosity(
    gpu: &Gpu,
    scene: &Scene,
    file: &CssmFile,
    shadow_resolution: u32,
    iterations: u32,
    options: RadiosityOptions,
) -> Result<AtlasRadiosity, RuntimeError> {
    let device = &gpu.device;
    let scene_gpu = SceneGpu::new(device, &gpu.queue, scene, Some(file))?;
    let lights = shadow_map::gpu_lights(scene, shadow_resolution)?;
    let shadows = ShadowMaps::new(device, &lights, shadow_resolution);
    let view_buffer = view_buffer(device, scene, 1, 1, lights.len() as u32, 1.0);
    let gi = AtlasGi::new(
        gpu,
        scene,
        &view_buffer,
        &scene_gpu,
        &shadows,
        file,
        options,
    )?;
    let mut timer = PassTimer::new(gpu);
    let mut encoder = device.create_command_encoder(&Default::default());
    shadows.render(&mut encoder, &scene_gpu, &mut timer);
    gi.run(&mut encoder, &mut timer, iterations);
    timer.resolve(&mut encoder);
    gpu.queue.submit([encoder.finish()]);
    gpu.wait()?;
    let timings = timer.read(gpu)?;
    let (atlas, radiosity) = (&gi.atlas, &gi.radiosity);
    let texels = 16 * atlas.texel_count as u64;
    let read = |buffer: &wgpu::Buffer, bytes: u64| -> Result<Vec<[f32; 4]>, RuntimeError> {
        Ok(bytemuck::cast_slice(&readback::read_buffer(gpu, buffer, 0, bytes)?).to_vec())
    };
    Ok(AtlasRadiosity {
        direct: read(&atlas.texel_radiance, texels)?,
        irradiance: read(&radiosity.texel_irradiance, texels)?,
        node_radiance: read(
            radiosity.radiance(iterations),
            16 * gi.hierarchy.node_count as u64,
        )?,
        timings,
    })
}

/// Encodes `image` as `format` in memory and writes it with the project's one atomic write
/// (`cssm_formats::cssm::write_bytes_atomic`): a failed write never leaves a half-written image.
fn save_image(
    path: &Path,
    image: image::DynamicImage,
    format: image::ImageFormat,
) -> Result<(), RuntimeError> {
    let fail = |reason: String| RuntimeError::Output {
        path: path.to_path_buf(),
        reason,
    };
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut bytes, format)
        .map_err(|e| fail(e.to_string()))?;
    cssm_formats::cssm::write_bytes_atomic(path, bytes.get_ref()).map_err(|e| match e {
        // The error names the path already; keep just the cause.
        cssm_formats::cssm::CssmError::Io { error, .. } => fail(error.to_string()),
        other => fail(other.to_string()),
    })
}

impl Frame {
    /// Saves the tone-mapped image as PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), RuntimeError> {
        let img = image::RgbaImage::from_raw(self.width, self.height, self.display.clone())
            .ok_or_else(|| RuntimeError::Gpu("display image has the wrong size".into()))?;
        save_image(path, img.into(), image::ImageFormat::Png)
    }

    /// Saves the linear radiance as OpenEXR (32-bit float RGBA).
    pub fn save_exr(&self, path: &Path) -> Result<(), RuntimeError> {
        let data: Vec<f32> = self.radiance.iter().flatten().copied().collect();
        let img = image::Rgba32FImage::from_raw(self.width, self.height, data)
            .ok_or_else(|| RuntimeError::Gpu("radiance image has the wrong size".into()))?;
        save_image(path, img.into(), image::ImageFormat::OpenExr)
    }
}
