//! A second renderer of the depth cube maps (§3.2.1), for scenes of few triangles: instead of one
//! BVH traversal per pixel, it goes triangle by triangle and face by face, finds the pixels whose
//! ray may meet the triangle (a conservative scanline cover of its projection), and runs the BVH's
//! own watertight ray/triangle test ([`WatertightRay`]) on those rays only. Each pixel's hits are
//! reduced by the BVH's own order-independent [`HitReducer`], so the intervals — and the `.cssm`
//! file — are byte-identical to [`cubemap::render`]'s (the tests below and
//! `tests/cube_renderer.rs` check it); only the time differs.
//!
//! Why it pays: the Cornell box has 36 triangles, each cube face sees a handful of them, and a
//! pixel is covered by two or three; a BVH traversal per pixel costs several node tests first.
//!
//! Conservative cover: the watertight test decides exactly for a triangle whose corners are moved
//! by at most a few ulps of the coordinates' magnitude (`corner_slack`); seen from the cube's
//! centre at distance `d` or more, such a move shifts the triangle's projection by less than
//! `margin` in face coordinates (`Triangle::margin`). The cover is the triangle clipped to the
//! face's frustum widened by that margin, projected, and widened again by it: it holds every pixel
//! whose ray the test may report as a hit.
//!
//! Straddling pixels whose centre points below the tangent plane cast along the plane
//! ([`cube::cast_direction`]), not through their centre: each such ray is binned into the pixel
//! cell its own direction falls in, and tested with the triangles that cover that cell.

use std::cell::RefCell;

use cssm_formats::{
    Texel,
    cube::{self, DepthQuantizer, PixelGrid},
};
use glam::{DVec3, Vec2, Vec3};

use crate::cubemap::{self, DONT_CARE, Interval, SecondLayer, Seen};
use crate::raycast::{FrontHit, HitReducer, SceneBvh, SharedAxisRays, WatertightRay, reduce_hits};

/// The scene as the rasteriser reads it: the BVH's own triangles and normals, by scene index.
pub struct RasterScene {
    triangles: Vec<[Vec3; 3]>,
    normals: Vec<Vec3>,
    magnitude: f32,
}

impl RasterScene {
    /// The triangles of `bvh`'s scene, exactly as its traversal tests them.
    pub fn new(bvh: &SceneBvh) -> Self {
        let (triangles, normals) = bvh.triangles_by_scene_index();
        Self {
            triangles,
            normals: normals.to_vec(),
            magnitude: bvh.magnitude(),
        }
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// True when the scene has no triangle.
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }
}

/// Kind of a pixel in [`Scratch::kind`]: neither cast nor tested (don't care, or cast along the
/// plane with no depth).
const SKIP: u32 = u32::MAX;
/// Cast through its centre.
const CENTRE: u32 = u32::MAX - 1;
// Anything else: the index of the pixel's ray in `Scratch::extras` (cast along the plane).

/// A ray cast along the tangent plane (a straddling pixel whose centre points below it).
#[derive(Clone, Copy)]
struct Extra {
    pixel: u32,
    /// Pixel cell (`face * n * n + row * n + col`) its direction falls in.
    cell: u32,
    dir: Vec3,
    ray: WatertightRay,
    depth_scale: f32,
    reducer: HitReducer,
}

/// The centre rays of one pixel grid: a resolution and a grid offset.
struct GridRays {
    n: u32,
    offset: Vec2,
    /// Centre direction of every pixel ([`cubemap::centre_directions`]).
    dirs: std::rc::Rc<[Vec3]>,
    /// Its watertight ray (from the origin).
    rays: Vec<WatertightRay>,
    /// The same rays laid out to test a triangle against a run of a row's pixels at once.
    lanes: SharedAxisRays,
}

impl GridRays {
    fn new(n: u32, offset: Vec2) -> Self {
        let dirs = cubemap::centre_directions(n, offset);
        let rays: Vec<WatertightRay> = dirs
            .iter()
            .map(|&dir| WatertightRay::new(Vec3::ZERO, dir))
            .collect();
        // The centre rays of a face share their axes (the face's major axis is the largest
        // component of each), so a triangle is reordered once per face.
        for (p, ray) in rays.iter().enumerate() {
            assert_eq!(ray.axes(), rays[p - p % (n * n) as usize].axes());
        }
        let lanes = SharedAxisRays::new(&rays);
        Self {
            n,
            offset,
            dirs,
            rays,
            lanes,
        }
    }
}

/// Per-thread buffers, reused from texel to texel.
#[derive(Default)]
struct Scratch {
    /// The centre rays of the last four grids (a staggered grid's texels take turns among
    /// four offsets).
    grids: Vec<GridRays>,
    /// One row's hits, from a grid's `lanes`.
    row_hits: Vec<f32>,
    kind: Vec<u32>,
    extras: Vec<Extra>,
    /// `extras[row_start[face * n + row]..row_start[face * n + row + 1]]` fall in that row.
    row_start: Vec<u32>,
    reducers: Vec<HitReducer>,
    seen: Vec<Seen>,
    triangles: Vec<Triangle>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// One triangle seen from one cube centre.
struct Triangle {
    index: u32,
    /// Corners relative to the centre, in `f32` exactly as [`WatertightRay::intersect`] computes
    /// them.
    rel: [[f32; 3]; 3],
    /// Widening of its cover in face coordinates (see the module's documentation); `None` when
    /// it comes so close to the centre that the cover is every pixel.
    margin: Option<f64>,
}

/// How far the watertight test's rounding may move a triangle's corners, for coordinates up to
/// `magnitude`: its inputs are `corner - origin` rounded to `f32` (half an ulp), then sheared and
/// crossed in `f32`; a few ulps of the magnitude, and 64 of them to be safe.
fn corner_slack(magnitude: f32) -> f64 {
    64.0 * f64::from(f32::EPSILON) * f64::from(magnitude)
}

impl Triangle {
    fn new(index: u32, corners: &[Vec3; 3], centre: Vec3) -> Self {
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
    fn face_corners(&self, face: u32) -> [[f64; 3]; 3] {
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
struct Polygon {
    points: [[f64; 3]; 8],
    len: usize,
}

impl Polygon {
    /// Keeps the part where `a * u + b * v + c * depth >= 0` (Sutherland–Hodgman).
    fn clip(&self, a: f64, b: f64, c: f64) -> Polygon {
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
struct Edge {
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
    fn new(p: [f64; 2], q: [f64; 2]) -> Edge {
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
fn band_span(edges: &[Edge], lo: f64, hi: f64) -> Option<(f64, f64)> {
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

/// Renders one texel's cube map into `out` (`6 * n * n` intervals), its pixels on `grid`,
/// triangle by triangle:
/// byte-identical to [`cubemap::render`] with the BVH `scene` was built from. Returns the number
/// of rays cast (pixels that were not don't-care), as it does.
///
/// ```
/// use cssm_bake::{cubemap, raster, raycast::SceneBvh};
/// use cssm_formats::{Texel, cube::{DepthQuantizer, PixelGrid}};
/// let scene = cssm_formats::Scene::load(
///     &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box"),
/// )?;
/// let bvh = SceneBvh::new(&scene);
/// let texel = Texel {
///     position: [278.0, 0.0, 279.0], normal: [0.0, 1.0, 0.0], area: 1.0,
///     material: 0, chart: 0, object: 0, x: 3, y: 0,
/// };
/// let grid = PixelGrid::Staggered;
/// let (n, near, quantizer) = (8, 0.5, DepthQuantizer::new(0.5, scene.diameter()));
/// let layer = cubemap::SecondLayer::Exchange;
/// let mut by_bvh = vec![cubemap::DONT_CARE; 6 * 8 * 8];
/// let mut by_raster = by_bvh.clone();
/// cubemap::render(&bvh, &texel, grid, n, near, &quantizer, layer, &mut by_bvh);
/// let scene = raster::RasterScene::new(&bvh);
/// raster::render(&scene, &texel, grid, n, near, &quantizer, layer, &mut by_raster);
/// assert_eq!(by_bvh, by_raster);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[allow(clippy::too_many_arguments)]
pub fn render(
    scene: &RasterScene,
    texel: &Texel,
    grid: PixelGrid,
    n: u32,
    near: f32,
    quantizer: &DepthQuantizer,
    second_layer: SecondLayer,
    out: &mut [Interval],
) -> u64 {
    SCRATCH.with(|scratch| {
        render_with(
            scene,
            texel,
            grid.offset(texel.x, texel.y),
            n,
            near,
            quantizer,
            second_layer,
            out,
            &mut scratch.borrow_mut(),
        )
    })
}

#[allow(clippy::too_many_arguments)]
fn render_with(
    scene: &RasterScene,
    texel: &Texel,
    offset: Vec2,
    n: u32,
    near: f32,
    quantizer: &DepthQuantizer,
    second_layer: SecondLayer,
    out: &mut [Interval],
    scratch: &mut Scratch,
) -> u64 {
    let normal = texel.nrm();
    let centre = texel.pos() + normal * near;
    let separation = cubemap::separation(quantizer);
    let min_hit = cubemap::min_hit(near, scene.magnitude);
    let any = second_layer == SecondLayer::Any;
    let exchange = second_layer == SecondLayer::Exchange;
    let pixels = 6 * n * n;
    let face_pixels = (n * n) as usize;

    let grid = match (scratch.grids.iter()).position(|g| g.n == n && g.offset == offset) {
        Some(i) => i,
        None => {
            if scratch.grids.len() == 4 {
                scratch.grids.remove(0);
            }
            scratch.grids.push(GridRays::new(n, offset));
            scratch.grids.len() - 1
        }
    };
    scratch.row_hits.resize(n as usize, 0.0);
    let Scratch {
        grids,
        row_hits,
        kind,
        extras,
        row_start,
        reducers,
        seen,
        triangles,
    } = scratch;
    let GridRays {
        dirs: centre_dirs,
        rays: centre_rays,
        lanes: centre_lanes,
        ..
    } = &grids[grid];

    // Which pixels cast which ray: exactly `cubemap::render`'s choices.
    kind.clear();
    kind.resize(pixels as usize, SKIP);
    extras.clear();
    let mut rays = 0;
    // Per face, the rows and columns holding a pixel to test (`[row0, row1, col0, col1]`;
    // empty when `row0 > row1`): for a texel's normal most of a face or all of it is don't care.
    let mut active = [[u32::MAX, 0, u32::MAX, 0]; 6];
    let mut activate = |face: u32, row: u32, col: u32| {
        let a = &mut active[face as usize];
        *a = [a[0].min(row), a[1].max(row), a[2].min(col), a[3].max(col)];
    };
    for face in 0..6 {
        // `cube::pixel_is_dont_care` with its per-face term hoisted, the same arithmetic.
        let corner_reach = cube::dont_care_reach(n, face, normal);
        for (row, col) in (0..n).flat_map(|row| (0..n).map(move |col| (row, col))) {
            let pixel = face * n * n + row * n + col;
            let below = centre_dirs[pixel as usize].dot(normal);
            if below + corner_reach < 0.0 {
                continue;
            }
            rays += 1;
            if below >= 0.0 {
                kind[pixel as usize] = CENTRE;
                activate(face, row, col);
                continue;
            }
            let (dir, depth_scale) =
                cube::cast_direction_from(centre_dirs[pixel as usize], below, normal, face);
            if depth_scale < 1e-3 {
                continue;
            }
            let (face, u, v, _) = cube::project(dir);
            let cell = cube::pixel_index_at(n, face, u, v, offset);
            let (_, cell_row, cell_col) = cube::split_pixel(n, cell);
            activate(face, cell_row, cell_col);
            extras.push(Extra {
                pixel,
                cell,
                dir,
                ray: WatertightRay::new(centre, dir),
                depth_scale,
                reducer: HitReducer::default(),
            });
        }
    }
    extras.sort_by_key(|e| e.cell);
    row_start.clear();
    row_start.resize((6 * n + 1) as usize, 0);
    for e in extras.iter() {
        row_start[(e.cell / n) as usize + 1] += 1;
    }
    for r in 1..row_start.len() {
        row_start[r] += row_start[r - 1];
    }
    for (i, e) in extras.iter().enumerate() {
        kind[e.pixel as usize] = i as u32;
    }

    // Triangles wholly below the tangent plane meet no cast ray: every ray leaves the centre
    // on or above the plane (the straddling pixels' along it, within rounding), so a triangle
    // whose corners all lie below it by more than that rounding over the triangle's distance,
    // plus the test's own slack, is skipped. On a closed object most of it is below each texel.
    let slack = corner_slack(scene.magnitude.max(centre.abs().max_element()));
    let (c, nrm) = (centre.as_dvec3(), normal.as_dvec3());
    let below_plane = |corners: &[Vec3; 3]| {
        let (mut top, mut reach) = (f64::NEG_INFINITY, 0.0f64);
        for corner in corners {
            let d = corner.as_dvec3() - c;
            top = top.max(d.dot(nrm));
            reach = reach.max(d.length());
        }
        top < -(1e-4 * (reach + slack) + slack)
    };
    triangles.clear();
    triangles.extend(
        scene
            .triangles
            .iter()
            .enumerate()
            .filter(|(_, corners)| !below_plane(corners))
            .map(|(i, corners)| Triangle::new(i as u32, corners, centre)),
    );

    seen.clear();
    seen.resize(if exchange { pixels as usize } else { 0 }, Seen::Behind);
    if reducers.len() != face_pixels {
        reducers.clear();
        reducers.resize(face_pixels, HitReducer::default());
    }
    // Pixel `col` of the grid covers `u` in `[(col + offset.x) step - 1, (col + 1 + offset.x)
    // step - 1]`, and likewise rows in `v`.
    let step = 2.0 / f64::from(n);
    let (shift_u, shift_v) = (f64::from(offset.x), f64::from(offset.y));
    let cell_u = |x: f64| ((x + 1.0) / step - shift_u).floor();
    let cell_v = |x: f64| ((x + 1.0) / step - shift_v).floor();
    let mut uv = [[0.0f64; 2]; 8];
    let mut edges = [Edge::default(); 8];
    for face in 0..6 {
        let base = face * n * n;
        let axes = centre_rays[base as usize].axes();
        let [row0, row1, col0, col1] = active[face as usize];
        let rows = f64::from(row0)..=f64::from(row1);
        let (col0, col1) = (f64::from(col0), f64::from(col1));
        // A face with nothing to test keeps its don't-care pixels.
        let face_triangles = if rows.is_empty() {
            &[][..]
        } else {
            &triangles[..]
        };
        for tri in face_triangles {
            let normal_of = scene.normals[tri.index as usize];
            let permuted = tri.rel.map(|p| axes.map(|k| p[k]));
            // Rows of the face to visit, each with its columns.
            let mut visit = |row: u32, c0: u32, c1: u32| {
                let first = (base + row * n + c0) as usize;
                let hits = &mut row_hits[..(c1 - c0 + 1) as usize];
                centre_lanes.intersect_permuted(first..first + hits.len(), &permuted, hits);
                for (col, &t) in (c0..=c1).zip(hits.iter()) {
                    let pixel = base + row * n + col;
                    if kind[pixel as usize] == CENTRE && t > min_hit {
                        let faces = any || normal_of.dot(centre_dirs[pixel as usize]) < 0.0;
                        reducers[(row * n + col) as usize].add(t, faces, separation);
                    }
                }
                let cells = (face * n + row) as usize;
                let (lo, hi) = (base + row * n + c0, base + row * n + c1);
                for e in &mut extras[row_start[cells] as usize..row_start[cells + 1] as usize] {
                    if (lo..=hi).contains(&e.cell) {
                        let t = e.ray.intersect_relative(&tri.rel);
                        if t > min_hit {
                            let faces = any || normal_of.dot(e.dir) < 0.0;
                            e.reducer.add(t, faces, separation);
                        }
                    }
                }
            };
            let Some(margin) = tri.margin else {
                for row in row0..=row1 {
                    visit(row, col0 as u32, col1 as u32);
                }
                continue;
            };
            // Clip to the frustum of the face widened by the margin: `(1 + margin) * depth
            // >= |u|, |v|` (which keeps the depth positive, the triangle being away from the
            // centre), then project.
            let w = 1.0 + margin;
            let mut poly = Polygon {
                points: [[0.0; 3]; 8],
                len: 3,
            };
            poly.points[..3].copy_from_slice(&tri.face_corners(face));
            for (a, b) in [(-1.0, 0.0), (1.0, 0.0), (0.0, -1.0), (0.0, 1.0)] {
                poly = poly.clip(a, b, w);
                if poly.len == 0 {
                    break;
                }
            }
            if poly.len == 0 {
                continue;
            }
            let (mut vmin, mut vmax) = (f64::INFINITY, f64::NEG_INFINITY);
            for (slot, p) in uv.iter_mut().zip(&poly.points[..poly.len]) {
                *slot = [p[0] / p[2], p[1] / p[2]];
                vmin = vmin.min(slot[1]);
                vmax = vmax.max(slot[1]);
            }
            for i in 0..poly.len {
                edges[i] = Edge::new(uv[i], uv[(i + 1) % poly.len]);
            }
            let edges = &edges[..poly.len];
            let r0 = cell_v(vmin - margin).max(*rows.start());
            let r1 = cell_v(vmax + margin).min(*rows.end());
            // (`max` and `min` drop a NaN bound: the rows stay within the active ones.)
            if r0 > r1 {
                continue;
            }
            for row in r0 as u32..=r1 as u32 {
                let lo = (f64::from(row) + shift_v) * step - 1.0 - margin;
                let hi = (f64::from(row + 1) + shift_v) * step - 1.0 + margin;
                let Some((u0, u1)) = band_span(edges, lo, hi) else {
                    continue;
                };
                let c0 = cell_u(u0 - margin).max(col0);
                let c1 = cell_u(u1 + margin).min(col1);
                if c0 <= c1 {
                    visit(row, c0 as u32, c1 as u32);
                }
            }
        }
        // This face's centre rays are complete; they all lie in its active rows and columns.
        let face_out = &mut out[base as usize..base as usize + face_pixels];
        face_out.fill(DONT_CARE);
        let cells =
            (row0..=row1).flat_map(|row| (col0 as u32..=col1 as u32).map(move |col| row * n + col));
        for local in cells.map(|c| c as usize) {
            let pixel = base as usize + local;
            if kind[pixel] != CENTRE {
                continue;
            }
            let hit = hit_of(
                &reducers[local],
                scene,
                || centre_rays[pixel].with_origin(centre),
                centre_dirs[pixel],
                any,
                min_hit,
                separation,
            );
            // Ready for the next face (every reducer starts and ends a face cleared).
            reducers[local] = HitReducer::default();
            let (interval, pixel_seen) = cubemap::finish_pixel(second_layer, hit, 1.0, quantizer);
            face_out[local] = interval;
            if exchange {
                seen[pixel] = pixel_seen;
            }
        }
    }
    for e in extras.iter() {
        let hit = hit_of(&e.reducer, scene, || e.ray, e.dir, any, min_hit, separation);
        let (interval, pixel_seen) =
            cubemap::finish_pixel(second_layer, hit, e.depth_scale, quantizer);
        out[e.pixel as usize] = interval;
        if exchange {
            seen[e.pixel as usize] = pixel_seen;
        }
    }
    if exchange {
        cubemap::exchange_pass(n, seen, out);
    }
    rays
}

/// The reducer's answer, or when it overflowed (a ray through a vertex shared by many
/// triangles), [`reduce_hits`] over the ray's hits with every triangle beyond `min_hit`, as the
/// BVH does.
fn hit_of(
    reducer: &HitReducer,
    scene: &RasterScene,
    ray: impl FnOnce() -> WatertightRay,
    dir: Vec3,
    any: bool,
    min_hit: f32,
    separation: f32,
) -> FrontHit {
    if !reducer.overflowed() {
        return reducer.hit();
    }
    let ray = ray();
    let hits: Vec<(f32, bool)> = scene
        .triangles
        .iter()
        .zip(&scene.normals)
        .map(|(tri, normal)| (ray.intersect(tri), any || normal.dot(dir) < 0.0))
        .filter(|&(t, _)| t > min_hit)
        .collect();
    reduce_hits(&hits, separation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raycast::{SplitMix64, SurfaceSampler};

    fn cornell() -> cssm_formats::Scene {
        cssm_formats::Scene::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box"),
        )
        .unwrap()
    }

    #[test]
    fn cornell_atlas_texels_match_the_bvh() {
        let scene = cornell();
        let bvh = SceneBvh::new(&scene);
        let raster = RasterScene::new(&bvh);
        let far = scene.diameter();
        let near = 5e-4 * far;
        let quantizer = DepthQuantizer::new(near, far);
        let atlas = crate::atlas::build(&scene, 64, &mut |_| {}).unwrap();
        // At 64 a ray through the vertical edge of the tall block exactly at its box's corner
        // once found the BVH missing a hit (`SceneBvh`'s widened boxes): every texel, every
        // layer, a third of them each.
        let n = 64;
        let mut bad = 0;
        for (k, texel) in atlas.texels.iter().enumerate() {
            {
                // Both grids, each with every layer (the texels' cells give a staggered grid's
                // four offsets).
                let layer = SecondLayer::ALL[k % 3];
                let grid = PixelGrid::ALL[(k / 3) % 2];
                let mut a = vec![DONT_CARE; (6 * n * n) as usize];
                let mut b = a.clone();
                cubemap::render(&bvh, texel, grid, n, near, &quantizer, layer, &mut a);
                render(&raster, texel, grid, n, near, &quantizer, layer, &mut b);
                for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                    if x != y && bad < 10 {
                        bad += 1;
                        eprintln!(
                            "texel {k} {texel:?} {layer} {grid} pixel {i} {:?}: {x:?} vs {y:?}",
                            cube::split_pixel(n, i as u32)
                        );
                    }
                }
            }
        }
        assert_eq!(bad, 0);
    }

    /// Random small triangle soups seen from random texels, with every second layer: quads
    /// sharing their diagonal, triangles across the texel's tangent plane and through its cube's
    /// centre, edge-on triangles in planes through the centre, a texel lying on a triangle of the
    /// soup (so pixels straddle its plane), and the texel's cube centre on a triangle's plane.
    #[test]
    fn random_soups_match_the_bvh() {
        let rng = RefCell::new(SplitMix64(5));
        let r = || rng.borrow_mut().next_f64() as f32;
        for case in 0..300 {
            let rand_vec = |scale: f32| Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 2.0 * scale;
            let texel_pos = rand_vec(1.0);
            let normal = rand_vec(1.0).normalize_or(Vec3::Z);
            let near = 0.01;
            let centre = texel_pos + normal * near;
            let mut positions: Vec<Vec3> = Vec::new();
            let mut triangles = Vec::new();
            let mut add = |corners: [Vec3; 3], positions: &mut Vec<Vec3>| {
                let b = positions.len() as u32;
                positions.extend(corners);
                triangles.push([b, b + 1, b + 2]);
            };
            // The texel's own triangle, and its neighbour across a shared edge.
            let (t1, t2) = (
                normal.any_orthonormal_pair().0 * 0.3,
                normal.any_orthonormal_pair().1 * 0.3,
            );
            add(
                [texel_pos - t1 - t2, texel_pos + t1 - t2, texel_pos + t2],
                &mut positions,
            );
            add(
                [texel_pos + t1 - t2, texel_pos + t1 + t2, texel_pos + t2],
                &mut positions,
            );
            for _ in 0..(2 + case % 12) {
                match (r() * 6.0) as u32 {
                    // A quad of two triangles sharing a diagonal.
                    0 => {
                        let (o, e1, e2) = (rand_vec(2.0), rand_vec(1.0), rand_vec(1.0));
                        add([o, o + e1, o + e2], &mut positions);
                        add([o + e2, o + e1, o + e1 + e2], &mut positions);
                    }
                    // Edge-on: in a plane through the cube's centre.
                    1 => {
                        let (d1, d2) = (rand_vec(1.0), rand_vec(1.0));
                        let (a, b, c) = (0.2 + r(), 0.2 + r(), 0.2 + r());
                        add(
                            [centre + d1 * a, centre + d2 * b, centre + (d1 + d2) * c],
                            &mut positions,
                        );
                    }
                    // Through the cube's centre (crossing its tangent plane).
                    2 => {
                        let (e1, e2) = (rand_vec(0.5), rand_vec(0.5));
                        add([centre - e1 - e2, centre + e1, centre + e2], &mut positions);
                    }
                    // With the cube's centre on its plane, not inside it.
                    3 => {
                        let e1 = rand_vec(0.5);
                        let e2 = e1.cross(rand_vec(1.0));
                        let o = centre + e1 * 1.5;
                        add([o, o + e1, o + e2], &mut positions);
                    }
                    // Just below the tangent plane through the cube's centre, by 1e-7 to 1e-3
                    // of its distance: the rays cast along the plane graze it, and the
                    // rasteriser's culling of triangles below the plane must keep it.
                    4 => {
                        let (u, v) = normal.any_orthonormal_pair();
                        let corner = |_| {
                            let (a, b) = (r() * 2.0 - 1.0, r() * 2.0 - 1.0);
                            let along = u * a + v * b;
                            let drop = 10f32.powf(-7.0 + 4.0 * r());
                            centre + along - normal * (along.length() * drop)
                        };
                        add(std::array::from_fn(corner), &mut positions);
                    }
                    _ => add(
                        [rand_vec(2.0), rand_vec(2.0), rand_vec(2.0)],
                        &mut positions,
                    ),
                }
            }
            let scene = cssm_formats::Scene::from_triangles(positions, triangles);
            let bvh = SceneBvh::new(&scene);
            let raster = RasterScene::new(&bvh);
            let quantizer = DepthQuantizer::new(near, 8.0);
            let texel = Texel {
                position: texel_pos.to_array(),
                normal: normal.to_array(),
                area: 1.0,
                material: 0,
                chart: 0,
                object: 0,
                // Every offset of a staggered grid, case after case.
                x: (case % 2) as u16,
                y: (case / 2 % 2) as u16,
            };
            let grid = PixelGrid::ALL[case / 4 % 2];
            for n in [8u32, 16] {
                for layer in SecondLayer::ALL {
                    let mut a = vec![DONT_CARE; (6 * n * n) as usize];
                    let mut b = a.clone();
                    let ra =
                        cubemap::render(&bvh, &texel, grid, n, near, &quantizer, layer, &mut a);
                    let rb = render(&raster, &texel, grid, n, near, &quantizer, layer, &mut b);
                    assert_eq!(ra, rb);
                    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                        assert_eq!(
                            x,
                            y,
                            "case {case} n {n} {layer} {grid} pixel {i} {:?}",
                            cube::split_pixel(n, i as u32)
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn cornell_texels_match_the_bvh() {
        let scene = cornell();
        let bvh = SceneBvh::new(&scene);
        let raster = RasterScene::new(&bvh);
        let sampler = SurfaceSampler::new(&scene);
        let mut rng = SplitMix64(3);
        let far = scene.diameter();
        let near = 5e-4 * far;
        let quantizer = DepthQuantizer::new(near, far);
        for n in [8u32, 16, 64] {
            for case in 0..200 {
                let p = sampler.point([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
                let texel = Texel {
                    position: p.position.to_array(),
                    normal: p.normal.to_array(),
                    area: 1.0,
                    material: 0,
                    chart: 0,
                    object: 0,
                    x: (case % 2) as u16,
                    y: (case / 2 % 2) as u16,
                };
                let grid = PixelGrid::ALL[case / 4 % 2];
                for layer in SecondLayer::ALL {
                    let mut a = vec![DONT_CARE; (6 * n * n) as usize];
                    let mut b = a.clone();
                    let ra =
                        cubemap::render(&bvh, &texel, grid, n, near, &quantizer, layer, &mut a);
                    let rb = render(&raster, &texel, grid, n, near, &quantizer, layer, &mut b);
                    assert_eq!(ra, rb);
                    for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                        assert_eq!(
                            x,
                            y,
                            "n {n} case {case} {layer} {grid} pixel {i} {:?}",
                            cube::split_pixel(n, i as u32)
                        );
                    }
                }
            }
        }
    }
}
