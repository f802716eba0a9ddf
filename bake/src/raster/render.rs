//! Rendering one texel's cube map triangle by triangle ([`render`]): which ray each pixel casts
//! (exactly `cubemap::render`'s choices), the triangles that may meet one, each face's scan over
//! their covers (`cover`), and every pixel's interval; with the per-thread buffers it reuses
//! from texel to texel.

use std::cell::RefCell;

use cssm_formats::{
    Texel,
    cube::{self, DepthQuantizer, PixelGrid},
};
use glam::{Vec2, Vec3};

use super::RasterScene;
use super::cover::{Edge, Polygon, Triangle, band_span, corner_slack};
use crate::cubemap::{self, DONT_CARE, Interval, SecondLayer, Seen};
use crate::raycast::{FrontHit, HitReducer, SharedAxisRays, WatertightRay, reduce_hits};

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
