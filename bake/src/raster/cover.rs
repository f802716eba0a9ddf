//! The conservative cover of one triangle on one cube face (the `raster` module's documentation
//! says why it holds every pixel the watertight test may report as a hit): the triangle seen
//! from the cube's centre with its margin ([`Triangle`]), clipped to the face's widened frustum
//! ([`Polygon`]), projected, and spanned row by row ([`Edge`], [`band_span`]).

use cssm_formats::cube;
use glam::{DVec3, Vec3};

/// One triangle seen from one cube centre.
pub(super) struct Triangle {
    pub(super) index: u32,
    /// Corners relative to the centre, in `f32` exactly as [`WatertightRay::intersect`] computes
    /// them.
    ///
    /// [`WatertightRay::intersect`]: crate::raycast::WatertightRay::intersect
    pub(super) rel: [[f32; 3]; 3],
    /// Widening of its cover in face coordinates (see the `raster` module's documentation);
    /// `None` when it comes so close to the centre that the cover is every pixel.
    pub(super) margin: Option<f64>,
}

/// How far the watertight test's rounding may move a triangle's corners, for coordinates up to
/// `magnitude`: its inputs are `corner - origin` rounded to `f32` (half an ulp), then sheared and
/// crossed in `f32`; a few ulps of the magnitude, and 64 of them to be safe.
pub(super) fn corner_slack(magnitude: f32) -> f64 {
    64.0 * f64::from(f32::EPSILON) * f64::from(magnitude)
}

impl Triangle {
    pub(super) fn new(index: u32, corners: &[Vec3; 3], centre: Vec3) -> Self {
        let rel = corners.map(|c| (c - centre).to_array());
        let magnitude = corners
            .iter()
            .map(|c| c.abs().max_element())
            .fold(centre.abs().max_element(), f32::max);
        // A lower bound of the distance from the centre to the triangle: to its bounding box.
        let lo = corners
            .iter()
            .fold(DVec3::INFINITY, |m, c| m.min(c.as_dvec3()));
        let hi = corners
            .iter()
            .fold(DVec3::NEG_INFINITY, |m, c| m.max(c.as_dvec3()));
        let p = centre.as_dvec3();
        let distance = (lo - p).max(p - hi).max(DVec3::ZERO).length();
        // A corner moved by `slack` shifts the projection of a point at depth `z` by at most
        // `slack * (1 + |u| + |v|) / z`; every point of the triangle within the widened frustum
        // has `z >= distance / 2` (its direction's length is at most `sqrt(1 + 2 * 1.5^2)`
        // times its depth). Plus 1e-5 for the rounding of the directions binned into cells.
        let slack = corner_slack(magnitude);
        let margin = 1e-5 + 4.0 * slack / (distance / 2.0);
        Self {
            index,
            rel,
            margin: (distance > 0.0 && margin < 0.25).then_some(margin),
        }
    }

    /// The triangle's corners as `(u-axis, v-axis, depth)` coordinates of face `face`.
    pub(super) fn face_corners(&self, face: u32) -> [[f64; 3]; 3] {
        let (major, ua, va) = cube::face_axes(face);
        let sign = f64::from(cube::face_sign(face));
        self.rel.map(|r| {
            [
                f64::from(r[ua]),
                f64::from(r[va]),
                sign * f64::from(r[major]),
            ]
        })
    }
}

/// A convex polygon of at most 7 corners (a triangle clipped by four planes).
#[derive(Clone, Copy)]
pub(super) struct Polygon {
    pub(super) points: [[f64; 3]; 8],
    pub(super) len: usize,
}

impl Polygon {
    /// Keeps the part where `a * u + b * v + c * depth >= 0` (Sutherland–Hodgman).
    pub(super) fn clip(&self, a: f64, b: f64, c: f64) -> Polygon {
        let mut out = Polygon {
            points: [[0.0; 3]; 8],
            len: 0,
        };
        let side = |p: &[f64; 3]| a * p[0] + b * p[1] + c * p[2];
        for i in 0..self.len {
            let (p, q) = (self.points[i], self.points[(i + 1) % self.len]);
            let (sp, sq) = (side(&p), side(&q));
            if sp >= 0.0 {
                out.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                let s = sp / (sp - sq);
                out.push([
                    p[0] + s * (q[0] - p[0]),
                    p[1] + s * (q[1] - p[1]),
                    p[2] + s * (q[2] - p[2]),
                ]);
            }
        }
        out
    }

    fn push(&mut self, p: [f64; 3]) {
        if self.len < self.points.len() {
            self.points[self.len] = p;
            self.len += 1;
        }
    }
}

/// An edge of a projected polygon, lower end first, for [`band_span`].
#[derive(Clone, Copy, Default)]
pub(super) struct Edge {
    /// `v` and `u` at the lower end.
    v0: f64,
    u0: f64,
    /// `v` and `u` at the upper end.
    v1: f64,
    u1: f64,
    /// `du / dv` (0 for a horizontal edge).
    slope: f64,
}

impl Edge {
    pub(super) fn new(p: [f64; 2], q: [f64; 2]) -> Edge {
        let (p, q) = if p[1] <= q[1] { (p, q) } else { (q, p) };
        let dv = q[1] - p[1];
        Edge {
            v0: p[1],
            u0: p[0],
            v1: q[1],
            u1: q[0],
            slope: if dv > 0.0 { (q[0] - p[0]) / dv } else { 0.0 },
        }
    }
}

/// Range of `u` over the convex polygon of `edges` within `v in [lo, hi]`, if it reaches that
/// band: the extremes lie on the edges' parts inside the band. (Rounding here is some 1e-15;
/// the cover is widened by at least 1e-5.)
pub(super) fn band_span(edges: &[Edge], lo: f64, hi: f64) -> Option<(f64, f64)> {
    let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
    for e in edges {
        if e.v1 < lo || e.v0 > hi {
            continue;
        }
        let (ua, ub) = if e.v1 == e.v0 {
            (e.u0, e.u1)
        } else {
            (
                e.u0 + (lo.max(e.v0) - e.v0) * e.slope,
                e.u0 + (hi.min(e.v1) - e.v0) * e.slope,
            )
        };
        min = min.min(ua.min(ub));
        max = max.max(ua.max(ub));
    }
    (min <= max).then_some((min, max))
}
