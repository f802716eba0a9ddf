//! A frame, pass by pass: the table of contents of the renderer. Every method runs the shared
//! passes it needs in this order:
//!
//! 1. `common::shadow_map` — one depth map per spot light (§4.7)
//! 2. `common::gbuffer` — position, normal, material, albedo, atlas coordinates per pixel
//! 3. the method's own passes — `direct`: `direct::ScreenDirect` (spot lights, PCF shadows)
//! 4. `common::tonemap` — exposure, ACES, sRGB
//!
//! and [`render_atlas_direct`] runs 1 and `direct::AtlasDirect`: the direct light in the atlas
//! texels that the indirect methods start from.

use std::{fmt, path::Path, str::FromStr};

use cssm_formats::{CssmFile, Scene, visibility::QueryOptions};
use wgpu::util::DeviceExt;

use crate::{
    Gpu, RuntimeError,
    common::{
        camera::View, gbuffer::GBuffer, readback, shadow_map, shadow_map::ShadowMaps,
        timestamps::PassTimer, tonemap::Tonemap,
    },
    direct::{AtlasDirect, ScreenDirect},
    load::{CssmGpu, SceneGpu},
};

/// A rendering method: what `cssm render --method` picks from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Direct light from the spot lights with shadow maps, no indirect light.
    Direct,
}

impl Method {
    /// Every method, in the order `--help` lists them.
    pub const ALL: [Method; 1] = [Method::Direct];

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Method::Direct => "direct",
        }
    }

    /// One line on what it computes.
    pub fn describe(self) -> &'static str {
        match self {
            Method::Direct => "direct light from spot lights, PCF shadow maps (no indirect light)",
        }
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
    /// Frames rendered; GPU timings are those of the last (the first warms caches up).
    pub frames: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            exposure: 1.0,
            shadow_resolution: shadow_map::DEFAULT_RESOLUTION,
            frames: 1,
        }
    }
}

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

/// Renders `scene` with `method`.
///
/// # Errors
/// Unsupported lights or sizes, unreadable textures, GPU errors.
pub fn render(
    gpu: &Gpu,
    scene: &Scene,
    method: Method,
    options: &RenderOptions,
) -> Result<Frame, RuntimeError> {
    let (w, h) = (options.width, options.height);
    if w == 0 || h == 0 || w > MAX_SIDE || h > MAX_SIDE {
        return Err(RuntimeError::Unsupported(format!(
            "image size {w}x{h}: each side must be 1 to {MAX_SIDE}"
        )));
    }
    let device = &gpu.device;
    let scene_gpu = SceneGpu::new(device, &gpu.queue, scene, None)?;
    let lights = shadow_map::gpu_lights(scene, options.shadow_resolution)?;
    let shadows = ShadowMaps::new(device, &lights, options.shadow_resolution);
    let view = View::of_scene(scene, w, h);
    let view_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("view"),
        contents: bytemuck::bytes_of(&view.gpu(lights.len() as u32, options.exposure)),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let gbuffer = GBuffer::new(device, &scene_gpu, &view_buffer, w, h);
    let Method::Direct = method;
    let direct = ScreenDirect::new(device, &view_buffer, &scene_gpu, &shadows, &gbuffer);
    let tonemap = Tonemap::new(device, &view_buffer, &direct.radiance);
    let mut timer = PassTimer::new(gpu);
    let mut timings = Vec::new();
    for _ in 0..options.frames.max(1) {
        let mut encoder = device.create_command_encoder(&Default::default());
        shadows.render(&mut encoder, &scene_gpu, &mut timer);
        gbuffer.render(&mut encoder, &scene_gpu, &mut timer);
        direct.run(&mut encoder, &mut timer);
        tonemap.run(&mut encoder, &mut timer);
        timer.resolve(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        gpu.wait()?;
        timings = timer.read(gpu)?;
    }
    let radiance = readback::read_texture(gpu, &direct.radiance, 16)?;
    let display = readback::read_texture(gpu, &tonemap.ldr, 4)?;
    Ok(Frame {
        width: w,
        height: h,
        radiance: bytemuck::cast_slice(&radiance).to_vec(),
        display,
        timings,
    })
}

/// Direct light in the atlas texels of `file` (baked from `scene`): diffuse radiance leaving
/// each texel, in texel order.
pub fn render_atlas_direct(
    gpu: &Gpu,
    scene: &Scene,
    file: &CssmFile,
    shadow_resolution: u32,
) -> Result<Vec<[f32; 4]>, RuntimeError> {
    let device = &gpu.device;
    let scene_gpu = SceneGpu::new(device, &gpu.queue, scene, Some(file))?;
    let cssm = CssmGpu::new(device, &gpu.queue, file, QueryOptions::default())?;
    let lights = shadow_map::gpu_lights(scene, shadow_resolution)?;
    let shadows = ShadowMaps::new(device, &lights, shadow_resolution);
    let view = View::of_scene(scene, 1, 1);
    let view_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("view"),
        contents: bytemuck::bytes_of(&view.gpu(lights.len() as u32, 1.0)),
        usage: wgpu::BufferUsages::UNIFORM,
    });
    let atlas = AtlasDirect::new(device, &view_buffer, &scene_gpu, &shadows, &cssm);
    let mut timer = PassTimer::new(gpu);
    let mut encoder = device.create_command_encoder(&Default::default());
    shadows.render(&mut encoder, &scene_gpu, &mut timer);
    atlas.run(&mut encoder, &mut timer);
    gpu.queue.submit([encoder.finish()]);
    gpu.wait()?;
    let bytes =
        readback::read_buffer(gpu, &atlas.texel_radiance, 0, 16 * atlas.texel_count as u64)?;
    Ok(bytemuck::cast_slice(&bytes).to_vec())
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
