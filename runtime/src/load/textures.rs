//! A scene's albedo, emission and normal-map textures, decoded, resampled to one size and
//! stacked as the layers of one texture array.

use super::*;

/// Side of the square textures on the GPU: every `map_Kd` and `map_Ke` is resampled to it so
/// that all fit one texture array.
pub const TEXTURE_SIZE: u32 = 512;

/// A texture (albedo or emission) resampled to [`TEXTURE_SIZE`], linear RGB (the CPU
/// references sample it).
#[derive(Clone, Debug)]
pub struct AlbedoTexture {
    /// Row-major texels, linear RGB.
    pub texels: Vec<[f32; 3]>,
}

impl AlbedoTexture {
    /// Bilinear sample with repeat wrapping at texture coordinates `uv` (v up, as in OBJ), the
    /// same filter `albedo_sample` in `common/albedo.wgsl` applies.
    pub fn sample(&self, uv: [f32; 2]) -> Vec3 {
        let s = TEXTURE_SIZE as f32;
        let x = uv[0] * s - 0.5;
        let y = (1.0 - uv[1]) * s - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: f32, yi: f32| {
            let n = TEXTURE_SIZE as i64;
            let (xi, yi) = ((xi as i64).rem_euclid(n), (yi as i64).rem_euclid(n));
            Vec3::from(self.texels[(yi * n + xi) as usize])
        };
        at(x0, y0) * (1.0 - fx) * (1.0 - fy)
            + at(x0 + 1.0, y0) * fx * (1.0 - fy)
            + at(x0, y0 + 1.0) * (1.0 - fx) * fy
            + at(x0 + 1.0, y0 + 1.0) * fx * fy
    }

    /// Mean of the texels, linear RGB (the texture's mean over its area, which bilinear
    /// filtering with repeat wrapping keeps).
    pub fn mean(&self) -> [f32; 3] {
        let sum = self
            .texels
            .iter()
            .fold(glam::DVec3::ZERO, |acc, t| acc + Vec3::from(*t).as_dvec3());
        (sum / self.texels.len().max(1) as f64).as_vec3().to_array()
    }
}

/// A material's layers in the texture array, -1 for none.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TextureLayers {
    /// Albedo texture (`map_Kd`, glTF `baseColorTexture`).
    pub albedo: i32,
    /// Emission texture (`map_Ke`, glTF `emissiveTexture`).
    pub emission: i32,
    /// Tangent-space normals (MTL `norm`, glTF `normalTexture`, or MTL `bump` turned into
    /// normals; [`crate::normal_map`]).
    pub normal: i32,
}

/// How an image becomes a layer: the same image may be two layers (an albedo texture used as
/// a height map too, or a height map at two multipliers).
#[derive(Clone, Copy, Debug, PartialEq)]
enum LayerKind {
    /// sRGB colours decoded to linear (albedo, emission).
    Colour,
    /// A height map turned into normals at this bump multiplier.
    Height(f32),
    /// A tangent-space normal map at this scale.
    Normal(f32),
}

/// Reads every material's textures (albedo: `map_Kd`, glTF `baseColorTexture`; emission:
/// `map_Ke`, glTF `emissiveTexture`; normals: `Material::normal_map`), each image once per way
/// it is read, resampled to [`TEXTURE_SIZE`]; returns the textures (one array for all kinds,
/// normals as unit vectors, see [`crate::normal_map`]) and each material's layers.
///
/// # Errors
/// [`RuntimeError::Texture`] for an image that cannot be read, naming its file.
pub fn load_textures(
    scene: &Scene,
) -> Result<(Vec<AlbedoTexture>, Vec<TextureLayers>), RuntimeError> {
    use cssm_formats::NormalMapKind;
    let mut textures = Vec::new();
    let mut sources: Vec<(&TextureSource, LayerKind)> = Vec::new();
    let mut layers = Vec::with_capacity(scene.materials.len());
    for m in &scene.materials {
        let normal = m.normal_map.as_ref().map(|n| {
            let kind = match n.kind {
                NormalMapKind::Height { multiplier } => LayerKind::Height(multiplier),
                NormalMapKind::Tangent { scale } => LayerKind::Normal(scale),
            };
            (&n.source, kind)
        });
        let wanted = [
            m.map_kd.as_ref().map(|s| (s, LayerKind::Colour)),
            m.map_emission.as_ref().map(|s| (s, LayerKind::Colour)),
            normal,
        ];
        let mut layer = [-1i32; 3];
        for (slot, wanted) in layer.iter_mut().zip(wanted) {
            let Some((source, kind)) = wanted else {
                continue;
            };
            *slot = match sources.iter().position(|s| *s == (source, kind)) {
                Some(i) => i as i32,
                None => {
                    let texels = match kind {
                        LayerKind::Colour => decode_texture(source)?,
                        LayerKind::Height(multiplier) => {
                            let grey: Vec<f32> = decode_image(source, "bump map")?
                                .iter()
                                .map(|c| (c[0] + c[1] + c[2]) / 3.0)
                                .collect();
                            crate::normal_map::height_to_normals(&grey, multiplier)
                        }
                        LayerKind::Normal(scale) => crate::normal_map::decode_normals(
                            &decode_image(source, "normal map")?,
                            scale,
                        ),
                    };
                    sources.push((source, kind));
                    textures.push(AlbedoTexture { texels });
                    textures.len() as i32 - 1
                }
            };
        }
        layers.push(TextureLayers {
            albedo: layer[0],
            emission: layer[1],
            normal: layer[2],
        });
    }
    Ok((textures, layers))
}

/// Decodes the image of `source` and resamples it to [`TEXTURE_SIZE`]² texels, linear RGB
/// (the image is sRGB-encoded, as `map_Kd` and `map_Ke` files and glTF colour and emissive
/// textures are).
///
/// # Errors
/// [`RuntimeError::Texture`] naming the file (or the scene file that embeds the image) when it
/// cannot be read or decoded.
pub fn decode_texture(source: &TextureSource) -> Result<Vec<[f32; 3]>, RuntimeError> {
    // Linear before resampling: an sRGB-space filter darkens every edge between light and dark
    // (a stripe of sRGB 255 and 0 resampled there keeps a linear mean of 0.36, not 0.5), and the
    // atlas takes a texture by its mean (`GpuMaterial::kd_mean`).
    resampled(source, "", srgb_to_linear)
}

/// Decodes the image of `source` and resamples it to [`TEXTURE_SIZE`]² texels, each channel
/// as stored, in `[0, 1]` (no transfer function: height and normal maps hold values, not
/// colours). `what` ("normal map", ...; empty for a colour texture) prefixes the reason of an
/// error.
///
/// # Errors
/// [`RuntimeError::Texture`] naming the file (or the scene file that embeds the image) when it
/// cannot be read or decoded.
pub fn decode_image(source: &TextureSource, what: &str) -> Result<Vec<[f32; 3]>, RuntimeError> {
    resampled(source, what, |c| c)
}

/// The image of `source`, each channel in `[0, 1]` through `transfer`, then resampled to
/// [`TEXTURE_SIZE`]² texels (16 bits per channel while resampling).
fn resampled(
    source: &TextureSource,
    what: &str,
    transfer: fn(f32) -> f32,
) -> Result<Vec<[f32; 3]>, RuntimeError> {
    let texture_error = |reason: String| {
        let reason = if what.is_empty() {
            reason
        } else {
            format!("{what}: {reason}")
        };
        RuntimeError::Texture {
            path: source.origin().to_path_buf(),
            reason: match source {
                TextureSource::File(_) => reason,
                TextureSource::Embedded { label, .. } => format!("{label}: {reason}"),
            },
        }
    };
    // Decoded within image's default limits (512 MiB of allocation).
    let img = match source {
        TextureSource::File(path) => {
            // A regular file only (a FIFO would hang the decoder's open).
            let (file, _) = cssm_formats::files::open_regular(path)
                .map_err(|e| texture_error(e.to_string()))?;
            // The format from the extension, as `image::open` does; from the contents otherwise.
            let mut reader = image::ImageReader::new(std::io::BufReader::new(file));
            match image::ImageFormat::from_path(path) {
                Ok(format) => reader.set_format(format),
                Err(_) => {
                    reader = reader
                        .with_guessed_format()
                        .map_err(|e| texture_error(e.to_string()))?;
                }
            }
            reader.decode()
        }
        TextureSource::Embedded { bytes, mime, .. } => {
            let mut reader = image::ImageReader::new(std::io::Cursor::new(&bytes[..]));
            match mime.as_deref().and_then(image::ImageFormat::from_mime_type) {
                Some(format) => reader.set_format(format),
                None => {
                    reader = reader
                        .with_guessed_format()
                        .map_err(|e| texture_error(e.to_string()))?;
                }
            }
            reader.decode()
        }
    }
    .map_err(|e| texture_error(e.to_string()))?;
    let table: Vec<u16> = (0..=255u8)
        .map(|c| (transfer(f32::from(c) / 255.0).clamp(0.0, 1.0) * 65535.0).round() as u16)
        .collect();
    let wide = reduced_wide(&img, &table);
    drop(img);
    let resized = image::imageops::resize(
        &wide,
        TEXTURE_SIZE,
        TEXTURE_SIZE,
        image::imageops::FilterType::Triangle,
    );
    Ok(resized
        .pixels()
        .map(|p| p.0.map(|c| f32::from(c) / 65535.0))
        .collect())
}

/// A side above which an image is first reduced by whole box factors ([`reduced_wide`]).
const REDUCE_ABOVE: u32 = 2 * TEXTURE_SIZE;

/// `img` through `table` (8-bit channel to 16-bit value) as 16-bit RGB. An image wider or
/// taller than [`REDUCE_ABOVE`] is reduced on the way by whole factors that keep it at least
/// that size, averaging each box after the table (so in linear space), a stripe of rows at a
/// time: a 23000² texture costs its decode and a few megabytes, not two full-size copies.
fn reduced_wide(
    img: &image::DynamicImage,
    table: &[u16],
) -> image::ImageBuffer<image::Rgb<u16>, Vec<u16>> {
    use image::GenericImageView;
    let (w, h) = img.dimensions();
    let (kx, ky) = ((w / REDUCE_ABOVE).max(1), (h / REDUCE_ABOVE).max(1));
    if kx == 1 && ky == 1 {
        let rgb = img.to_rgb8();
        return image::ImageBuffer::from_fn(w, h, |x, y| {
            image::Rgb(rgb.get_pixel(x, y).0.map(|c| table[c as usize]))
        });
    }
    let (nw, nh) = (w.div_ceil(kx), h.div_ceil(ky));
    let mut sums = vec![[0u64; 3]; nw as usize * nh as usize];
    let mut counts = vec![0u32; nw as usize * nh as usize];
    for row in 0..nh {
        let y0 = row * ky;
        let stripe = img.crop_imm(0, y0, w, ky.min(h - y0)).to_rgb8();
        for (x, _, p) in stripe.enumerate_pixels() {
            let i = (row * nw + x / kx) as usize;
            for (sum, c) in sums[i].iter_mut().zip(p.0) {
                *sum += u64::from(table[c as usize]);
            }
            counts[i] += 1;
        }
    }
    image::ImageBuffer::from_fn(nw, nh, |x, y| {
        let i = (y * nw + x) as usize;
        let n = u64::from(counts[i].max(1));
        image::Rgb(sums[i].map(|s| ((s + n / 2) / n) as u16))
    })
}

/// The sRGB transfer function, inverted.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A texture far larger than the renderer's is reduced in linear space, a stripe at a
    /// time, to the mean the full-size path gives (issue 53, class 5).
    #[test]
    fn a_huge_texture_is_reduced_in_stripes_to_the_same_linear_mean() {
        // A checkerboard of sRGB 255 and 64: its linear mean is the mean of the two linear
        // values (averaging in sRGB first would give a darker one).
        let (w, h) = (3 * REDUCE_ABOVE + 5, REDUCE_ABOVE + 3);
        let img = image::RgbImage::from_fn(w, h, |x, y| {
            image::Rgb(if (x + y) % 2 == 0 { [255; 3] } else { [64; 3] })
        });
        let table: Vec<u16> = (0..=255u8)
            .map(|c| (srgb_to_linear(f32::from(c) / 255.0) * 65535.0).round() as u16)
            .collect();
        let reduced = reduced_wide(&image::DynamicImage::ImageRgb8(img), &table);
        assert_eq!(reduced.dimensions(), (w.div_ceil(3), h));
        let mean = |v: &[u16]| v.iter().map(|&c| f64::from(c)).sum::<f64>() / v.len() as f64;
        let expected = 0.5 * (f64::from(table[255]) + f64::from(table[64]));
        assert!(
            (mean(reduced.as_raw()) - expected).abs() < 0.01 * expected,
            "{} vs {expected}",
            mean(reduced.as_raw())
        );
    }

    /// A textured material reflects in the atlas Kd times its texture's linear mean (the
    /// G-buffer and the path tracer see Kd times the texture); an untextured one its Kd.
    #[test]
    fn the_atlas_albedo_of_a_textured_material_is_kd_times_the_texture_mean() {
        let dir = tempfile::tempdir().unwrap();
        // Half the pixels sRGB 255 (linear 1), half sRGB 0: a linear mean of one half.
        let mut stripes = image::RgbImage::new(4, 4);
        for (x, _, p) in stripes.enumerate_pixels_mut() {
            *p = image::Rgb(if x % 2 == 0 { [255; 3] } else { [0; 3] });
        }
        stripes.save(dir.path().join("stripes.png")).unwrap();
        std::fs::write(
            dir.path().join("quad.mtl"),
            "newmtl tex\nKd 0.8 0.6 0.4\nmap_Kd stripes.png\nnewmtl plain\nKd 0.5 0.5 0.5\n",
        )
        .unwrap();
        std::fs::write(
            dir.path().join("quad.obj"),
            "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n\
             vt 0 1\nusemtl tex\nf 1/1 2/2 3/3\nusemtl plain\nf 1/1 3/3 4/4\n",
        )
        .unwrap();
        let scene = Scene::load(dir.path()).unwrap();
        let (materials, _) = cpu_materials(&scene).unwrap();
        let by_name = |name: &str| {
            let i = scene.materials.iter().position(|m| m.name == name).unwrap();
            materials[i]
        };
        let textured = by_name("tex");
        assert_eq!(textured.kd, [0.8, 0.6, 0.4], "the G-buffer's Kd stays");
        for (mean, kd) in textured.kd_mean.iter().zip([0.8, 0.6, 0.4]) {
            assert!((mean - 0.5 * kd).abs() < 1e-6, "{:?}", textured.kd_mean);
        }
        assert_eq!(by_name("plain").kd_mean, [0.5; 3]);
    }
}
