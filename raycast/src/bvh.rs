//! Exact ray casting against the scene with obvhs: the reference for every visibility answer,
//! and the tool the bake renders the depth cube maps with (§3.2.1).

use std::time::Duration;

use cssm_formats::Scene;
use glam::{UVec2, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    cwbvh::{CwBvh, builder::build_cwbvh},
    ray::Ray,
    traverse,
    triangle::Triangle,
};

/// Widening of every triangle's box in the BVH, relative to the scene's largest coordinate: some
/// thousand times the rounding of a ray/box test.
const BOX_PAD: f32 = 1.0 / 16384.0;

/// A BVH over the scene's triangles.
pub struct SceneBvh {
    bvh: CwBvh,
    /// Triangle corners in BVH primitive order (so no indirection while traversing).
    triangles: Vec<[Vec3; 3]>,
    /// Geometric normal (not normalised; its winding side is the front) of every triangle, by
    /// scene index.
    normals: Vec<Vec3>,
    /// Largest absolute coordinate of any corner.
    magnitude: f32,
}

/// First and second intersection along a ray (dual depth layers, §3.2 after Weiskopf and Ertl).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DualHit {
    /// Ray parameter of the first hit, `INFINITY` if none.
    pub first: f32,
    /// Ray parameter of the next hit at least `separation` beyond the first, `INFINITY` if none.
    pub second: f32,
}

/// Result of [`SceneBvh::front_dual_hit`]: the first hit, whether it faces the ray's origin, and
/// the nearest hit beyond it that does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrontHit {
    /// Ray parameter of the first hit, `INFINITY` if none.
    pub first: f32,
    /// Whether the first hit's surface faces the origin (any of the triangles within
    /// `separation` of it does).
    pub first_faces: bool,
    /// Ray parameter of the nearest front-facing hit at least `separation` beyond the first,
    /// `INFINITY` if none.
    pub second: f32,
}

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

/// Hits farther than this many beyond the first may still join the first surface's cluster in
/// [`HitReducer`] without overflowing it (a ray through a vertex meets every triangle around it).
const CLUSTER: usize = 3;

/// Reduces the hits of one ray, met in *any* order, to its first hit, whether the first surface
/// faces the origin and the second hit: exactly [`reduce_hits`] over the same hits, streamed.
///
/// The answer must not depend on the order the hits arrive in: the BVH meets them in its
/// traversal's order, the bake's rasteriser triangle by triangle, and both must write the same
/// cube maps. Hits within `separation` of the first are one surface (a ray through a shared
/// edge meets both triangles at one `t`), but which hits those are is only known once the first
/// is: so the reducer keeps every hit within `separation` of the current first (up to
/// three of them; more sets [`HitReducer::overflowed`] and the caller reduces the full
/// list with [`reduce_hits`]), and re-sorts them when a nearer first arrives.
///
/// ```
/// use cssm_raycast::{HitReducer, reduce_hits};
/// let hits = [(3.0, true), (1.0, false), (1.0005, true), (2.0, false)];
/// let mut r = HitReducer::default();
/// for &(t, faces) in hits.iter().rev() {
///     r.add(t, faces, 1e-3);
/// }
/// let expected = reduce_hits(&hits, 1e-3);
/// assert_eq!((r.first(), r.first_faces(), r.second()), (1.0, true, 3.0));
/// assert_eq!(r.hit(), expected);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct HitReducer {
    first: f32,
    second: f32,
    /// Other hits within the separation of `first`.
    cluster: [f32; CLUSTER],
    /// Bit `i` for `cluster[i]` facing the origin, bit `CLUSTER` for `first`.
    faces: u8,
    len: u8,
    overflowed: bool,
}

impl Default for HitReducer {
    fn default() -> Self {
        Self {
            first: f32::INFINITY,
            second: f32::INFINITY,
            cluster: [f32::INFINITY; CLUSTER],
            faces: 0,
            len: 0,
            overflowed: false,
        }
    }
}

/// `t` lies more than `separation` beyond `first`: another surface. Monotone in `first`, so a
/// hit beyond the first stays beyond it when a nearer first arrives.
#[inline]
fn beyond(t: f32, first: f32, separation: f32) -> bool {
    t - first > separation
}

impl HitReducer {
    /// Adds the hit at ray parameter `t` (ignored unless `0 < t <` [`HitReducer::second`]: a
    /// hit at or beyond the second can change nothing) whose surface faces the origin when
    /// `faces` (pass `true` for every hit to take the second hit whichever way it faces).
    #[inline]
    pub fn add(&mut self, t: f32, faces: bool, separation: f32) {
        if !(t > 0.0 && t < self.second) {
            return;
        }
        // The common cases inline (the first hit, or one beyond it), the re-sort out of line.
        if self.first == f32::INFINITY {
            self.first = t;
            self.faces = u8::from(faces) << CLUSTER;
            return;
        }
        if t < self.first {
            self.nearer_first(t, faces, separation);
        } else if !beyond(t, self.first, separation) {
            self.push(t, faces);
        } else if faces {
            self.second = t;
        }
    }

    /// [`HitReducer::add`] of a hit nearer than the first: the old first and its cluster are
    /// sorted again around the new one.
    #[inline(never)]
    fn nearer_first(&mut self, t: f32, faces: bool, separation: f32) {
        let old = (self.first, self.faces & (1 << CLUSTER) != 0);
        let old_cluster = self.cluster;
        let old_faces = self.faces;
        let old_len = self.len as usize;
        self.first = t;
        self.faces = u8::from(faces) << CLUSTER;
        self.len = 0;
        let members = old_cluster[..old_len]
            .iter()
            .enumerate()
            .map(|(i, &m)| (m, old_faces & (1 << i) != 0))
            .chain(std::iter::once(old).filter(|&(m, _)| m.is_finite()));
        for (m, m_faces) in members {
            if beyond(m, t, separation) {
                if m_faces && m < self.second {
                    self.second = m;
                }
            } else {
                self.push(m, m_faces);
            }
        }
    }

    #[inline]
    fn push(&mut self, t: f32, faces: bool) {
        let i = self.len as usize;
        if i == CLUSTER {
            self.overflowed = true;
            return;
        }
        self.cluster[i] = t;
        self.faces |= u8::from(faces) << i;
        self.len += 1;
    }

    /// Ray parameter of the first hit, `INFINITY` if none.
    pub fn first(&self) -> f32 {
        self.first
    }

    /// Whether any hit within the separation of the first faces the origin.
    pub fn first_faces(&self) -> bool {
        self.faces != 0
    }

    /// Ray parameter of the nearest facing hit more than the separation beyond the first,
    /// `INFINITY` if none. Also the bound beyond which no hit matters any more (a traversal's
    /// `tmax`).
    pub fn second(&self) -> f32 {
        self.second
    }

    /// More hits than the reducer keeps fell within the separation of the first: its answer
    /// may be wrong, reduce the ray's full hit list with [`reduce_hits`] instead.
    pub fn overflowed(&self) -> bool {
        self.overflowed
    }

    /// The answer as a [`FrontHit`].
    pub fn hit(&self) -> FrontHit {
        FrontHit {
            first: self.first,
            first_faces: self.first_faces(),
            second: self.second,
        }
    }
}

/// The definition [`HitReducer`] streams: over the hits `(t, faces)` with `0 < t < INFINITY`,
/// `first` is the nearest, `first_faces` whether any hit within `separation` of it faces the
/// origin, and `second` the nearest facing hit more than `separation` beyond the first.
/// Independent of the hits' order.
pub fn reduce_hits(hits: &[(f32, bool)], separation: f32) -> FrontHit {
    let valid = || hits.iter().filter(|&&(t, _)| t > 0.0 && t < f32::INFINITY);
    let first = valid().map(|&(t, _)| t).fold(f32::INFINITY, f32::min);
    let first_faces = valid().any(|&(t, f)| f && !beyond(t, first, separation));
    let second = valid()
        .filter(|&&(t, f)| f && beyond(t, first, separation))
        .map(|&(t, _)| t)
        .fold(f32::INFINITY, f32::min);
    FrontHit {
        first,
        first_faces,
        second,
    }
}

/// The scene's triangles as obvhs builds BVHs from them, in the scene's order.
pub fn scene_triangles(scene: &Scene) -> Vec<Triangle> {
    (0..scene.triangles.len())
        .map(|t| {
            let [a, b, c] = scene.triangle(t);
            Triangle {
                v0: a.into(),
                v1: b.into(),
                v2: c.into(),
            }
        })
        .collect()
}

impl SceneBvh {
    /// Builds the BVH (deterministic for a given scene).
    pub fn new(scene: &Scene) -> Self {
        let tris = scene_triangles(scene);
        let magnitude = scene
            .positions
            .iter()
            .map(|p| p.abs().max_element())
            .fold(0.0, f32::max);
        // Every triangle's box is widened a little: obvhs' box test rounds, and a ray that
        // grazes a box (through the edge a block's two side faces share, exactly on the box's
        // corner) may miss it although the watertight test hits the triangle inside. The
        // widening is far beyond that rounding, so the traversal meets every hit the test
        // reports, as testing every triangle would (the bake's rasteriser does, and its cube
        // maps must be the same).
        let pad = Vec3A::splat(BOX_PAD * magnitude.max(f32::MIN_POSITIVE)); // `box_padding`
        let boxes: Vec<Aabb> = tris
            .iter()
            .map(|t| {
                let b = t.aabb();
                Aabb::new(b.min - pad, b.max + pad)
            })
            .collect();
        let bvh = build_cwbvh(
            &boxes,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let triangles = bvh
            .primitive_indices
            .iter()
            .map(|&i| {
                let t = tris[i as usize];
                [t.v0.into(), t.v1.into(), t.v2.into()]
            })
            .collect();
        let normals = (0..scene.triangles.len())
            .map(|t| {
                let [a, b, c] = scene.triangle(t);
                (b - a).cross(c - a)
            })
            .collect();
        Self {
            bvh,
            triangles,
            normals,
            magnitude,
        }
    }

    /// Traverses the ray `origin + t * dir`, `t` in `(tmin, tmax)`, calling `on_hit(t, triangle)`
    /// for every triangle hit (watertight test) inside the current range, with the scene's index
    /// of the triangle; `on_hit` returns the new upper bound, which prunes the rest of the
    /// traversal.
    fn for_each_hit(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        mut on_hit: impl FnMut(f32, u32) -> f32,
    ) {
        // A negative zero component (`-Vec3::Z`) sends obvhs' traversal into the wrong octant
        // and every hit is missed; adding zero turns -0.0 into +0.0 and changes nothing else.
        let dir = dir + Vec3::ZERO;
        let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), tmin, tmax);
        let mut traverse_ray = ray;
        let mut state = self.bvh.new_traversal(ray.direction);
        let mut node;
        let wt = WatertightRay::new(origin, dir);
        traverse!(
            self.bvh,
            node,
            state,
            node.intersect_ray(&traverse_ray, state.oct_inv4),
            {
                let t = wt.intersect(&self.triangles[state.primitive_id as usize]);
                if t > tmin && t < traverse_ray.tmax {
                    let triangle = self.bvh.primitive_indices[state.primitive_id as usize];
                    traverse_ray.tmax = on_hit(t, triangle);
                }
            }
        );
    }

    /// Closest hit parameter along `origin + t * dir` for `t` in `(tmin, tmax)`, if any.
    pub fn closest(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<f32> {
        self.closest_hit(origin, dir, tmin, tmax).map(|(t, _)| t)
    }

    /// Closest hit along `origin + t * dir` for `t` in `(tmin, tmax)`: its parameter and the
    /// scene's index of the triangle hit.
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<(f32, u32)> {
        let mut best = None;
        self.for_each_hit(origin, dir, tmin, tmax, |t, triangle| {
            best = Some((t, triangle));
            t
        });
        best
    }

    /// True when the open segment from `a` to `b` hits nothing.
    pub fn segment_clear(&self, a: Vec3, b: Vec3) -> bool {
        let d = b - a;
        self.closest(a, d, 1e-5, 1.0 - 1e-5).is_none()
    }

    /// First and second hit of `origin + t * dir`, `t > 0`; hits within `separation` of the
    /// first count as the first (a ray through a shared edge meets both triangles at one `t`),
    /// and the second is the nearest hit more than `separation` beyond the first
    /// ([`reduce_hits`] with every hit facing). One traversal, pruned beyond the second.
    pub fn dual_hit(&self, origin: Vec3, dir: Vec3, separation: f32) -> DualHit {
        self.dual_hit_beyond(origin, dir, 0.0, separation)
    }

    /// [`SceneBvh::dual_hit`] over the hits with `t > tmin` only.
    pub fn dual_hit_beyond(&self, origin: Vec3, dir: Vec3, tmin: f32, separation: f32) -> DualHit {
        let hit = self.reduce(origin, dir, tmin, separation, |_| true);
        DualHit {
            first: hit.first,
            second: hit.second,
        }
    }

    /// Like [`SceneBvh::dual_hit`], but the second hit is the nearest *front-facing* one (its
    /// triangle's front side towards the ray's origin) beyond the first. Back-facing surfaces
    /// between the two (the far side of a wall, of a column, of the teapot) are skipped: a
    /// point on them faces away from the origin, so it can exchange no light with it (its
    /// cosine is zero) and whether it is visible never matters. The result also says whether the
    /// first hit faces the origin (any triangle within `separation` of it does).
    pub fn front_dual_hit(&self, origin: Vec3, dir: Vec3, separation: f32) -> FrontHit {
        self.front_dual_hit_beyond(origin, dir, 0.0, separation)
    }

    /// [`SceneBvh::front_dual_hit`] over the hits with `t > tmin` only.
    pub fn front_dual_hit_beyond(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        separation: f32,
    ) -> FrontHit {
        self.reduce(origin, dir, tmin, separation, |triangle| {
            self.normals[triangle as usize].dot(dir) < 0.0
        })
    }

    /// Largest absolute coordinate of the scene's corners: what the watertight test's rounding
    /// scales with.
    pub fn magnitude(&self) -> f32 {
        self.magnitude
    }

    /// How far every triangle's box in the BVH is widened on each side (a fraction of
    /// [`SceneBvh::magnitude`]): another BVH over the same triangles (the bake's on the GPU)
    /// widens its boxes as much, so that its traversal too meets every hit the watertight test
    /// reports.
    pub fn box_padding(&self) -> f32 {
        BOX_PAD * self.magnitude.max(f32::MIN_POSITIVE)
    }

    /// The scene's triangles (corners in the scene's order) and their geometric normals, by
    /// scene index: what a renderer needs to meet the same hits as this BVH.
    pub fn triangles_by_scene_index(&self) -> (Vec<[Vec3; 3]>, &[Vec3]) {
        let mut tris = vec![[Vec3::ZERO; 3]; self.triangles.len()];
        for (slot, &i) in self.bvh.primitive_indices.iter().enumerate() {
            tris[i as usize] = self.triangles[slot];
        }
        (tris, &self.normals)
    }

    /// [`HitReducer`] over the ray's hits, `faces` telling which triangles face the origin; the
    /// full hit list through [`reduce_hits`] when the reducer overflows.
    fn reduce(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        separation: f32,
        faces: impl Fn(u32) -> bool,
    ) -> FrontHit {
        let mut reducer = HitReducer::default();
        self.for_each_hit(origin, dir, tmin, f32::INFINITY, |t, triangle| {
            reducer.add(t, faces(triangle), separation);
            reducer.second()
        });
        if !reducer.overflowed() {
            return reducer.hit();
        }
        let mut hits = Vec::new();
        self.for_each_hit(origin, dir, tmin, f32::INFINITY, |t, triangle| {
            hits.push((t, faces(triangle)));
            f32::INFINITY
        });
        reduce_hits(&hits, separation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_planes() -> Scene {
        // Two parallel quads at z = 1 and z = 3.
        let positions = vec![
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(1.0, -1.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(-1.0, 1.0, 1.0),
            Vec3::new(-1.0, -1.0, 3.0),
            Vec3::new(1.0, -1.0, 3.0),
            Vec3::new(1.0, 1.0, 3.0),
            Vec3::new(-1.0, 1.0, 3.0),
        ];
        cssm_formats::Scene::from_triangles(
            positions,
            vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]],
        )
    }

    #[test]
    fn dual_hit_finds_both_layers_even_through_a_shared_edge() {
        let bvh = SceneBvh::new(&two_planes());
        let h = bvh.dual_hit(Vec3::new(0.3, 0.2, 0.0), Vec3::Z, 1e-3);
        assert!(
            (h.first - 1.0).abs() < 1e-5 && (h.second - 3.0).abs() < 1e-5,
            "{h:?}"
        );
        // Through the diagonal shared by both triangles of each quad.
        let h = bvh.dual_hit(Vec3::new(0.25, 0.25, 0.0), Vec3::Z, 1e-3);
        assert!(
            (h.first - 1.0).abs() < 1e-5 && (h.second - 3.0).abs() < 1e-5,
            "{h:?}"
        );
        let h = bvh.dual_hit(Vec3::new(0.0, 0.0, 2.0), Vec3::Z, 1e-3);
        assert!(
            (h.first - 1.0).abs() < 1e-5 && h.second.is_infinite(),
            "{h:?}"
        );
        let h = bvh.dual_hit(Vec3::new(5.0, 0.0, 0.0), Vec3::Z, 1e-3);
        assert!(h.first.is_infinite() && h.second.is_infinite());
        assert!(!bvh.segment_clear(Vec3::ZERO, Vec3::new(0.0, 0.0, 2.0)));
        assert!(bvh.segment_clear(Vec3::new(0.0, 0.0, 1.5), Vec3::new(0.0, 0.0, 2.5)));
    }

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

    /// A slab (front face at z = 1 facing -z, back face at z = 1.2 facing +z) and a wall at
    /// z = 3 facing -z, all unit quads around the z axis.
    fn slab_and_wall() -> Scene {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for (z, faces_minus_z) in [(1.0, true), (1.2, false), (3.0, true)] {
            let base = positions.len() as u32;
            for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                positions.push(Vec3::new(x, y, z));
            }
            // Counter-clockwise seen from +z is a +z normal.
            if faces_minus_z {
                triangles.extend([[base, base + 2, base + 1], [base, base + 3, base + 2]]);
            } else {
                triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
            }
        }
        cssm_formats::Scene::from_triangles(positions, triangles)
    }

    #[test]
    fn front_dual_hit_skips_surfaces_facing_away() {
        let bvh = SceneBvh::new(&slab_and_wall());
        let near = |a: f32, b: f32| (a - b).abs() < 1e-5;
        // From below: the slab's front, then its back (facing away), then the wall.
        let any = bvh.dual_hit(Vec3::new(0.3, 0.2, 0.0), Vec3::Z, 1e-3);
        assert!(near(any.first, 1.0) && near(any.second, 1.2), "{any:?}");
        let facing = bvh.front_dual_hit(Vec3::new(0.3, 0.2, 0.0), Vec3::Z, 1e-3);
        assert!(
            near(facing.first, 1.0) && near(facing.second, 3.0) && facing.first_faces,
            "{facing:?}"
        );
        // Through the quads' shared diagonal, the same.
        let facing = bvh.front_dual_hit(Vec3::new(0.25, 0.25, 0.0), Vec3::Z, 1e-3);
        assert!(
            near(facing.first, 1.0) && near(facing.second, 3.0),
            "{facing:?}"
        );
        // From above: the wall's back comes first (whatever it faces, the first hit is the
        // first), then the slab's back face, which faces this origin.
        let down = bvh.front_dual_hit(Vec3::new(0.3, 0.2, 5.0), -Vec3::Z, 1e-3);
        assert!(
            near(down.first, 2.0) && near(down.second, 3.8) && !down.first_faces,
            "{down:?}"
        );
        // From inside the slab: only its back face ahead, facing away.
        let inside = bvh.front_dual_hit(Vec3::new(0.3, 0.2, 1.1), Vec3::Z, 1e-3);
        assert!(
            near(inside.first, 0.1) && near(inside.second, 1.9) && !inside.first_faces,
            "{inside:?}"
        );
        let out = bvh.front_dual_hit(Vec3::new(0.3, 0.2, 3.5), Vec3::Z, 1e-3);
        assert!(out.first.is_infinite() && out.second.is_infinite());
    }

    /// Random hit lists, many hits close together (shared edges, vertices, thin slabs), in
    /// random orders: the streamed reduction equals the definition whenever it does not
    /// overflow, and overflows only with more than [`CLUSTER`] hits besides a first.
    #[test]
    fn hit_reducer_is_reduce_hits_in_any_order() {
        let mut rng = crate::SplitMix64(7);
        let separation = 1e-3;
        let mut overflows = 0;
        for case in 0..20_000 {
            let count = 1 + (rng.next_f64() * 7.0) as usize;
            let mut hits: Vec<(f32, bool)> = (0..count)
                .map(|_| {
                    // Hits on a grid of a third of the separation, so clusters, exact ties and
                    // chains spanning more than the separation all occur.
                    let t = 1.0 + (rng.next_f64() * 12.0).floor() as f32 * separation / 3.0;
                    let t = if rng.next_f64() < 0.1 { -t } else { t };
                    (t, rng.next_f64() < 0.5)
                })
                .collect();
            let expected = reduce_hits(&hits, separation);
            for _ in 0..4 {
                for i in (1..hits.len()).rev() {
                    let j = (rng.next_f64() * (i + 1) as f64) as usize;
                    hits.swap(i, j.min(i));
                }
                let mut r = HitReducer::default();
                for &(t, f) in &hits {
                    r.add(t, f, separation);
                }
                if r.overflowed() {
                    overflows += 1;
                    // Only with more hits than the cluster holds, within the separation of one
                    // of them (a first on the way).
                    let valid = hits.iter().filter(|&&(t, _)| t > 0.0).count();
                    assert!(valid > CLUSTER + 1, "case {case}: {hits:?}");
                } else {
                    assert_eq!(r.hit(), expected, "case {case}: {hits:?}");
                }
            }
        }
        // The fallback path is exercised, but rarely.
        assert!(overflows > 0 && overflows < 20_000, "{overflows}");
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

    /// The BVH's pruned traversal meets every hit that matters: on random triangle soups its
    /// answers equal [`reduce_hits`] over every triangle tested one by one.
    #[test]
    fn bvh_answers_equal_brute_force_on_random_soups() {
        let mut rng = crate::SplitMix64(11);
        let mut r = || rng.next_f64() as f32;
        for soup in 0..40 {
            let mut positions = Vec::new();
            let mut triangles = Vec::new();
            for t in 0..(4 + soup * 3) as u32 {
                // A grid of quads sharing edges, and free triangles.
                let base = Vec3::new(r() * 4.0 - 2.0, r() * 4.0 - 2.0, r() * 4.0 - 2.0);
                let (e1, e2) = (
                    Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 2.0,
                    Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 2.0,
                );
                positions.extend([base, base + e1, base + e2, base + e1 + e2]);
                let b = 4 * t;
                triangles.push([b, b + 1, b + 2]);
                triangles.push([b + 2, b + 1, b + 3]);
            }
            let scene = Scene::from_triangles(positions, triangles);
            let bvh = SceneBvh::new(&scene);
            let (tris, normals) = bvh.triangles_by_scene_index();
            for _ in 0..400 {
                let origin = Vec3::new(r() * 4.0 - 2.0, r() * 4.0 - 2.0, r() * 4.0 - 2.0);
                // Axis-aligned and general directions.
                let dir = match (r() * 4.0) as u32 {
                    0 => Vec3::Z * if r() < 0.5 { 1.0 } else { -1.0 },
                    _ => Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5),
                };
                if dir == Vec3::ZERO {
                    continue;
                }
                let wt = WatertightRay::new(origin, dir);
                let hits: Vec<(f32, bool)> = tris
                    .iter()
                    .zip(normals)
                    .map(|(tri, n)| (wt.intersect(tri), n.dot(dir) < 0.0))
                    .collect();
                let any: Vec<_> = hits.iter().map(|&(t, _)| (t, true)).collect();
                let expected = reduce_hits(&any, 1e-3);
                let got = bvh.dual_hit(origin, dir, 1e-3);
                assert_eq!((got.first, got.second), (expected.first, expected.second));
                assert_eq!(
                    bvh.front_dual_hit(origin, dir, 1e-3),
                    reduce_hits(&hits, 1e-3)
                );
            }
        }
    }
}
