//! Depth cube maps (§3.2.1): for one texel, a `6 x N x N` map of linear depth seen from the
//! texel position pushed off the surface by the near distance. Every pixel records the codes of
//! all depths between its ray's first and second intersection, any of which is a correct
//! stand-in (dual depth layers); pixels wholly behind the tangent plane are "don't care".
//! Beyond the paper, [`SecondLayer::Facing`] ends the range at the nearest intersection whose
//! surface faces the texel instead of at the second one, and [`SecondLayer::Exchange`] also
//! drops the lower end where the first surface faces away.

use cssm_formats::{
    Texel,
    cube::{self, DEPTH_MAX, DepthQuantizer, PixelGrid},
};

use crate::raster::RasterScene;
use crate::raycast::{FrontHit, SceneBvh};

/// Acceptable code range `[lo, hi]` of one pixel; `[0, DEPTH_MAX]` means "don't care".
pub type Interval = (u16, u16);

/// Which intersection closes a pixel's interval.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SecondLayer {
    /// The second intersection, whichever way its surface faces (the paper, §3.2, after
    /// Weiskopf and Ertl's dual depth layers).
    #[default]
    Any,
    /// Beyond the paper: the nearest intersection beyond the first whose surface *faces* the
    /// texel. A point on a surface facing away (the far side of a wall, of a column, of a closed
    /// mesh) has a zero cosine towards the texel, so it exchanges no light with it and its
    /// visibility never matters; skipping it widens the interval from a wall's thickness to the
    /// room behind it, and runs grow longer.
    Facing,
    /// Beyond the paper: only surfaces that can exchange light with the texel bound the range.
    /// The top is as in [`SecondLayer::Facing`]; the bottom is the first intersection only when
    /// its surface faces the texel (that point must stay visible). When the first surface faces
    /// away (the back of a single-sided panel, the inside of an object the texel lies in), no
    /// point in front of it exchanges light with the texel, so any code below the top will do.
    /// A pixel whose ray meets no facing surface at all is "don't care" when its eight
    /// neighbours meet none either; next to one that does, it keeps the paper's range, since
    /// the query's pixel footprint (and its 2x2 filter) reaches across the border.
    Exchange,
}

impl SecondLayer {
    /// Every choice, default first.
    pub const ALL: [SecondLayer; 3] =
        [SecondLayer::Any, SecondLayer::Facing, SecondLayer::Exchange];

    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SecondLayer::Any => "any",
            SecondLayer::Facing => "facing",
            SecondLayer::Exchange => "exchange",
        }
    }
}

impl std::fmt::Display for SecondLayer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for SecondLayer {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "any" => Ok(SecondLayer::Any),
            "facing" => Ok(SecondLayer::Facing),
            "exchange" => Ok(SecondLayer::Exchange),
            other => Err(format!(
                "unknown second layer '{other}': expected any, facing or exchange"
            )),
        }
    }
}

/// Which renderer draws the cube maps: both write byte-identical maps, only their speed
/// differs with the scene's size (reports/bake.md, "CPU rasteriser").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CubeRenderer {
    /// The rasteriser for scenes of at most `N^2.5 / 5` triangles at cube resolution `N`, the
    /// BVH above ([`CubeRenderer::resolve`]).
    #[default]
    Auto,
    /// Triangle by triangle ([`crate::raster`]): fastest for scenes of few triangles.
    Raster,
    /// One BVH traversal per pixel ([`render`]).
    Bvh,
}

impl CubeRenderer {
    /// Every choice, default first.
    pub const ALL: [CubeRenderer; 3] =
        [CubeRenderer::Auto, CubeRenderer::Raster, CubeRenderer::Bvh];

    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            CubeRenderer::Auto => "auto",
            CubeRenderer::Raster => "raster",
            CubeRenderer::Bvh => "bvh",
        }
    }

    /// The renderer used for a scene of `triangles` triangles at cube resolution `n`:
    /// [`CubeRenderer::Raster`] or [`CubeRenderer::Bvh`]. [`CubeRenderer::Auto`] rasterises up
    /// to `n^2.5 / 5` triangles (36 at cube 8, 204 at 16, 1,158 at 32, 6,553 at 64). The
    /// rasteriser's cost per map grows with the triangles (each is clipped to every face and
    /// scanned row by row) and the pixels they cover, the BVH's with the pixels and slowly with
    /// the triangles; in `benches/cube_renderer.rs` (the Cornell box split into more and more
    /// triangles, and the teapot) the two break even at about 28 triangles at cube 8, 200 at 16,
    /// 1,150 at 32 and 5,600-6,500 at 64 (reports/bake.md, "The rasteriser's crossover, again").
    ///
    /// ```
    /// use cssm_bake::cubemap::CubeRenderer;
    /// assert_eq!(CubeRenderer::Auto.resolve(30, 64), CubeRenderer::Raster);
    /// assert_eq!(CubeRenderer::Auto.resolve(100, 8), CubeRenderer::Bvh);
    /// assert_eq!(CubeRenderer::Auto.resolve(6_320, 64), CubeRenderer::Raster);
    /// assert_eq!(CubeRenderer::Auto.resolve(7_680, 64), CubeRenderer::Bvh);
    /// assert_eq!(CubeRenderer::Auto.resolve(2_000, 32), CubeRenderer::Bvh);
    /// assert_eq!(CubeRenderer::Bvh.resolve(30, 64), CubeRenderer::Bvh);
    /// ```
    pub fn resolve(self, triangles: usize, n: u32) -> CubeRenderer {
        match self {
            // triangles <= n^2.5 / 5, squared to stay in integers.
            CubeRenderer::Auto if (triangles as u128).pow(2) * 25 <= u128::from(n).pow(5) => {
                CubeRenderer::Raster
            }
            CubeRenderer::Auto => CubeRenderer::Bvh,
            other => other,
        }
    }
}

impl std::fmt::Display for CubeRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for CubeRenderer {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "auto" => Ok(CubeRenderer::Auto),
            "raster" => Ok(CubeRenderer::Raster),
            "bvh" => Ok(CubeRenderer::Bvh),
            other => Err(format!(
                "unknown cube renderer '{other}': expected auto, raster or bvh"
            )),
        }
    }
}

/// A scene ready to render cube maps with, by the renderer [`CubeRenderer::resolve`] picks for
/// each map's resolution.
pub struct Renderer<'a> {
    bvh: &'a SceneBvh,
    choice: CubeRenderer,
    /// Where every texel's pixels sit.
    grid: PixelGrid,
    /// The rasteriser's scene, unless the choice is the BVH.
    raster: Option<RasterScene>,
}

impl<'a> Renderer<'a> {
    /// Renders `bvh`'s scene as `choice` says, each texel's pixels on `grid`.
    pub fn new(bvh: &'a SceneBvh, choice: CubeRenderer, grid: PixelGrid) -> Self {
        let raster = (choice != CubeRenderer::Bvh).then(|| RasterScene::new(bvh));
        Self {
            bvh,
            choice,
            grid,
            raster,
        }
    }

    /// [`CubeRenderer::Raster`] or [`CubeRenderer::Bvh`]: the renderer of maps of resolution
    /// `n`.
    pub fn kind(&self, n: u32) -> CubeRenderer {
        match &self.raster {
            Some(scene) => self.choice.resolve(scene.len(), n),
            None => CubeRenderer::Bvh,
        }
    }

    /// Renders one texel's cube map into `out`, as [`render`] does (byte for byte), returning the
    /// rays cast.
    pub fn render(
        &self,
        texel: &Texel,
        n: u32,
        near: f32,
        quantizer: &DepthQuantizer,
        second_layer: SecondLayer,
        out: &mut [Interval],
    ) -> u64 {
        match &self.raster {
            Some(scene) if self.kind(n) == CubeRenderer::Raster => crate::raster::render(
                scene,
                texel,
                self.grid,
                n,
                near,
                quantizer,
                second_layer,
                out,
            ),
            _ => render(
                self.bvh,
                texel,
                self.grid,
                n,
                near,
                quantizer,
                second_layer,
                out,
            ),
        }
    }
}

/// The don't-care interval.
pub const DONT_CARE: Interval = (0, DEPTH_MAX);

/// What a pixel's ray saw, for [`SecondLayer::Exchange`]'s second pass.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Seen {
    /// Wholly behind the tangent plane (or cast along it with no depth): don't care.
    Behind,
    /// No surface facing the texel along the ray.
    NoFacingSurface,
    /// A surface facing the texel.
    FacingSurface,
}

/// Renders one texel's cube map into `out` (`6 * n * n` intervals), its pixels on `grid`, by
/// one BVH traversal per pixel. Returns the number of rays cast (pixels that were not
/// don't-care). [`crate::raster::render`] writes the same intervals triangle by triangle.
#[allow(clippy::too_many_arguments)]
pub fn render(
    bvh: &SceneBvh,
    texel: &Texel,
    grid: PixelGrid,
    n: u32,
    near: f32,
    quantizer: &DepthQuantizer,
    second_layer: SecondLayer,
    out: &mut [Interval],
) -> u64 {
    let cast = ray_caster(bvh, near, quantizer, second_layer);
    render_with(
        texel,
        grid,
        n,
        near,
        quantizer,
        second_layer,
        out,
        |_, centre, dir| cast(centre, dir),
    )
}

/// The BVH's answer for a pixel's ray from `centre` along `dir`, as [`render`] casts it.
pub(crate) fn ray_caster<'a>(
    bvh: &'a SceneBvh,
    near: f32,
    quantizer: &DepthQuantizer,
    second_layer: SecondLayer,
) -> impl Fn(glam::Vec3, glam::Vec3) -> FrontHit + 'a {
    let separation = separation(quantizer);
    let min_hit = min_hit(near, bvh.magnitude());
    move |centre, dir| match second_layer {
        SecondLayer::Any => {
            let hit = bvh.dual_hit_beyond(centre, dir, min_hit, separation);
            FrontHit {
                first: hit.first,
                first_faces: true,
                second: hit.second,
            }
        }
        SecondLayer::Facing | SecondLayer::Exchange => {
            bvh.front_dual_hit_beyond(centre, dir, min_hit, separation)
        }
    }
}

/// The cube centre of `texel`: its position pushed off its surface by the near distance.
pub(crate) fn centre(texel: &Texel, near: f32) -> glam::Vec3 {
    texel.pos() + texel.nrm() * near
}

/// [`render`] with each cast pixel's hits from `hit(pixel, centre, direction)`: the BVH's, or
/// the GPU's ([`crate::gpu`]). Everything else (which pixels are cast, along which ray, their
/// intervals, the exchange layer's second pass) is this one code for every renderer.
#[allow(clippy::too_many_arguments)]
pub(crate) fn render_with(
    texel: &Texel,
    grid: PixelGrid,
    n: u32,
    near: f32,
    quantizer: &DepthQuantizer,
    second_layer: SecondLayer,
    out: &mut [Interval],
    mut hit: impl FnMut(usize, glam::Vec3, glam::Vec3) -> FrontHit,
) -> u64 {
    let normal = texel.nrm();
    let centre = centre(texel, near);
    let exchange = second_layer == SecondLayer::Exchange;
    let mut seen = if exchange {
        vec![Seen::Behind; out.len()]
    } else {
        Vec::new()
    };
    let mut rays = 0;
    let face_pixels = (n * n) as usize;
    let directions = centre_directions(n, grid.offset(texel.x, texel.y));
    let reach: [f32; 6] = std::array::from_fn(|f| cube::dont_care_reach(n, f as u32, normal));
    for (pixel, slot) in out.iter_mut().enumerate() {
        *slot = DONT_CARE;
        // `cube::pixel_is_dont_care` and `cube::cast_direction`, their shared terms computed
        // once (the same arithmetic).
        let face = (pixel / face_pixels) as u32;
        let centre_dir = directions[pixel];
        let below = centre_dir.dot(normal);
        if below + reach[face as usize] < 0.0 {
            continue;
        }
        rays += 1;
        // Straddling pixels whose centre points below the plane are cast along it (see
        // `cube::cast_direction`): otherwise they would only see the texel's own surface.
        let (dir, depth_scale) = cube::cast_direction_from(centre_dir, below, normal, face);
        if depth_scale < 1e-3 {
            continue;
        }
        let (interval, pixel_seen) = finish_pixel(
            second_layer,
            hit(pixel, centre, dir),
            depth_scale,
            quantizer,
        );
        *slot = interval;
        if exchange {
            seen[pixel] = pixel_seen;
        }
    }
    if exchange {
        exchange_pass(n, &seen, out);
    }
    rays
}

/// Hits closer together than a tenth of a depth code are the same surface.
pub(crate) fn separation(quantizer: &DepthQuantizer) -> f32 {
    0.1 * quantizer.far() / DEPTH_MAX as f32
}

/// Hits nearer the cube's centre than this are not seen. The centre sits the near distance off
/// its own surface; a surface through the centre itself (a texel in a corner, pushed along its
/// normal into the plane of the adjacent wall) meets the ray at `t = 0` give or take the
/// watertight test's rounding, which scales with the coordinates' magnitude, and whether the
/// BVH's box tests let such a hit through is a matter of rounding too. Ignoring every hit within
/// a hundredth of the near distance, and well beyond that rounding, makes the answer the same
/// for every renderer: such a hit would only say "code 0" for a surface the texel lies on.
pub(crate) fn min_hit(near: f32, magnitude: f32) -> f32 {
    (0.01 * near).max(256.0 * f32::EPSILON * magnitude)
}

/// A cast pixel's interval from its ray's hits (`hit.first_faces` unused for
/// [`SecondLayer::Any`], whose second hit is taken whichever way it faces), and what its ray saw.
#[inline]
pub(crate) fn finish_pixel(
    second_layer: SecondLayer,
    hit: FrontHit,
    depth_scale: f32,
    quantizer: &DepthQuantizer,
) -> (Interval, Seen) {
    let mut seen = Seen::Behind;
    if second_layer == SecondLayer::Exchange {
        let second = hit.second * depth_scale;
        seen = if hit.first_faces || second.is_finite() {
            Seen::FacingSurface
        } else {
            Seen::NoFacingSurface
        };
        if !hit.first_faces && second.is_finite() {
            // Nothing to keep visible: every code below the first facing surface.
            return ((0, quantizer.last_code_before(second)), seen);
        }
    }
    (
        quantizer.interval(hit.first * depth_scale, hit.second * depth_scale),
        seen,
    )
}

/// [`SecondLayer::Exchange`]'s second pass: a pixel that met no facing surface, nor did any of
/// its eight neighbours, is don't care.
pub(crate) fn exchange_pass(n: u32, seen: &[Seen], out: &mut [Interval]) {
    BORDER_NEIGHBOURS.with_borrow_mut(|(resolution, border)| {
        if *resolution != n {
            *border = border_neighbours(n);
            *resolution = n;
        }
        let side = n as usize;
        for (pixel, slot) in out.iter_mut().enumerate() {
            if seen[pixel] != Seen::NoFacingSurface {
                continue;
            }
            let (face, row, col) = cube::split_pixel(n, pixel as u32);
            let (row, col) = (row as usize, col as usize);
            let clear = if row == 0 || col == 0 || row + 1 == side || col + 1 == side {
                let edge = border_index(n, face, row, col);
                border[edge]
                    .iter()
                    .all(|&q| seen[q as usize] != Seen::FacingSurface)
            } else {
                // Inside the face: the 3x3 block around the pixel (`cube::neighbours`).
                let (above, below) = (pixel - side, pixel + side);
                [
                    above - 1,
                    above,
                    above + 1,
                    pixel - 1,
                    pixel + 1,
                    below - 1,
                    below,
                    below + 1,
                ]
                .iter()
                .all(|&q| seen[q] != Seen::FacingSurface)
            };
            if clear {
                *slot = DONT_CARE;
            }
        }
    });
}

/// [`cube::pixel_direction_at`] of every pixel at resolution `n` on the grid shifted by
/// `offset`, computed once per thread, resolution and offset (two divisions per pixel of every
/// map otherwise: 9% of a BVH bake's samples with the don't-care test). A bake's texels take
/// turns among the four offsets of a staggered grid, so the last four tables are kept.
pub(crate) fn centre_directions(n: u32, offset: glam::Vec2) -> std::rc::Rc<[glam::Vec3]> {
    CENTRE_DIRECTIONS.with_borrow_mut(|tables| {
        if let Some((_, _, dirs)) = tables.iter().find(|(r, o, _)| *r == n && *o == offset) {
            return dirs.clone();
        }
        let dirs: std::rc::Rc<[glam::Vec3]> = (0..6 * n * n)
            .map(|p| cube::pixel_direction_at(n, p, offset))
            .collect();
        if tables.len() == 4 {
            tables.remove(0);
        }
        tables.push((n, offset, dirs.clone()));
        dirs
    })
}

thread_local! {
    /// [`centre_directions`]' tables: resolution, offset, directions.
    #[allow(clippy::type_complexity)]
    static CENTRE_DIRECTIONS: std::cell::RefCell<Vec<(u32, glam::Vec2, std::rc::Rc<[glam::Vec3]>)>> =
        const { std::cell::RefCell::new(Vec::new()) };
    /// [`cube::neighbours`] of every pixel on a face's border (those cross to other faces,
    /// each a projection per neighbour) at the last resolution this thread saw: computed once
    /// per bake thread instead of for every map (they cost the exchange pass a third of a
    /// Cornell bake's 7%).
    static BORDER_NEIGHBOURS: std::cell::RefCell<(u32, Vec<[u32; 8]>)> =
        const { std::cell::RefCell::new((0, Vec::new())) };
}

/// Index of border pixel `(face, row, col)` among the `4 (n - 1)` border pixels of each face, face
/// after face: the rows 0 and `n - 1` whole, the columns 0 and `n - 1` in between.
fn border_index(n: u32, face: u32, row: usize, col: usize) -> usize {
    let side = n as usize;
    let per_face = 4 * (side - 1);
    let within = if row == 0 {
        col
    } else if row + 1 == side {
        side + col
    } else {
        2 * side + 2 * (row - 1) + usize::from(col != 0)
    };
    face as usize * per_face + within
}

/// [`cube::neighbours`] of every border pixel, in [`border_index`] order.
fn border_neighbours(n: u32) -> Vec<[u32; 8]> {
    let side = n as usize;
    let mut table = vec![[0; 8]; 6 * 4 * (side - 1)];
    for pixel in 0..6 * n * n {
        let (face, row, col) = cube::split_pixel(n, pixel);
        let (row, col) = (row as usize, col as usize);
        if row == 0 || col == 0 || row + 1 == side || col + 1 == side {
            table[border_index(n, face, row, col)] = cube::neighbours(n, pixel);
        }
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// Above a texel at the origin facing +z: a single-sided panel at z = 1 that faces away
    /// from it (+z), wider than the view straight up, and a smaller ceiling at z = 3 that faces
    /// it (-z), seen only by the middle pixels of the +z face.
    fn panel_and_ceiling() -> crate::raycast::SceneBvh {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for (z, half, faces_minus_z) in [(1.0, 1.5, false), (3.0, 0.5, true)] {
            let base = positions.len() as u32;
            for (x, y) in [(-half, -half), (half, -half), (half, half), (-half, half)] {
                positions.push(Vec3::new(x, y, z));
            }
            if faces_minus_z {
                triangles.extend([[base, base + 2, base + 1], [base, base + 3, base + 2]]);
            } else {
                triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
            }
        }
        crate::raycast::SceneBvh::new(&cssm_formats::Scene::from_triangles(positions, triangles))
    }

    /// The exchange pass's neighbours (a table on the border, the 3x3 block inside) are
    /// `cube::neighbours`, at even and odd resolutions, one resolution after another on one
    /// thread.
    #[test]
    fn exchange_pass_neighbours_are_the_cubes() {
        for n in [8, 5, 8, 16] {
            let pixels = 6 * n * n;
            for pixel in 0..pixels {
                // One pixel met no facing surface; a single neighbour (or none) did.
                for facing in cube::neighbours(n, pixel).into_iter().chain([pixel]) {
                    let mut seen = vec![Seen::Behind; pixels as usize];
                    seen[pixel as usize] = Seen::NoFacingSurface;
                    if facing != pixel {
                        seen[facing as usize] = Seen::FacingSurface;
                    }
                    let mut out = vec![(1, 2); pixels as usize];
                    exchange_pass(n, &seen, &mut out);
                    let expect = if facing == pixel { DONT_CARE } else { (1, 2) };
                    assert_eq!(
                        out[pixel as usize], expect,
                        "n {n} pixel {pixel} facing {facing}"
                    );
                }
            }
        }
    }

    #[test]
    fn exchange_keeps_only_the_bounds_of_surfaces_facing_the_texel() {
        let bvh = panel_and_ceiling();
        let texel = Texel {
            position: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
            area: 1.0,
            material: 0,
            chart: 0,
            object: 0,
            x: 0,
            y: 0,
        };
        let (n, near) = (8, 0.01);
        let quantizer = DepthQuantizer::new(near, 10.0);
        let render_with = |layer| {
            let mut out = vec![DONT_CARE; 6 * (n * n) as usize];
            render(
                &bvh,
                &texel,
                PixelGrid::Centred,
                n,
                near,
                &quantizer,
                layer,
                &mut out,
            );
            out
        };
        let (facing, exchange) = (
            render_with(SecondLayer::Facing),
            render_with(SecondLayer::Exchange),
        );
        let pixel = |u: f32, v: f32| cube::pixel_index(n, 4, u, v) as usize;
        let panel = quantizer.ceil(1.0 - near);
        let ceiling = quantizer.last_code_before(3.0 - near);

        // Straight up: the panel's back, then the ceiling. Facing keeps the panel as the
        // bottom; exchange drops it, since no point on the panel's back exchanges light.
        let up = pixel(0.1, 0.1);
        assert_eq!(facing[up], (panel, ceiling));
        assert_eq!(exchange[up], (0, ceiling));
        // Next to those pixels, only the panel's back: the paper's range stays, since the
        // query's footprint reaches the ceiling pixels.
        let beside = pixel(0.4, 0.1);
        assert_eq!(facing[beside], (panel, DEPTH_MAX));
        assert_eq!(exchange[beside], facing[beside]);
        // Far from any facing surface: don't care.
        let far = pixel(0.9, -0.9);
        assert_eq!(facing[far], (panel, DEPTH_MAX));
        assert_eq!(exchange[far], DONT_CARE);
        // Sideways, past the panel's edge, the ray meets nothing: the paper's "visible" code,
        // and don't care for exchange.
        let side = cube::pixel_index(n, 0, 0.0, 0.0) as usize;
        assert_eq!(facing[side], (DEPTH_MAX, DEPTH_MAX));
        assert_eq!(exchange[side], DONT_CARE);
        // Exchange only ever widens the ranges: every code facing accepts, it accepts too.
        for (f, e) in facing.iter().zip(&exchange) {
            assert!(e.0 <= f.0 && e.1 >= f.1, "{f:?} -> {e:?}");
        }
    }
}
