//! Copies GPU buffers and textures back to the CPU (tests, image output, timings), and writes
//! a read-back image as PNG or OpenEXR (`cssm render`, `cssm view`'s screenshots, the lab's
//! `cssm report error` and `cssm compare`).

use std::path::Path;

use crate::RuntimeError;

/// Reads `size` bytes of `buffer` from `offset` (the buffer needs `COPY_SRC`).
pub fn read_buffer(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    buffer: &wgpu::Buffer,
    offset: u64,
    size: u64,
) -> Result<Vec<u8>, RuntimeError> {
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, offset, &staging, 0, size);
    queue.submit([encoder.finish()]);
    map_and_copy(device, &staging, size)
}

fn map_and_copy(
    device: &wgpu::Device,
    staging: &wgpu::Buffer,
    size: u64,
) -> Result<Vec<u8>, RuntimeError> {
    map_read(device, staging, size, <[u8]>::to_vec)
}

/// Maps the first `size` bytes of `staging` (a `MAP_READ` buffer whose copy was submitted),
/// waits for the GPU, hands them to `read` and unmaps: `read` converts them in one pass, where
/// [`read_buffer`] copies them out first.
pub fn map_read<R>(
    device: &wgpu::Device,
    staging: &wgpu::Buffer,
    size: u64,
    read: impl FnOnce(&[u8]) -> R,
) -> Result<R, RuntimeError> {
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, 0..size, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RuntimeError::Gpu(e.to_string()))?;
    // A map fails when the device is lost (a driver reset, a removed GPU, `destroy`) or the
    // buffer destroyed; the callback may not even run then.
    let lost = |e: &dyn std::fmt::Display| {
        RuntimeError::Gpu(format!(
            "reading results back from the GPU failed ({e}): the device was lost (a driver \
             reset or a removed GPU) or the buffer destroyed"
        ))
    };
    rx.recv().map_err(|e| lost(&e))?.map_err(|e| lost(&e))?;
    let result = {
        let view = staging
            .get_mapped_range(0..size)
            .map_err(|e| RuntimeError::Gpu(e.to_string()))?;
        read(&view)
    };
    staging.unmap();
    Ok(result)
}

/// Reads a texture's mip 0 (every layer of an array, every slice of a 3D texture) as tightly
/// packed rows of `bytes_per_pixel`, layer after layer.
pub fn read_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
    bytes_per_pixel: u32,
) -> Result<Vec<u8>, RuntimeError> {
    let (w, h) = (texture.width(), texture.height());
    let layers = texture.depth_or_array_layers() as u64;
    let row = w * bytes_per_pixel;
    let padded =
        row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let size = padded as u64 * h as u64 * layers;
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback texture"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &staging,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(h),
            },
        },
        texture.size(),
    );
    queue.submit([encoder.finish()]);
    let data = map_and_copy(device, &staging, size)?;
    let mut out = Vec::with_capacity(row as usize * h as usize * layers as usize);
    for y in 0..h as usize * layers as usize {
        let start = y * padded as usize;
        out.extend_from_slice(&data[start..start + row as usize]);
    }
    Ok(out)
}

/// A rendered image, read back.
#[derive(Clone, Debug)]
pub struct Image {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Linear radiance, RGBA, row-major, row 0 at the top.
    pub radiance: Vec<[f32; 4]>,
    /// Tone-mapped sRGB, RGBA8.
    pub display: Vec<u8>,
    /// GPU milliseconds per pass of the first frame, which also ran the view-independent
    /// passes; empty without timestamp queries.
    pub first_timings: Vec<(&'static str, f64)>,
    /// GPU milliseconds per pass of the last frame; empty without timestamp queries.
    pub timings: Vec<(&'static str, f64)>,
}

impl Image {
    /// Tone-maps the radiance anew at `exposure` (a multiplier), on the CPU with the GPU's curve
    /// ([`crate::common::tonemap::tonemap`]): for an exposure known only once the frame is read
    /// back ([`crate::common::tonemap::auto_exposure_stops`]).
    pub fn retonemap(&mut self, exposure: f32) {
        self.display = tonemapped(&self.radiance, exposure);
    }

    /// An image of linear `radiance` computed on the CPU (the path tracer), tone-mapped with the
    /// GPU's curve ([`crate::common::tonemap::tonemap`]) at `exposure`; no timings.
    pub fn from_cpu(width: u32, height: u32, radiance: Vec<[f32; 4]>, exposure: f32) -> Self {
        let display = tonemapped(&radiance, exposure);
        Self {
            width,
            height,
            radiance,
            display,
            first_timings: Vec::new(),
            timings: Vec::new(),
        }
    }
}

/// `radiance` as opaque tone-mapped sRGB bytes, RGBA.
fn tonemapped(radiance: &[[f32; 4]], exposure: f32) -> Vec<u8> {
    radiance
        .iter()
        .flat_map(|c| {
            let [r, g, b] = crate::common::tonemap::tonemap([c[0], c[1], c[2]], exposure);
            [r, g, b, 255]
        })
        .collect()
}

/// An `Rgba8Unorm` target of `width` x `height` to render into, read back and sample (the
/// default target format of [`crate::RendererSettings`]; `cssm view` blits it to its window).
pub fn offscreen_target(device: &wgpu::Device, width: u32, height: u32) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some("offscreen target"),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    })
}

/// Renders `frames` (at least one) frames of `renderer` into an offscreen target and reads the
/// last back: the offscreen loop of the command line, the tests and the benchmarks. The
/// renderer must draw into `Rgba8Unorm` (the default of [`crate::RendererSettings`]).
///
/// # Errors
/// Another target format, GPU errors while rendering, a failed read-back.
pub fn render_image(renderer: &mut crate::Renderer, frames: u32) -> Result<Image, RuntimeError> {
    if renderer.target_format() != wgpu::TextureFormat::Rgba8Unorm {
        return Err(RuntimeError::Unsupported(format!(
            "offscreen images are Rgba8Unorm; this renderer draws into {:?}",
            renderer.target_format()
        )));
    }
    let (device, queue) = {
        let ctx = renderer.context();
        (ctx.device.clone(), ctx.queue.clone())
    };
    let (width, height) = renderer.context().size();
    let target = offscreen_target(&device, width, height);
    let view = target.create_view(&Default::default());
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let (mut first_timings, mut timings) = (Vec::new(), Vec::new());
    for frame in 0..frames.max(1) {
        let mut encoder = device.create_command_encoder(&Default::default());
        renderer.render(&mut encoder, &view);
        queue.submit([encoder.finish()]);
        timings = renderer.read_timings()?;
        if frame == 0 {
            first_timings = timings.clone();
        }
    }
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(RuntimeError::Gpu(e.to_string()));
    }
    let radiance = read_texture(&device, &queue, renderer.radiance(), 16)?;
    let display = read_texture(&device, &queue, &target, 4)?;
    Ok(Image {
        width,
        height,
        radiance: bytemuck::cast_slice(&radiance).to_vec(),
        display,
        first_timings,
        timings,
    })
}

/// Read-back bytes of `vec4f`s as vectors.
pub fn vec4s(bytes: &[u8]) -> Vec<glam::Vec4> {
    bytemuck::cast_slice::<u8, [f32; 4]>(bytes)
        .iter()
        .map(|&v| glam::Vec4::from(v))
        .collect()
}

/// The tone-mapped image as PNG.
///
/// # Errors
/// A display image of the wrong size, a failed encode or write; the message names `path`.
pub fn save_png(path: &Path, image: &Image) -> Result<(), String> {
    save_rgba_png(path, image.width, image.height, image.display.clone())
}

/// RGBA8 pixels of `width` x `height` as PNG.
///
/// # Errors
/// Pixels of the wrong size, a failed encode or write; the message names `path`.
pub fn save_rgba_png(path: &Path, width: u32, height: u32, rgba: Vec<u8>) -> Result<(), String> {
    let img = ::image::RgbaImage::from_raw(width, height, rgba)
        .ok_or_else(|| format!("{}: the display image has the wrong size", path.display()))?;
    save_image(path, img.into(), ::image::ImageFormat::Png)
}

/// The linear radiance as OpenEXR (32-bit float RGBA).
///
/// # Errors
/// A failed encode or write; the message names `path`.
pub fn save_exr(path: &Path, image: &Image) -> Result<(), String> {
    save_radiance_exr(path, image.width, image.height, &image.radiance)
}

/// Linear RGBA radiance of `width` x `height` as OpenEXR (32-bit float RGBA): what
/// `cssm render --exr` and `cssm view`'s EXR screenshots write.
///
/// # Errors
/// Radiance of the wrong size, a failed encode or write; the message names `path`.
pub fn save_radiance_exr(
    path: &Path,
    width: u32,
    height: u32,
    radiance: &[[f32; 4]],
) -> Result<(), String> {
    let data: Vec<f32> = radiance.iter().flatten().copied().collect();
    let img = ::image::Rgba32FImage::from_raw(width, height, data)
        .ok_or_else(|| format!("{}: the radiance image has the wrong size", path.display()))?;
    save_image(path, img.into(), ::image::ImageFormat::OpenExr)
}

/// The linear RGBA radiance of an image file (what [`save_exr`] writes) and its width and
/// height.
///
/// # Errors
/// A file that cannot be read or decoded; the message names `path`.
pub fn load_radiance(path: &Path) -> Result<(u32, u32, Vec<[f32; 4]>), String> {
    let image = ::image::open(path)
        .map_err(|e| format!("{}: {e}", path.display()))?
        .to_rgba32f();
    let (width, height) = image.dimensions();
    let radiance = image
        .as_raw()
        .chunks_exact(4)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect();
    Ok((width, height, radiance))
}

/// Encodes `image` as `format` in memory and writes it with the project's one atomic write
/// (`cssm_formats::cssm::write_bytes_atomic`): a failed write never leaves a half-written image.
fn save_image(
    path: &Path,
    image: ::image::DynamicImage,
    format: ::image::ImageFormat,
) -> Result<(), String> {
    use cssm_formats::cssm::{CssmError, write_bytes_atomic};
    let fail = |reason: String| format!("{}: {reason}", path.display());
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut bytes, format)
        .map_err(|e| fail(e.to_string()))?;
    write_bytes_atomic(path, bytes.get_ref()).map_err(|e| match e {
        // The error names the path already; keep just the cause.
        CssmError::Io { error, .. } => fail(error.to_string()),
        other => fail(other.to_string()),
    })
}
