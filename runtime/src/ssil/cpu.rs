//! CPU twins of the SSIL kernels, the same arithmetic in `f32`: the light a pixel sends
//! ([`sender_radiance`], `sender.wgsl`, with exact shadows), one level's gather for given
//! pixels ([`gather_pixel`], `gather.wgsl`), the frustum's solid voxels by ray casts through
//! the columns ([`voxelize`], `voxels.wgsl`'s XOR raster), their AND down the levels
//! ([`and_down`]) and the temporal filter of a pixel ([`temporal_pixel`], `temporal.wgsl`).
//! `tests/gpu/ssil.rs` holds them to the GPU's results on the Cornell box.

use glam::{Mat4, Vec3, Vec4, Vec4Swizzles};

use super::{FrameParams, GatherParams, SLICES};
use crate::{common::filters::upsample_weights, gpu_types::GpuMaterial};

const PI: f32 = std::f32::consts::PI;

/// Most steps of a visibility march (`gather.wgsl`: `MAX_MARCH`).
const MAX_MARCH: u32 = 256;

use crate::common::random::{hash_unit, pcg_hash};

/// `sender.wgsl`: the light the G-buffer pixel (`position`, `normal` turned towards the eye,
/// `albedo`, `emission` as the G-buffer holds them) sends to the others, its diffuse direct
/// light `albedo / pi E` under every spot light of `scene` (exact shadow rays through `bvh`
/// where the GPU looks its shadow maps up) plus the radiance it emits towards the eye (zero on
/// an emitter's back). Zero where no surface covers the pixel.
pub fn sender_radiance(
    scene: &cssm_formats::Scene,
    bvh: &cssm_raycast::SceneBvh,
    [position, normal, albedo, emission]: [Vec4; 4],
) -> Vec3 {
    use crate::direct::cpu::{ray_epsilon, spot_irradiance};
    if position.w <= 0.0 {
        return Vec3::ZERO;
    }
    let eps = ray_epsilon(scene);
    let (p, n) = (position.xyz(), normal.xyz());
    let e: Vec3 = scene
        .lights
        .iter()
        .filter_map(|l| spot_irradiance(l, bvh, eps, p, n).map(|(e, _)| e))
        .sum();
    albedo.xyz() / PI * e + emission.xyz()
}

/// What the gather of one level reads, as read back from the GPU.
pub struct GatherInputs<'a> {
    /// World to clip space.
    pub view_proj: Mat4,
    /// The eye.
    pub eye: Vec3,
    /// The frame's parameters.
    pub frame: FrameParams,
    /// The scene's materials.
    pub materials: &'a [GpuMaterial],
    /// The G-buffer pyramid's positions (levels 1 and up).
    pub position: &'a [Vec4],
    /// Its normals.
    pub normal: &'a [Vec4],
    /// The light pyramid.
    pub sender: &'a [Vec4],
    /// The solid voxels, four words per column.
    pub grid: &'a [u32],
    /// The gathered planes as they were before this level ran (the coarser levels' results).
    pub gathered: &'a [Vec4],
}

impl GatherInputs<'_> {
    fn to_level(&self, clip: Vec4, params: &GatherParams) -> glam::Vec2 {
        let ndc = clip.xy() / clip.w;
        let full = glam::Vec2::new(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5)
            * glam::Vec2::new(params.full_size[0] as f32, params.full_size[1] as f32);
        full / (1u32 << params.level) as f32
    }

    /// `gather.wgsl`: `occluded`.
    pub fn occluded(&self, a: Vec3, b: Vec3, params: &GatherParams) -> bool {
        let pa = self.to_level(self.view_proj * a.extend(1.0), params);
        let pb = self.to_level(self.view_proj * b.extend(1.0), params);
        let len = (pb - pa).length();
        let steps = len.ceil().clamp(1.0, MAX_MARCH as f32) as u32;
        for s in 1..steps {
            let t = s as f32 / steps as f32;
            if t * len < params.bias || (1.0 - t) * len < params.bias {
                continue;
            }
            let c = self.view_proj * a.lerp(b, t).extend(1.0);
            if c.w <= 0.0 {
                continue;
            }
            let px = self.to_level(c, params).floor();
            let (x, y) = (px.x as i32, px.y as i32);
            if x < 0 || y < 0 || x >= params.size[0] as i32 || y >= params.size[1] as i32 {
                continue;
            }
            let tz = (c.w - self.frame.z_near) / (self.frame.z_far - self.frame.z_near);
            if !(0.0..1.0).contains(&tz) {
                continue;
            }
            let slice = (tz * SLICES as f32) as u32;
            let column = params.grid_offset + y as u32 * params.size[0] + x as u32;
            if (self.grid[(4 * column + slice / 32) as usize] >> (slice % 32)) & 1 == 1 {
                return true;
            }
        }
        false
    }

    /// `gather.wgsl`: `sent`, the irradiance and direction of the sample at level pixel `q`.
    fn sent(
        &self,
        x: Vec3,
        n: Vec3,
        q: (i32, i32),
        dp: f32,
        params: &GatherParams,
    ) -> Option<(Vec3, Vec3)> {
        if q.0 < 0 || q.1 < 0 || q.0 >= params.size[0] as i32 || q.1 >= params.size[1] as i32 {
            return None;
        }
        let j = (params.offset + q.1 as u32 * params.size[0] + q.0 as u32) as usize;
        let s = self.position[j];
        if s.w <= 0.0 {
            return None;
        }
        let ns = self.normal[j].truncate();
        let d = s.truncate() - x;
        let r2 = d.dot(d);
        if r2 <= 1e-12 {
            return None;
        }
        let w = d / r2.sqrt();
        let (cos_r, cos_s) = (n.dot(w), -ns.dot(w));
        if cos_r <= 0.0 || cos_s <= 0.0 {
            return None;
        }
        let z = (self.view_proj * s.truncate().extend(1.0)).w;
        let to_eye = self.eye - s.truncate();
        let dist = to_eye.length();
        let cos_alpha = z / dist;
        let cos_beta = (ns.dot(to_eye) / dist).max(0.01);
        let (full_pixels, copies) = if params.sample_disc == 1 {
            (dp * (1u32 << (2 * params.level)) as f32, 1.0)
        } else {
            ((1u32 << (2 * params.level)) as f32, dp)
        };
        let ds = self.frame.pixel_area * z * z * cos_alpha / cos_beta * full_pixels;
        let f = copies * cos_r * cos_s * ds / (r2 + cos_s * ds / PI);
        if params.visibility == 1 && self.occluded(x, s.truncate(), params) {
            return None;
        }
        Some((self.sender[j].truncate() * f, w))
    }
}

/// `gather.wgsl`: `angle_density`.
fn angle_density(delta: f32, p_uniform: f32, sigma: f32) -> f32 {
    let g: f32 = (-1..=1)
        .map(|k| {
            let t = (delta + 2.0 * PI * k as f32) / sigma;
            (-0.5 * t * t).exp()
        })
        .sum();
    p_uniform / (2.0 * PI) + (1.0 - p_uniform) * g / (sigma * (2.0 * PI).sqrt())
}

fn wrap_angle(a: f32) -> f32 {
    a - 2.0 * PI * ((a + PI) / (2.0 * PI)).floor()
}

/// A sample's level pixel: the pixel centre plus `rho` along `theta`, floored.
fn sample_pixel(centre: (f32, f32), rho: f32, theta: f32) -> (i32, i32) {
    (
        (centre.0 + rho * theta.cos()).floor() as i32,
        (centre.1 + rho * theta.sin()).floor() as i32,
    )
}

/// `gather.wgsl`: `gather` at `pixel` of the level of `params`: the diffuse and the
/// lobe-weighted irradiance, the coarser level's up-sampled result included.
pub fn gather_pixel(
    inputs: &GatherInputs,
    params: &GatherParams,
    (px, py): (u32, u32),
) -> [Vec3; 2] {
    let i = (params.offset + py * params.size[0] + px) as usize;
    let x4 = inputs.position[i];
    if x4.w <= 0.0 {
        return [Vec3::ZERO; 2];
    }
    let x = x4.truncate();
    let n4 = inputs.normal[i];
    let n = n4.truncate();
    let m = inputs.materials[n4.w as usize];
    let key = pcg_hash(px ^ pcg_hash(py ^ pcg_hash(params.level ^ pcg_hash(inputs.frame.seed))));
    let rotation = hash_unit(key);
    let jitter = hash_unit(pcg_hash(key));
    let r1 = if params.disc == 1 {
        0.0
    } else {
        0.5 * params.radius
    };
    let r2 = params.radius;
    let ring = PI * (r2 * r2 - r1 * r1);
    let count = params.samples as f32;
    let centre = (px as f32 + 0.5, py as f32 + 0.5);
    let me = (px as i32, py as i32);
    let radius_of = |k: u32| {
        let u = (k as f32 * 0.618_034 + jitter).fract();
        (r1 * r1 + u * (r2 * r2 - r1 * r1)).sqrt()
    };
    let mut diffuse = Vec3::ZERO;
    for k in 0..params.samples {
        let theta = 2.0 * PI * (k as f32 + rotation) / count;
        let q = sample_pixel(centre, radius_of(k), theta);
        if q == me {
            continue;
        }
        if let Some((e, _)) = inputs.sent(x, n, q, ring / count, params) {
            diffuse += e;
        }
    }
    let mut glossy = Vec3::ZERO;
    let ks = Vec3::from(m.ks);
    if ks.max_element() > 0.0 {
        let v = (inputs.eye - x).normalize();
        let mirrored = (-v).reflect(n);
        let far = inputs.view_proj * (x + inputs.eye.distance(x) * mirrored).extend(1.0);
        let (mut theta_r, mut p_uniform) = (0.0f32, 1.0f32);
        if far.w > 1e-6 {
            let dir = inputs.to_level(far, params) - glam::Vec2::new(centre.0, centre.1);
            if dir.length() > 1e-3 {
                theta_r = dir.y.atan2(dir.x);
                let sigma_g = (PI / m.ns.max(1e-3)).sqrt();
                let m_uniform = 2.0 * PI * params.uniform_weight;
                let m_gauss = sigma_g * (2.0 * PI).sqrt();
                p_uniform = m_uniform / (m_uniform + m_gauss);
            }
        }
        let sigma = (PI / m.ns.max(1e-3)).sqrt();
        let lobe_scale = (m.ns + 2.0) / (2.0 * PI);
        let jitter_b = hash_unit(pcg_hash(key ^ 0x9e37_79b9));
        for k in 0..params.samples {
            let a = (k as f32 + rotation) / count;
            let theta = if a < p_uniform {
                theta_r + 2.0 * PI * a / p_uniform
            } else {
                let u1 = 1.0 - (a - p_uniform) / (1.0 - p_uniform);
                let u2 = (k as f32 * 0.754_878 + jitter_b).fract();
                theta_r + sigma * (-2.0 * u1.max(1e-7).ln()).sqrt() * (2.0 * PI * u2).cos()
            };
            let density = angle_density(wrap_angle(theta - theta_r), p_uniform, sigma);
            let q = sample_pixel(centre, radius_of(k), theta);
            if q == me {
                continue;
            }
            let dp = ring / (count * 2.0 * PI * density);
            if let Some((e, w)) = inputs.sent(x, n, q, dp, params) {
                let lobe = lobe_scale * mirrored.dot(w).max(0.0).powf(m.ns);
                glossy += lobe * e;
            }
        }
    }
    let mut up = [Vec4::ZERO; 2];
    if params.has_coarse == 1 {
        let (qx, qy) = (centre.0 / 2.0 - 0.5, centre.1 / 2.0 - 0.5);
        let (bx, by) = (qx.floor(), qy.floor());
        let mut indices = [0usize; 4];
        let taps = std::array::from_fn(|t| {
            let sx = (bx as i32 + (t as i32 & 1)).clamp(0, params.coarse_size[0] as i32 - 1);
            let sy = (by as i32 + (t as i32 >> 1)).clamp(0, params.coarse_size[1] as i32 - 1);
            let c = (params.coarse_offset + sy as u32 * params.coarse_size[0] + sx as u32) as usize;
            indices[t] = c;
            let p = inputs.position[c];
            (p.w > 0.0).then(|| {
                (
                    inputs.eye.distance(p.truncate()),
                    inputs.normal[c].truncate(),
                )
            })
        });
        let weights = upsample_weights(
            (inputs.eye.distance(x), n),
            taps,
            (qx - bx, qy - by),
            params.depth_sigma,
            params.normal_power,
        );
        let pixels = params.pixels as usize;
        for t in 0..4 {
            if weights[t] > 0.0 {
                up[0] += weights[t] * inputs.gathered[indices[t]];
                up[1] += weights[t] * inputs.gathered[pixels + indices[t]];
            }
        }
    }
    [diffuse + up[0].truncate(), glossy + up[1].truncate()]
}

/// Pixels of a G-buffer as senders of Eq. 3 with Eq. 4, each its own disc: the sum the gather
/// estimates at its finest level (`scale` 4^level, the level's pixels), or over the full-res
/// G-buffer (`scale` 1), the bound of any screen-space method.
pub struct ScreenSenders<'a> {
    /// Positions, w 1 where covered.
    pub position: &'a [Vec4],
    /// Normals towards the eye.
    pub normal: &'a [Vec4],
    /// The light each sends (rgb).
    pub light: &'a [Vec4],
    /// World to clip space.
    pub view_proj: Mat4,
    /// The eye.
    pub eye: Vec3,
    /// [`super::pixel_area`] of the full-res image.
    pub pixel_area: f32,
    /// Full-res pixels per sender pixel.
    pub scale: f32,
}

impl ScreenSenders<'_> {
    /// The irradiance at `x` (normal `n`) from every covered sender but `skip`: from all, and
    /// from those `visible(x, n, s, ns)` says are visible.
    pub fn irradiance(
        &self,
        x: Vec3,
        n: Vec3,
        skip: Option<usize>,
        visible: &dyn Fn(Vec3, Vec3, Vec3, Vec3) -> bool,
    ) -> (Vec3, Vec3) {
        let (mut all, mut seen) = (Vec3::ZERO, Vec3::ZERO);
        for (j, s4) in self.position.iter().enumerate() {
            if s4.w <= 0.0 || Some(j) == skip {
                continue;
            }
            let (s, ns) = (s4.truncate(), self.normal[j].truncate());
            let d = s - x;
            let r2 = d.dot(d);
            if r2 <= 1e-12 {
                continue;
            }
            let w = d / r2.sqrt();
            let (cos_r, cos_s) = (n.dot(w), -ns.dot(w));
            if cos_r <= 0.0 || cos_s <= 0.0 {
                continue;
            }
            let z = (self.view_proj * s.extend(1.0)).w;
            let to_eye = self.eye - s;
            let cos_beta = (ns.dot(to_eye) / to_eye.length()).max(0.01);
            let ds = self.scale * self.pixel_area * z * z * (z / to_eye.length()) / cos_beta;
            let e = self.light[j].truncate() * (cos_r * cos_s * ds / (r2 + cos_s * ds / PI));
            all += e;
            if visible(x, n, s, ns) {
                seen += e;
            }
        }
        (all, seen)
    }
}

/// `gather.wgsl`: `accumulate` at one pixel of the finest gathered level: the bounce's diffuse
/// and lobe-weighted irradiance added to the bounces' running sum (`None` at the first bounce),
/// and, when another bounce follows, the light the pixel sends in it, `albedo / pi` times the
/// diffuse irradiance.
pub fn accumulate(
    gathered: [Vec3; 2],
    sum: Option<[Vec3; 2]>,
    albedo: Vec3,
    next_bounce: bool,
) -> ([Vec3; 2], Option<Vec3>) {
    let total = match sum {
        Some([d, g]) => [gathered[0] + d, gathered[1] + g],
        None => gathered,
    };
    (total, next_bounce.then(|| albedo / PI * gathered[0]))
}

/// `voxels.wgsl`: `slice_of`.
fn slice_of(z: f32, (z_near, z_far): (f32, f32)) -> u32 {
    let t = (z - z_near) / (z_far - z_near);
    (t * SLICES as f32).floor().clamp(0.0, (SLICES - 1) as f32) as u32
}

/// The solid voxels of the raster level `start` over a `full`-size image of `view_proj`: per
/// column, the ray through its centre against every triangle between the near and the far
/// plane, each crossing toggling the slices from its depth on (the rasteriser's XOR, whose
/// coverage rule may differ from these ray casts on a triangle's very edge).
pub fn voxelize(
    triangles: &[[Vec3; 3]],
    view_proj: Mat4,
    full: (u32, u32),
    start: u32,
    z_range: (f32, f32),
) -> Vec<u32> {
    let scale = (1u32 << start) as f32;
    let (cw, ch) = (full.0.div_ceil(1 << start), full.1.div_ceil(1 << start));
    let inverse = view_proj.inverse();
    let mut grid = vec![0u32; (4 * cw * ch) as usize];
    for y in 0..ch {
        for x in 0..cw {
            let ndc_x = (x as f32 + 0.5) * scale / full.0 as f32 * 2.0 - 1.0;
            let ndc_y = 1.0 - (y as f32 + 0.5) * scale / full.1 as f32 * 2.0;
            let unproject = |z: f32| {
                let p = inverse * Vec4::new(ndc_x, ndc_y, z, 1.0);
                p.truncate() / p.w
            };
            let (near, far) = (unproject(0.0), unproject(1.0));
            let dir = far - near;
            let base = (4 * (y * cw + x)) as usize;
            for tri in triangles {
                let Some(t) = ray_triangle(near, dir, tri) else {
                    continue;
                };
                if !(0.0..=1.0).contains(&t) {
                    continue;
                }
                let z = (view_proj * (near + t * dir).extend(1.0)).w;
                let first = slice_of(z, z_range);
                for w in 0..4u32 {
                    grid[base + w as usize] ^= mask_from(first, w);
                }
            }
        }
    }
    grid
}

/// `voxels.wgsl`: `mask_from`.
fn mask_from(first: u32, word: u32) -> u32 {
    let start = 32 * word;
    if first <= start {
        u32::MAX
    } else if first >= start + 32 {
        0
    } else {
        !((1u32 << (first - start)) - 1)
    }
}

/// Möller-Trumbore: the ray parameter of the crossing, if the ray crosses the triangle.
fn ray_triangle(origin: Vec3, dir: Vec3, [a, b, c]: &[Vec3; 3]) -> Option<f32> {
    let (e1, e2) = (*b - *a, *c - *a);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - *a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(q) * inv)
}

/// `voxels.wgsl`: `and_down`, the next coarser level's columns of a `fine` level of `size`.
pub fn and_down(fine: &[u32], (fw, fh): (u32, u32)) -> Vec<u32> {
    let (cw, ch) = (fw.div_ceil(2), fh.div_ceil(2));
    let mut out = vec![0u32; (4 * cw * ch) as usize];
    for y in 0..ch {
        for x in 0..cw {
            let mut words = [u32::MAX; 4];
            for c in 0..4u32 {
                let (cx, cy) = (2 * x + (c & 1), 2 * y + (c >> 1));
                if cx >= fw || cy >= fh {
                    continue;
                }
                let base = (4 * (cy * fw + cx)) as usize;
                for (w, word) in words.iter_mut().enumerate() {
                    *word &= fine[base + w];
                }
            }
            let o = (4 * (y * cw + x)) as usize;
            out[o..o + 4].copy_from_slice(&words);
        }
    }
    out
}

/// The G-buffer texels and history a pixel's temporal filter reads.
pub struct TemporalInputs<'a> {
    /// This frame's eye.
    pub eye: Vec3,
    /// The previous frame's world-to-clip.
    pub previous_view_proj: Mat4,
    /// The previous frame's eye.
    pub previous_eye: Vec3,
    /// Weight of the history.
    pub blend: f32,
    /// Image size.
    pub size: (u32, u32),
    /// The materials.
    pub materials: &'a [GpuMaterial],
    /// This frame's G-buffer positions and normals.
    pub position: &'a [Vec4],
    /// Normals (w material).
    pub normal: &'a [Vec4],
    /// The previous frame's.
    pub history_position: &'a [Vec4],
    /// The previous frame's normals.
    pub history_normal: &'a [Vec4],
    /// This frame's two planes.
    pub current: &'a [Vec4],
    /// The previous frame's blended planes.
    pub history: &'a [Vec4],
}

/// `temporal.wgsl`: the blended diffuse and lobe-weighted values of pixel `(x, y)`.
pub fn temporal_pixel(inputs: &TemporalInputs, (x, y): (u32, u32)) -> [Vec4; 2] {
    let (w, h) = inputs.size;
    let plane = (w * h) as usize;
    let i = (y * w + x) as usize;
    let (mut diffuse, mut glossy) = (inputs.current[i], inputs.current[plane + i]);
    let p = inputs.position[i];
    if p.w <= 0.0 {
        return [diffuse, glossy];
    }
    let clip = inputs.previous_view_proj * p.truncate().extend(1.0);
    if clip.w <= 0.0 {
        return [diffuse, glossy];
    }
    let ndc = clip.xy() / clip.w;
    let ax = ((ndc.x * 0.5 + 0.5) * w as f32).floor() as i32;
    let ay = ((0.5 - ndc.y * 0.5) * h as f32).floor() as i32;
    if ax < 0 || ay < 0 || ax >= w as i32 || ay >= h as i32 {
        return [diffuse, glossy];
    }
    let hi = (ay as u32 * w + ax as u32) as usize;
    let hp = inputs.history_position[hi];
    let n4 = inputs.normal[i];
    let tolerance = 0.02 * inputs.eye.distance(p.truncate());
    let same = hp.w > 0.0
        && hp.truncate().distance(p.truncate()) <= tolerance
        && inputs.history_normal[hi].truncate().dot(n4.truncate()) >= 0.9;
    if same {
        let a = inputs.blend;
        diffuse = diffuse.lerp(inputs.history[hi], a);
        let m = inputs.materials[n4.w as usize];
        let now = (inputs.eye - p.truncate()).normalize();
        let before = (inputs.previous_eye - p.truncate()).normalize();
        let angle = now.dot(before).clamp(-1.0, 1.0).acos();
        let lobe = 0.5f32.powf(1.0 / m.ns.max(1e-3)).acos();
        let a_glossy = a * (1.0 - angle / lobe.max(1e-4)).max(0.0);
        glossy = glossy.lerp(inputs.history[plane + hi], a_glossy);
    }
    [diffuse, glossy]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masks_cover_the_slices_from_the_first_on() {
        assert_eq!(mask_from(0, 0), u32::MAX);
        assert_eq!(mask_from(1, 0), u32::MAX - 1);
        assert_eq!(mask_from(31, 0), 1 << 31);
        assert_eq!(mask_from(32, 0), 0);
        assert_eq!(mask_from(40, 1), !0xff);
        assert_eq!(mask_from(127, 3), 1 << 31);
        // Two crossings leave the slices between them set: a closed object's inside.
        let inside: Vec<u32> = (0..4)
            .map(|w| mask_from(10, w) ^ mask_from(70, w))
            .collect();
        assert_eq!(inside, vec![!0x3ff, u32::MAX, 0x3f, 0]);
    }

    /// A closed box in front of the eye fills the slices between its front and back faces,
    /// and the AND of a column with an empty neighbour is empty.
    #[test]
    fn a_closed_box_is_solid_between_its_faces() {
        let corners: Vec<Vec3> = (0..8)
            .map(|c| {
                Vec3::new(
                    if c & 1 == 0 { -0.5 } else { 0.5 },
                    if c & 2 == 0 { -0.5 } else { 0.5 },
                    if c & 4 == 0 { -3.0 } else { -2.0 },
                )
            })
            .collect();
        let quads = [
            [0, 1, 3, 2],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 3, 7, 5],
        ];
        let triangles: Vec<[Vec3; 3]> = quads
            .iter()
            .flat_map(|q| {
                [
                    [corners[q[0]], corners[q[1]], corners[q[2]]],
                    [corners[q[0]], corners[q[2]], corners[q[3]]],
                ]
            })
            .collect();
        let proj = glam::camera::rh::proj::directx::perspective(60f32.to_radians(), 1.0, 0.1, 10.0);
        let view_proj =
            proj * glam::camera::rh::view::look_at_mat4(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y);
        let range = (1.0, 5.0);
        let grid = voxelize(&triangles, view_proj, (16, 16), 1, range);
        // The centre column (4, 4) of 8x8: solid from depth 2 to 3, slices 32 to 63.
        let base = 4 * (4 * 8 + 4);
        assert_eq!(&grid[base..base + 4], &[0, u32::MAX, 0, 0]);
        // A corner column misses the box.
        assert_eq!(&grid[0..4], &[0; 4]);
        let coarse = and_down(&grid, (8, 8));
        assert_eq!(coarse.len(), 4 * 16);
        // Coarse column (2, 2): the AND of fine columns (4..6, 4..6); (5, 4) leaves the box
        // through its side before the back face, so only the slices all four share remain.
        let word = |x: usize, y: usize| grid[4 * (y * 8 + x) + 1];
        let shared = word(4, 4) & word(5, 4) & word(4, 5) & word(5, 5);
        assert!(shared != 0 && shared != u32::MAX, "{shared:x}");
        assert_eq!(
            &coarse[4 * (2 * 4 + 2)..4 * (2 * 4 + 2) + 4],
            &[0, shared, 0, 0]
        );
        assert_eq!(&coarse[0..4], &[0; 4]);
    }
}
