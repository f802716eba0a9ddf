//! The watertight ray/triangle test of Woop, Benthin and Wald: one ray at a time
//! ([`WatertightRay`]) and many rays from one origin sharing their axes ([`SharedAxisRays`]).
//! Every renderer of the bake's cube maps (the BVH, the bake's rasteriser, the GPU's
//! `bvh_trace.wgsl`) decides hits with this arithmetic, so that their outputs agree bit for bit.

use glam::Vec3;

/// Per-ray constants of the watertight ray/triangle test of Woop, Benthin and Wald (JCGT 2013).
/// Möller–Trumbore (obvhs' `Triangle::intersect`) lets rays through the edge shared by two
/// triangles escape both, which would punch holes through walls at the quads' diagonals.
///
/// Public so that every renderer of the bake's cube maps (the BVH here, the bake's per-texel
/// rasteriser) decides hits with the very same arithmetic: their outputs must agree bit for bit.
/// So must the GPU's (`bvh_trace.wgsl`), which is why the test stays in `f32` throughout: the
/// paper recomputes the edge functions in double precision when one of them is exactly zero,
/// and WGSL has no `f64`. Without it a ray whose edge function rounds to zero counts as on that
/// edge, and so hits the triangles on both sides of it: still watertight, and the same on every
/// device that rounds as IEEE `f32` does. A ray in the triangle's plane (to within rounding)
/// misses it, as the paper's `det == 0` case does.
///
/// ```
/// use cssm_raycast::WatertightRay;
/// use glam::Vec3;
/// let ray = WatertightRay::new(Vec3::ZERO, Vec3::Z);
/// let tri = [Vec3::new(-1.0, -1.0, 2.0), Vec3::new(1.0, -1.0, 2.0), Vec3::new(0.0, 1.0, 2.0)];
/// assert_eq!(ray.intersect(&tri), 2.0);
/// assert!(ray.intersect(&tri.map(|p| p + Vec3::X * 5.0)).is_infinite());
/// ```
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    origin: Vec3,
    // Bytes, not `usize`: a renderer keeps a table of these, one per pixel.
    kx: u8,
    ky: u8,
    kz: u8,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl WatertightRay {
    /// The ray `origin + t * dir`. A negative zero component of `dir` counts as a positive one
    /// (as it does for the BVH's traversal, which needs it so).
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        let dir = dir + Vec3::ZERO;
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        let d = dir.to_array();
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Self {
            origin,
            kx: kx as u8,
            ky: ky as u8,
            kz: kz as u8,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }

    /// The same ray from another origin (the per-ray constants depend on the direction only).
    pub fn with_origin(self, origin: Vec3) -> Self {
        Self { origin, ..self }
    }

    /// The ray's origin.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// Ray parameter of the hit with `tri`, `INFINITY` for a miss. Points on a shared edge hit
    /// both triangles (the caller merges equal distances).
    #[inline]
    pub fn intersect(&self, tri: &[Vec3; 3]) -> f32 {
        let o = self.origin;
        self.intersect_relative(&[
            (tri[0] - o).to_array(),
            (tri[1] - o).to_array(),
            (tri[2] - o).to_array(),
        ])
    }

    /// [`WatertightRay::intersect`] with the corners already relative to the origin
    /// (`corner - origin`, computed in `f32` exactly so): a renderer that tests one triangle
    /// against many rays from one origin subtracts once. The ray's own origin is not used.
    #[inline]
    pub fn intersect_relative(&self, rel: &[[f32; 3]; 3]) -> f32 {
        self.test(rel, self.axes())
    }

    /// The ray's axes `(kx, ky, kz)`: [`WatertightRay::intersect_permuted`] takes the corners'
    /// coordinates in this order.
    pub fn axes(&self) -> [usize; 3] {
        [self.kx as usize, self.ky as usize, self.kz as usize]
    }

    /// [`WatertightRay::intersect_relative`] with each corner's coordinates already in the order
    /// of [`WatertightRay::axes`]: a renderer whose rays share their axes (the pixels of one cube
    /// face) reorders a triangle once.
    #[inline]
    pub fn intersect_permuted(&self, rel: &[[f32; 3]; 3]) -> f32 {
        self.test(rel, [0, 1, 2])
    }

    /// The test itself, reading coordinate `axes[i]` of each corner as the ray's axis `i`: every
    /// form above is this one arithmetic, with the corners read in place (`axes` the ray's own)
    /// or already reordered (`[0, 1, 2]`, constant indices once inlined).
    #[inline(always)]
    fn test(&self, rel: &[[f32; 3]; 3], axes: [usize; 3]) -> f32 {
        let (sx, sy, sz) = (self.sx, self.sy, self.sz);
        let seen = sheared(rel, axes, sx, sy);
        // No double-precision fallback on an exact zero (the type's documentation says why).
        let [u, v, w] = edge_functions(seen);
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return f32::INFINITY;
        }
        let det = u + v + w;
        if det == 0.0 || seen_edge_on(seen, det) {
            return f32::INFINITY;
        }
        let t = distance_numerator(rel, axes, sz, [u, v, w]) / det;
        if t.is_finite() { t } else { f32::INFINITY }
    }
}

/// The corners relative to the ray's origin, sheared so that the ray runs along the third axis:
/// `[ax, ay, bx, by, cx, cy]`.
#[inline(always)]
fn sheared(rel: &[[f32; 3]; 3], axes: [usize; 3], sx: f32, sy: f32) -> [f32; 6] {
    let [a, b, c] = rel;
    let [kx, ky, kz] = axes;
    [
        a[kx] - sx * a[kz],
        a[ky] - sy * a[kz],
        b[kx] - sx * b[kz],
        b[ky] - sy * b[kz],
        c[kx] - sx * c[kz],
        c[ky] - sy * c[kz],
    ]
}

/// The scaled barycentric coordinates `[u, v, w]` of the ray's point in the sheared triangle.
#[inline(always)]
fn edge_functions([ax, ay, bx, by, cx, cy]: [f32; 6]) -> [f32; 3] {
    [cx * by - cy * bx, ax * cy - ay * cx, bx * ay - by * ax]
}

/// How thin, as twice its area over the square of its corners' largest offset from the ray, a
/// triangle's view along the ray may be before the ray counts as running in its plane.
const EDGE_ON: f32 = 1.0 / 65536.0;

/// Whether the ray runs in the triangle's plane, to within `f32`'s rounding: the triangle seen
/// along it (`sheared`, whose doubled signed area is `det`) is a sliver at most [`EDGE_ON`] as
/// wide as it is long. Its edge functions are then rounding noise, which may come out exactly
/// zero or of one sign and make a "hit" at a meaningless distance (a ray grazing a box's top
/// at exactly its height, as turned cube maps cast them). A miss, as for `det == 0`. Powers of
/// two and `max` only, so every device computes it alike (`seen_edge_on` in `bvh_trace.wgsl`).
#[inline(always)]
fn seen_edge_on([ax, ay, bx, by, cx, cy]: [f32; 6], det: f32) -> bool {
    let reach = ax
        .abs()
        .max(ay.abs())
        .max(bx.abs())
        .max(by.abs())
        .max(cx.abs())
        .max(cy.abs());
    det.abs() <= reach * reach * EDGE_ON
}

/// `t * det`: the hit's distance weighted by the barycentric coordinates.
#[inline(always)]
fn distance_numerator(rel: &[[f32; 3]; 3], axes: [usize; 3], sz: f32, [u, v, w]: [f32; 3]) -> f32 {
    let [a, b, c] = rel;
    let kz = axes[2];
    u * sz * a[kz] + v * sz * b[kz] + w * sz * c[kz]
}

/// Many rays from one origin sharing their axes ([`WatertightRay::axes`]), say the centre rays
/// of one cube face, laid out for testing one triangle against a run of them at once:
/// [`SharedAxisRays::intersect_permuted`] is [`WatertightRay::intersect_permuted`] for each, with
/// the same arithmetic, in lanes the compiler can vectorise.
///
/// ```
/// use cssm_raycast::{SharedAxisRays, WatertightRay};
/// use glam::Vec3;
/// let rays: Vec<_> = (0..8)
///     .map(|i| WatertightRay::new(Vec3::ZERO, Vec3::new(i as f32 * 0.1 - 0.4, 0.05, 1.0)))
///     .collect();
/// let shared = SharedAxisRays::new(&rays);
/// let tri = [[-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [0.0, 1.0, 3.0f32]];
/// let axes = rays[0].axes();
/// let permuted = tri.map(|p| axes.map(|k| p[k]));
/// let mut t = [0.0; 8];
/// shared.intersect_permuted(0..8, &permuted, &mut t);
/// for (ray, t) in rays.iter().zip(t) {
///     assert_eq!(t.to_bits(), ray.intersect_permuted(&permuted).to_bits());
/// }
/// ```
#[derive(Clone, Debug, Default)]
pub struct SharedAxisRays {
    sx: Vec<f32>,
    sy: Vec<f32>,
    sz: Vec<f32>,
}

impl SharedAxisRays {
    /// The per-ray constants of `rays` (their origins are not used).
    pub fn new(rays: &[WatertightRay]) -> Self {
        Self {
            sx: rays.iter().map(|r| r.sx).collect(),
            sy: rays.iter().map(|r| r.sy).collect(),
            sz: rays.iter().map(|r| r.sz).collect(),
        }
    }

    /// Number of rays.
    pub fn len(&self) -> usize {
        self.sx.len()
    }

    /// True when there is no ray.
    pub fn is_empty(&self) -> bool {
        self.sx.is_empty()
    }

    /// Writes into `out[i]` the hit of ray `range.start + i` with the triangle whose corners
    /// are `rel` (relative to the origin, coordinates in the rays' axes' order), exactly as
    /// [`WatertightRay::intersect_permuted`] gives it, bit for bit.
    #[inline]
    pub fn intersect_permuted(
        &self,
        range: std::ops::Range<usize>,
        rel: &[[f32; 3]; 3],
        out: &mut [f32],
    ) {
        const AXES: [usize; 3] = [0, 1, 2];
        let out = &mut out[..range.len()];
        let (sx, sy, sz) = (
            &self.sx[range.clone()],
            &self.sy[range.clone()],
            &self.sz[range],
        );
        // The edge-on test's reach, bounded for every ray at once: a sheared coordinate is
        // `a[kx] - sx * a[kz]` with `|sx| <= 1` (the ray's major axis is `kz`), so its magnitude
        // is at most `|a[kx]| + |a[kz]|`, rounding included. A lane whose `det` clears the bound's
        // threshold is not edge-on; the few that do not are decided below, exactly.
        let bound = rel.iter().fold(0.0f32, |m, p| {
            m.max(p[0].abs() + p[2].abs()).max(p[1].abs() + p[2].abs())
        });
        let loose = bound * bound * EDGE_ON;
        for (((t_out, &sx), &sy), &sz) in out.iter_mut().zip(sx).zip(sy).zip(sz) {
            // `WatertightRay::test` without its branches: the same operations in the same
            // order, each outcome selected afterwards.
            let [u, v, w] = edge_functions(sheared(rel, AXES, sx, sy));
            let outside = ((u < 0.0) | (v < 0.0) | (w < 0.0)) & ((u > 0.0) | (v > 0.0) | (w > 0.0));
            let det = u + v + w;
            let t = distance_numerator(rel, AXES, sz, [u, v, w]) / det;
            let miss = outside | (det == 0.0) | !t.is_finite();
            let unsure = det.abs() <= loose;
            *t_out = if miss {
                f32::INFINITY
            } else if unsure {
                f32::NAN
            } else {
                t
            };
        }
        for (((t_out, &sx), &sy), &sz) in out.iter_mut().zip(sx).zip(sy).zip(sz) {
            if t_out.is_nan() {
                let seen = sheared(rel, AXES, sx, sy);
                let [u, v, w] = edge_functions(seen);
                let det = u + v + w;
                *t_out = if seen_edge_on(seen, det) {
                    f32::INFINITY
                } else {
                    distance_numerator(rel, AXES, sz, [u, v, w]) / det
                };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ray in a triangle's plane misses it, whatever rounding makes of its edge functions, in
    /// its own test and in [`SharedAxisRays`]' lanes:
    /// triangles and rays exactly in an oblique plane, `x + y + z = k` (every coordinate a
    /// multiple of 1/64, so the plane holds them exactly in `f32`), as turned cube maps cast
    /// horizontal rays along a box's top.
    #[test]
    fn rays_in_a_triangles_plane_miss_it() {
        let mut rng = crate::SplitMix64(5);
        let mut grid =
            |range: f64| ((rng.next_f64() * 2.0 - 1.0) * range * 64.0).round() as f32 / 64.0;
        let (mut tested, mut rounded) = (0, 0);
        for _ in 0..4000 {
            let k = grid(300.0);
            let mut point = || {
                let (x, y) = (grid(300.0), grid(300.0));
                Vec3::new(x, y, k - x - y)
            };
            let tri = [point(), point(), point()];
            let origin = point();
            // Inside the triangle, exactly: a division by a power of two.
            let inside = (tri[0] + tri[1] + tri[2] * 2.0) / 4.0;
            let ray = WatertightRay::new(origin, inside - origin);
            let rel = tri.map(|p| (p - origin).to_array());
            let [u, v, w] = edge_functions(sheared(&rel, ray.axes(), ray.sx, ray.sy));
            let one_sign =
                [u, v, w].iter().all(|&e| e >= 0.0) || [u, v, w].iter().all(|&e| e <= 0.0);
            rounded += usize::from(one_sign && u + v + w != 0.0);
            tested += 1;
            assert!(ray.intersect(&tri).is_infinite(), "{tri:?} from {origin}");
            // The rasteriser's lanes too.
            let mut lane = [0.0];
            let permuted = rel.map(|p| ray.axes().map(|k| p[k]));
            SharedAxisRays::new(&[ray]).intersect_permuted(0..1, &permuted, &mut lane);
            assert!(lane[0].is_infinite(), "{tri:?} from {origin}, in a lane");
        }
        // Without the edge-on test, rounding alone would have let these through.
        assert!(rounded > 10, "{rounded} of {tested}");
    }

    /// Whether `ray` meets the triangle `rel` (corners in its axes' order) on an edge: an edge
    /// function exactly zero.
    fn on_an_edge(ray: &WatertightRay, rel: &[[f32; 3]; 3]) -> bool {
        let [u, v, w] = edge_functions(sheared(rel, [0, 1, 2], ray.sx, ray.sy));
        u == 0.0 || v == 0.0 || w == 0.0
    }

    /// The lanes of [`SharedAxisRays`] give each ray's own answer bit for bit; rays aimed at
    /// corners and along edges of triangles on a coarse grid make exact zeros of the edge
    /// functions (hits on an edge), exact hits and exact misses common.
    #[test]
    fn shared_axis_rays_answer_as_each_ray() {
        let mut rng = crate::SplitMix64(11);
        let mut grid = |scale: f64| ((rng.next_f64() * 8.0).floor() - 4.0) as f32 * scale as f32;
        let (mut edges, mut hits, mut total) = (0, 0, 0);
        for face in 0..6usize {
            // Directions around one axis, so the rays share their axes.
            let (major, sign) = (face / 2, if face % 2 == 0 { 1.0 } else { -1.0 });
            let rays: Vec<WatertightRay> = (0..64)
                .map(|i| {
                    let mut d = [0.0f32; 3];
                    d[major] = sign;
                    d[(major + 1) % 3] = ((i % 8) as f32 - 3.5) / 5.0;
                    d[(major + 2) % 3] = ((i / 8) as f32 - 4.0) / 5.0;
                    WatertightRay::new(Vec3::ZERO, Vec3::from_array(d))
                })
                .collect();
            let axes = rays[0].axes();
            assert!(rays.iter().all(|r| r.axes() == axes));
            let lanes = SharedAxisRays::new(&rays);
            let mut out = vec![0.0; rays.len()];
            for _ in 0..400 {
                // Corners on a grid of quarter units at depth 1 to 4 along the face's axis,
                // so rays through corners and edges occur.
                let tri: [[f32; 3]; 3] = std::array::from_fn(|_| {
                    let mut p = [0.0f32; 3];
                    p[major] = sign * (2.5 + grid(0.5)).max(0.5);
                    p[(major + 1) % 3] = grid(0.25);
                    p[(major + 2) % 3] = grid(0.25);
                    p
                });
                let permuted = tri.map(|p| axes.map(|k| p[k]));
                let (start, end) = (3, 3 + 7 + (total % 50));
                lanes.intersect_permuted(start..end, &permuted, &mut out);
                for (ray, &t) in rays[start..end].iter().zip(&out) {
                    let expected = ray.intersect_permuted(&permuted);
                    total += 1;
                    assert_eq!(t.to_bits(), expected.to_bits(), "{tri:?}");
                    hits += usize::from(t.is_finite());
                    edges += usize::from(t.is_finite() && on_an_edge(ray, &permuted));
                }
            }
        }
        assert!(
            edges > 100 && hits > 1000 && hits < total,
            "{edges} hits on an edge, {hits} hits, {total} tests"
        );
    }
}
