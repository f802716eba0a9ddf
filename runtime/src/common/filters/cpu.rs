//! The CPU twins of the filters ([`blur`], [`upsample`]), doing the GPU's arithmetic in `f32`
//! on a G-buffer read back ([`CpuGuide`]), and the weights they share with `bilateral.wgsl`
//! ([`bilateral_weight`], [`upsample_weights`]), which other techniques' twins use too.

use glam::{Vec3, Vec4};

use super::{FilterOptions, low_size, representative};

/// A low-res guide on the CPU: per low-res pixel, row-major, position (w 1 where covered) and
/// normal.
pub type LowRows = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// The G-buffer on the CPU, the guide of the CPU twins: full-res rows of the position
/// (xyz, w 1 where covered) and normal (xyz) targets, and the eye.
#[derive(Clone, Debug)]
pub struct CpuGuide {
    /// Full-res width.
    pub width: u32,
    /// Full-res height.
    pub height: u32,
    /// Per pixel xyz world position, w 1 where covered (`GBuffer::position`).
    pub position: Vec<[f32; 4]>,
    /// Per pixel xyz unit normal (`GBuffer::normal`).
    pub normal: Vec<[f32; 4]>,
    /// Eye position (`View::eye`).
    pub eye: Vec3,
    /// The low-res guide when the filter reads it from buffers
    /// ([`LowGuide::Buffers`](super::LowGuide::Buffers)): per low-res pixel, row-major,
    /// position (w 1 where covered) and normal; `None` for the G-buffer at each low-res
    /// pixel's [`representative`].
    pub low: Option<LowRows>,
}

/// `filters.wgsl`: `Guide`.
pub(super) struct Guide {
    pub(super) covered: bool,
    distance: f32,
    normal: Vec3,
}

impl Guide {
    /// What [`bilateral_weight`] compares: distance from the eye and normal.
    fn key(&self) -> (f32, Vec3) {
        (self.distance, self.normal)
    }
}

impl CpuGuide {
    pub(super) fn at(&self, (x, y): (u32, u32)) -> Guide {
        let i = (y * self.width + x) as usize;
        let p = self.position[i];
        Guide {
            covered: p[3] > 0.0,
            distance: self.eye.distance(Vec3::new(p[0], p[1], p[2])),
            normal: Vec4::from(self.normal[i]).truncate(),
        }
    }

    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// `filters.wgsl`: `low_guide_at`.
    fn low_at(&self, low: (u32, u32), factor: u32) -> Guide {
        match &self.low {
            None => self.at(representative(low, factor, self.size())),
            Some((position, normal)) => {
                let (lw, _) = low_size(self.size(), factor);
                let i = (low.1 * lw + low.0) as usize;
                let p = position[i];
                Guide {
                    covered: p[3] > 0.0,
                    distance: self.eye.distance(Vec3::new(p[0], p[1], p[2])),
                    normal: Vec4::from(normal[i]).truncate(),
                }
            }
        }
    }
}

/// `filters.wgsl`: `range_weight`, the depth and normal weight of `tap` against `centre`.
fn range_weight(centre: &Guide, tap: &Guide, options: &FilterOptions) -> f32 {
    bilateral_weight(
        centre.key(),
        tap.key(),
        options.depth_sigma,
        options.normal_power,
    )
}

/// `bilateral.wgsl`: `bilateral_weight`, the depth and normal weight of a tap (distance from
/// the eye, normal) against a centre whose distance is the reference; 0 for normals facing
/// apart.
pub fn bilateral_weight(
    (centre_distance, centre_normal): (f32, Vec3),
    (tap_distance, tap_normal): (f32, Vec3),
    depth_sigma: f32,
    normal_power: f32,
) -> f32 {
    let r = (tap_distance - centre_distance) / (depth_sigma * centre_distance.max(1e-6));
    let c = centre_normal.dot(tap_normal);
    if c <= 0.0 {
        return 0.0;
    }
    (-r * r).exp() * c.powf(normal_power)
}

/// `filters.wgsl`: `blur`, one pass along `axis`.
fn blur_pass(
    input: &[Vec4],
    layers: u32,
    guide: &CpuGuide,
    options: &FilterOptions,
    axis: (i32, i32),
) -> Vec<Vec4> {
    let (lw, lh) = low_size(guide.size(), options.factor);
    let plane = (lw * lh) as usize;
    let mut out = vec![Vec4::ZERO; plane * layers as usize];
    let radius = options.radius as i32;
    let s = options.spatial_sigma;
    for y in 0..lh {
        for x in 0..lw {
            let centre_index = (y * lw + x) as usize;
            let centre = guide.low_at((x, y), options.factor);
            if !centre.covered {
                continue;
            }
            let mut taps = Vec::with_capacity(2 * radius as usize + 1);
            for k in -radius..=radius {
                let (tx, ty) = (x as i32 + k * axis.0, y as i32 + k * axis.1);
                if tx < 0 || ty < 0 || tx >= lw as i32 || ty >= lh as i32 {
                    continue;
                }
                let (tx, ty) = (tx as u32, ty as u32);
                let tap = guide.low_at((tx, ty), options.factor);
                if !tap.covered {
                    continue;
                }
                let spatial = (-((k * k) as f32) / (2.0 * s * s)).exp();
                let w = spatial * range_weight(&centre, &tap, options);
                if w > 0.0 {
                    taps.push((w, (ty * lw + tx) as usize));
                }
            }
            for l in 0..layers as usize {
                let (mut sum, mut total) = (Vec4::ZERO, 0.0f32);
                for &(w, i) in &taps {
                    sum += w * input[l * plane + i];
                    total += w;
                }
                out[l * plane + centre_index] = sum / total;
            }
        }
    }
    out
}

/// CPU twin of the GPU blur (`blur_x`, then `blur_y`): `layers` low-res planes in, the same
/// out. Radius 0 returns the input unchanged (the GPU skips the blur).
///
/// # Panics
/// An `input` shorter than `layers` planes of the guide's low-res size.
pub fn blur(input: &[Vec4], layers: u32, guide: &CpuGuide, options: &FilterOptions) -> Vec<Vec4> {
    let (lw, lh) = low_size(guide.size(), options.factor);
    assert!(
        input.len() >= (lw * lh * layers) as usize,
        "blur: short input"
    );
    if options.radius == 0 {
        return input[..(lw * lh * layers) as usize].to_vec();
    }
    let scratch = blur_pass(input, layers, guide, options, (1, 0));
    blur_pass(&scratch, layers, guide, options, (0, 1))
}

/// CPU twin of the GPU up-sampling (`upsample`): `layers` low-res planes in, full-res planes
/// out.
///
/// # Panics
/// A `low` shorter than `layers` planes of the guide's low-res size.
pub fn upsample(low: &[Vec4], layers: u32, guide: &CpuGuide, options: &FilterOptions) -> Vec<Vec4> {
    let full = guide.size();
    let (lw, lh) = low_size(full, options.factor);
    assert!(
        low.len() >= (lw * lh * layers) as usize,
        "upsample: short input"
    );
    let (low_plane, full_plane) = ((lw * lh) as usize, (full.0 * full.1) as usize);
    let mut out = vec![Vec4::ZERO; full_plane * layers as usize];
    for y in 0..full.1 {
        for x in 0..full.0 {
            let pixel_index = (y * full.0 + x) as usize;
            let pixel = guide.at((x, y));
            if !pixel.covered {
                continue;
            }
            let f = options.factor as f32;
            let (qx, qy) = ((x as f32 + 0.5) / f - 0.5, (y as f32 + 0.5) / f - 0.5);
            let (bx, by) = (qx.floor(), qy.floor());
            let mut indices = [0usize; 4];
            let taps: [Guide; 4] = std::array::from_fn(|i| {
                let (ox, oy) = (i as i32 & 1, i as i32 >> 1);
                let sx = (bx as i32 + ox).clamp(0, lw as i32 - 1) as u32;
                let sy = (by as i32 + oy).clamp(0, lh as i32 - 1) as u32;
                indices[i] = (sy * lw + sx) as usize;
                guide.low_at((sx, sy), options.factor)
            });
            let weights = upsample_weights(
                pixel.key(),
                taps.map(|t| t.covered.then(|| t.key())),
                (qx - bx, qy - by),
                options.depth_sigma,
                options.normal_power,
            );
            for l in 0..layers as usize {
                let mut value = Vec4::ZERO;
                for i in 0..4 {
                    if weights[i] > 0.0 {
                        value += weights[i] * low[l * low_plane + indices[i]];
                    }
                }
                out[l * full_plane + pixel_index] = value;
            }
        }
    }
    out
}

/// `bilateral.wgsl`: `upsample_weights`, joint bilateral up-sampling from the 2x2 low-res taps
/// around a pixel (in the order (0,0), (1,0), (0,1), (1,1); `None` where uncovered), `t` the
/// pixel's fractional position between them: bilinear weights times [`bilateral_weight`]
/// against the pixel's (distance, normal), normalised; when every tap is rejected, weight 1 on
/// the covered tap nearest in distance; all 0 when none is covered.
pub fn upsample_weights(
    pixel: (f32, Vec3),
    taps: [Option<(f32, Vec3)>; 4],
    (tx, ty): (f32, f32),
    depth_sigma: f32,
    normal_power: f32,
) -> [f32; 4] {
    let mut weights = [0.0f32; 4];
    let mut total = 0.0f32;
    let mut nearest: Option<(usize, f32)> = None;
    for (i, tap) in taps.iter().enumerate() {
        let Some(tap) = *tap else { continue };
        let gap = (tap.0 - pixel.0).abs();
        if nearest.is_none_or(|(_, g)| gap < g) {
            nearest = Some((i, gap));
        }
        let wx = if i & 1 == 1 { tx } else { 1.0 - tx };
        let wy = if i >> 1 == 1 { ty } else { 1.0 - ty };
        weights[i] = wx * wy * bilateral_weight(pixel, tap, depth_sigma, normal_power);
        total += weights[i];
    }
    if total >= 1e-6 {
        return weights.map(|w| w / total);
    }
    let mut fallback = [0.0; 4];
    if let Some((i, _)) = nearest {
        fallback[i] = 1.0;
    }
    fallback
}
