//! The CPU reference visibility query over a baked CSSM (§3.2.2).
//!
//! To test whether a point `p_i` is visible from the surface point `p_j`, take the depth cube
//! map of the texel that stands for `p_j`, project `p_i` into it (pixel `q`, depth `q_z`) and
//! decode the stored depth `z_xy` of that pixel: `p_i` is occluded when `z_xy < q_z - bias`.
//! Pixels wholly behind `p_j`'s tangent plane hold "don't care" depths and answer *occluded*:
//! light leaves a surface only on its front side. Percentage-closer filtering (§3.2.2, "the same
//! generalized PCF used with CSMs") blends the tests of the 2x2 pixels around the projection.
//!
//! Beyond the paper, a query between two surface points that both have texels asks both ends
//! ([`QueryOptions::both_ends`], [`VisibilityQuery::visibility_between`]): the mean of what
//! `p_j`'s cube maps say of `p_i` and what `p_i`'s say of `p_j`. Visibility is symmetric, but
//! the two answers' errors are not: an occluder near one end covers many pixels of that end's
//! cube map and few of the other's, so the end near it resolves its edge, and where one end's
//! pixels straddle an edge the other's often do not. So the two answers are not simply averaged:
//! each end weighs by how near to it its blocking pixels put the occluder ([`EndAnswer`],
//! [`combine_ends`]); with nothing blocked at either end that is the mean.
//!
//! The GPU query of the runtime computes exactly this; this module is its reference.

use glam::{Vec2, Vec3};

use crate::{
    cssm::CssmFile,
    cube::{self, DepthQuantizer},
};

mod work;

pub use work::{Buffer, Load, QueryTally, QueryWork, Site, TEXEL_BYTES};

/// Options of a query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryOptions {
    /// Constant depth bias, as a multiple of the bake's near distance.
    pub bias_near: f32,
    /// Depth bias proportional to the query depth.
    pub bias_relative: f32,
    /// Blend the 2x2 pixels around the projection (PCF) instead of one pixel.
    pub pcf: bool,
    /// Blend the cube maps of the 2x2 atlas texels around the sender point (bilinear weights,
    /// same chart), instead of taking the one texel under it: the generalised PCF of CSMs,
    /// filtering across neighbouring depth maps as well as pixels.
    pub sender_filter: bool,
    /// Queries between two surface points that both have texels ([`VisibilityQuery::
    /// visibility_between`]) combine both ends' answers ([`combine_ends`]) instead of taking
    /// the sender's alone.
    pub both_ends: bool,
}

impl Default for QueryOptions {
    fn default() -> Self {
        Self {
            // Measured on the Cornell box (atlas 64, cube 32, 100,000 pairs): with receiver-plane
            // depth, PCF and sender filtering, a zero bias agrees best (98.2%); 1 near distance
            // gives 98.0%, 4 gives 97.4%.
            bias_near: 0.0,
            bias_relative: 0.0,
            pcf: true,
            sender_filter: true,
            // Measured with `cssm check` (100,000 pairs, seed 1; reports/visibility.md): over
            // the pairs that exchange light, 98.47% -> 99.10% on the Cornell box (atlas 64,
            // cube 32) and 93.93% -> 95.97% on the 3,700-face church (atlas 256, cube 32).
            both_ends: true,
        }
    }
}

/// One end's answer for the other end's point: what its cube maps say, and where they put the
/// occluder.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EndAnswer {
    /// Fraction of the point visible (PCF over the pixels, sender filter over the texels).
    pub visible: f32,
    /// How near to this end the blocking pixels put the occluder: the sum over the blocked taps
    /// of their weight times `1 - stored depth / receiver depth`. 0 when nothing blocks (or
    /// only don't-care pixels do), up to 1 when every tap is blocked right at the cube centre.
    /// A stored depth lies at or beyond the first surface along the pixel's ray that faces
    /// this end (its interval starts there), so a small one says the occluder is near.
    pub nearness: f32,
}

/// How much more the end nearer the occluder counts in [`combine_ends`]: its weight is
/// `exp(NEARER_END_WEIGHT * nearness)`. Measured with `cssm diagnose ends` over the pairs
/// that exchange light (reports/visibility.md, "Which end to trust"): 1, 2 and 4 all gain on
/// the church and the Cornell box; 2 gains most on both.
pub const NEARER_END_WEIGHT: f32 = 2.0;

/// Both ends' answers combined into one visible fraction: their mean, each end weighted by
/// `exp(NEARER_END_WEIGHT * nearness)`. The end nearer the occluder sees it larger (its edges
/// span more of that end's pixels), so where the two ends disagree it is more often right; with
/// nothing blocked at either end the weights are equal and this is the plain mean. The result
/// lies between the two answers.
///
/// ```
/// use cssm_formats::visibility::{EndAnswer, combine_ends};
/// let clear = EndAnswer { visible: 1.0, nearness: 0.0 };
/// // Blocked, by an occluder a tenth of the way from this end to the receiver.
/// let blocked_near = EndAnswer { visible: 0.0, nearness: 0.9 };
/// assert_eq!(combine_ends(clear, clear), 1.0);
/// assert!(combine_ends(clear, blocked_near) < 0.5);
/// ```
pub fn combine_ends(forward: EndAnswer, backward: EndAnswer) -> f32 {
    let weight_forward = (NEARER_END_WEIGHT * forward.nearness).exp();
    let weight_backward = (NEARER_END_WEIGHT * backward.nearness).exp();
    (weight_forward * forward.visible + weight_backward * backward.visible)
        / (weight_forward + weight_backward)
}

/// Answers visibility queries from a baked CSSM without decompressing it.
pub struct VisibilityQuery<'a> {
    file: &'a CssmFile,
    quantizer: DepthQuantizer,
    /// Depth-map index of every texel (inverse of the sequence).
    map_of_texel: Vec<u32>,
    /// Texel index of every atlas cell, `u32::MAX` where undefined.
    grid: Vec<u32>,
    /// Steps of the GPU query's search over one pixel's runs ([`QueryWork::search_steps`]).
    search_steps: u32,
    /// Query options.
    pub options: QueryOptions,
}

const NONE: u32 = u32::MAX;

impl<'a> VisibilityQuery<'a> {
    /// Prepares queries over `file` (which must have passed `cssm::validate`).
    pub fn new(file: &'a CssmFile, options: QueryOptions) -> Self {
        let r = file.params.atlas_resolution as usize;
        let mut grid = vec![NONE; r * r];
        for (i, t) in file.texels.iter().enumerate() {
            grid[t.y as usize * r + t.x as usize] = i as u32;
        }
        let mut map_of_texel = vec![0; file.texels.len()];
        for (k, &t) in file.sequence.iter().enumerate() {
            map_of_texel[t as usize] = k as u32;
        }
        Self {
            file,
            quantizer: DepthQuantizer::new(file.params.near, file.params.far),
            map_of_texel,
            grid,
            search_steps: file.runs.search_steps(),
            options,
        }
    }

    /// The file queried.
    pub fn file(&self) -> &CssmFile {
        self.file
    }

    /// Atlas coordinates (texel units) of the point with barycentric coordinates `bary` on
    /// scene triangle `triangle`; `None` for a triangle index the file does not have.
    pub fn atlas_point(&self, triangle: usize, bary: [f32; 3]) -> Option<Vec2> {
        let uv = self.file.triangle_uvs.get(triangle)?;
        Some(
            Vec2::from(uv[0]) * bary[0] + Vec2::from(uv[1]) * bary[1] + Vec2::from(uv[2]) * bary[2],
        )
    }

    /// The texel standing for the point with barycentric coordinates `bary` on scene triangle
    /// `triangle`: the atlas cell under its atlas coordinates, or, where that cell is undefined
    /// (chart borders), the nearest defined cell of the same chart within two texels.
    pub fn texel_at(&self, triangle: usize, bary: [f32; 3]) -> Option<u32> {
        self.texel_at_point(self.atlas_point(triangle, bary)?)
    }

    /// Texel of the atlas cell `(x, y)`; `None` outside the atlas or where the cell is
    /// undefined.
    pub fn cell(&self, x: i64, y: i64) -> Option<u32> {
        let r = self.file.params.atlas_resolution as i64;
        if x < 0 || y < 0 || x >= r || y >= r {
            return None;
        }
        Some(self.grid[(y * r + x) as usize]).filter(|&t| t != NONE)
    }

    /// [`Self::texel_at`] for atlas coordinates `p` (texel units): the cell under `p`, or the
    /// nearest defined cell within two texels.
    pub fn texel_at_point(&self, p: Vec2) -> Option<u32> {
        self.texel_at_point_counted(p, Site::default(), &mut QueryWork::default())
    }

    /// Reads atlas cell `(x, y)` as [`Self::cell`], telling `tally` of the read where the GPU
    /// makes one (inside the atlas).
    fn cell_counted(&self, x: i64, y: i64, site: Site, tally: &mut impl QueryTally) -> Option<u32> {
        let r = self.file.params.atlas_resolution as i64;
        if x < 0 || y < 0 || x >= r || y >= r {
            return None;
        }
        tally.load(site, Load::GridCell((y * r + x) as u32));
        self.cell(x, y)
    }

    fn texel_at_point_counted(
        &self,
        p: Vec2,
        at: Site,
        tally: &mut impl QueryTally,
    ) -> Option<u32> {
        let finding = Site {
            finding: 1,
            sender: 0,
            ..at
        };
        // Nothing within two texels of a point this far off the page (a NaN fails too); the
        // cell arithmetic below stays far from overflow.
        let r = self.file.params.atlas_resolution as f32;
        let near_page = -3.0..=r + 3.0;
        if !(near_page.contains(&p.x) && near_page.contains(&p.y)) {
            return None;
        }
        let (cx, cy) = (p.x.floor() as i64, p.y.floor() as i64);
        if let Some(direct) = self.cell_counted(cx, cy, finding, tally) {
            return Some(direct);
        }
        // Chart of the triangle: the chart of any defined texel near its atlas footprint.
        let mut best: Option<(f32, u32)> = None;
        for dy in -2..=2 {
            for dx in -2..=2 {
                let neighbour = Site {
                    tap: (1 + (dy + 2) * 5 + (dx + 2)) as u8,
                    ..finding
                };
                let Some(t) = self.cell_counted(cx + dx, cy + dy, neighbour, tally) else {
                    continue;
                };
                let centre = Vec2::new((cx + dx) as f32 + 0.5, (cy + dy) as f32 + 0.5);
                let d = centre.distance_squared(p);
                if best.is_none_or(|(bd, _)| d < bd) {
                    best = Some((d, t));
                }
            }
        }
        best.map(|(_, t)| t)
    }

    /// Quantised depth stored for `texel` at cube-map `pixel`.
    #[inline]
    pub fn depth_code(&self, texel: u32, pixel: u32) -> u16 {
        self.file
            .runs
            .lookup(self.map_of_texel[texel as usize], pixel)
    }

    /// Centre of `texel`'s cube map.
    pub fn cube_centre(&self, texel: u32) -> Vec3 {
        let t = &self.file.texels[texel as usize];
        t.pos() + t.nrm() * self.file.params.near
    }

    /// Fraction of `p_i` visible from the cube map of `texel` (0 or 1 without PCF).
    ///
    /// A receiver behind the sender's tangent plane (by more than the near distance) is
    /// occluded: light leaves a surface on its front side. A receiver on or above the plane but
    /// below the cube centre's horizon (a coplanar neighbour) is looked up along the plane,
    /// where the bake cast the straddling pixels' rays.
    pub fn visibility(&self, texel: u32, p_i: Vec3) -> f32 {
        self.visibility_oriented(texel, p_i, None)
    }

    /// [`Self::visibility`] for a receiver whose surface normal `n_i` is known. Each pixel then
    /// compares its stored depth with the depth at which *its own* ray meets the receiver's
    /// tangent plane, not with the receiver's depth (receiver-plane depth, after Isidoro 2006):
    /// a surface seen at a grazing angle spans a wide range of depths across one pixel, and
    /// without this the pixel's centre ray, hitting that surface nearer or farther, shadows it.
    pub fn visibility_oriented(&self, texel: u32, p_i: Vec3, n_i: Option<Vec3>) -> f32 {
        self.answer_oriented(texel, p_i, n_i).visible
    }

    /// [`Self::visibility_oriented`] with where the blocking pixels put the occluder
    /// ([`EndAnswer::nearness`]).
    pub fn answer_oriented(&self, texel: u32, p_i: Vec3, n_i: Option<Vec3>) -> EndAnswer {
        self.answer_oriented_counted(texel, p_i, n_i, Site::default(), &mut QueryWork::default())
    }

    /// [`Self::answer_oriented`], telling `tally` of every load the GPU's `cssm_answer_texel`
    /// makes for it, at `at` (its end and sender slot; the taps and steps filled in here).
    pub fn answer_oriented_counted(
        &self,
        texel: u32,
        p_i: Vec3,
        n_i: Option<Vec3>,
        at: Site,
        tally: &mut impl QueryTally,
    ) -> EndAnswer {
        tally.load(at, Load::Texel(texel));
        let n = self.file.params.cube_resolution;
        let t = &self.file.texels[texel as usize];
        let normal = t.nrm();
        let near = self.file.params.near;
        if (p_i - t.pos()).dot(normal) < -near {
            return EndAnswer::default();
        }
        let centre = self.cube_centre(texel);
        // The texel's own pixel grid (`cube::PixelGrid`), in pixels.
        let offset = self.file.pixel_grid.offset(t.x, t.y);
        // The cube map's own frame (`cube::CubeFrame`): the pixel directions and the faces are
        // in it, so the lookup direction and both normals go into it; dot products between
        // world vectors stay as they are.
        let frame = self.file.cube_frame;
        let cube_normal = frame.to_cube(normal);
        let cube_n_i = n_i.map(|n_i| (n_i, frame.to_cube(n_i)));
        let mut d = p_i - centre;
        let below = d.dot(normal);
        if below < 0.0 {
            d -= normal * below;
        }
        if d.length_squared() < near * near * 1e-6 {
            return EndAnswer {
                visible: 1.0,
                nearness: 0.0,
            };
        }
        let (face, u, v, depth) = cube::project(frame.to_cube(d));
        let bias =
            self.options.bias_near * self.file.params.near + self.options.bias_relative * depth;
        // Depth of the receiver along the ray the bake cast for `pixel`.
        let receiver_depth = |pixel: u32| -> f32 {
            let Some((n_i, cube_n_i)) = cube_n_i else {
                return depth;
            };
            let (ray, scale) = cube::cast_direction_at(n, pixel, cube_normal, offset);
            let denom = ray.dot(cube_n_i);
            if denom.abs() < 1e-4 {
                return depth;
            }
            let along = (p_i - centre).dot(n_i) / denom * scale;
            if along.is_finite() && along > 0.0 {
                along.clamp(0.5 * depth, 1.5 * depth)
            } else {
                depth
            }
        };
        // (visible, nearness) of PCF tap `tap`, at `pixel`.
        let map = self.map_of_texel[texel as usize];
        let runs = &self.file.runs;
        let mut test = |tap: u8, pixel: u32| -> (f32, f32) {
            if cube::pixel_is_dont_care_at(n, pixel, cube_normal, offset) {
                return (0.0, 0.0);
            }
            // The GPU's search (`cssm_lookup_slot`), load by load.
            let site = Site { tap, ..at };
            let slot = runs.slot(map, pixel);
            tally.load(site, Load::Offsets(slot));
            tally.lookup(site, slot, map % crate::cssm::SEGMENT_MAPS);
            let mut step = 0;
            let code = runs.lookup_traced(map, pixel, self.search_steps, |run| {
                step += 1;
                tally.load(Site { step, ..site }, Load::Probe(run));
            });
            let stored = self.quantizer.depth(code);
            let receiver = receiver_depth(pixel);
            if stored >= receiver - bias {
                (1.0, 0.0)
            } else {
                (0.0, (1.0 - stored / receiver).clamp(0.0, 1.0))
            }
        };
        if !self.options.pcf {
            let (visible, nearness) = test(0, cube::pixel_index_at(n, face, u, v, offset));
            return EndAnswer { visible, nearness };
        }
        // Bilinear weights over the 2x2 pixel centres around the projection, clamped to the face.
        let fx = ((u + 1.0) * 0.5 * n as f32 - 0.5 - offset.x).clamp(0.0, n as f32 - 1.0);
        let fy = ((v + 1.0) * 0.5 * n as f32 - 0.5 - offset.y).clamp(0.0, n as f32 - 1.0);
        let (x0, y0) = (fx.floor() as u32, fy.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(n - 1), (y0 + 1).min(n - 1));
        let (wx, wy) = (fx - x0 as f32, fy - y0 as f32);
        let base = face * n * n;
        let (t00, t10) = (test(0, base + y0 * n + x0), test(1, base + y0 * n + x1));
        let (t01, t11) = (test(2, base + y1 * n + x0), test(3, base + y1 * n + x1));
        let bilinear = |a: f32, b: f32, c: f32, d: f32| {
            (1.0 - wy) * ((1.0 - wx) * a + wx * b) + wy * ((1.0 - wx) * c + wx * d)
        };
        EndAnswer {
            visible: bilinear(t00.0, t10.0, t01.0, t11.0),
            nearness: bilinear(t00.1, t10.1, t01.1, t11.1),
        }
    }

    /// Whether `p_i` is visible from the cube map of `texel` (PCF: at least half visible).
    pub fn visible(&self, texel: u32, p_i: Vec3) -> bool {
        self.visibility(texel, p_i) >= 0.5
    }

    /// Texels standing for the surface point (`triangle`, `bary`) with their weights: the 2x2
    /// atlas texels around its atlas coordinates with bilinear weights, restricted to the chart
    /// of the texel under it and renormalised; just that texel when sender filtering is off.
    pub fn sender_texels(&self, triangle: usize, bary: [f32; 3]) -> Vec<(u32, f32)> {
        match self.atlas_point(triangle, bary) {
            Some(p) => self.sender_texels_at(p),
            None => Vec::new(),
        }
    }

    /// [`Self::sender_texels`] for atlas coordinates `p` (texel units).
    pub fn sender_texels_at(&self, p: Vec2) -> Vec<(u32, f32)> {
        self.sender_slots_at(p, Site::default(), &mut QueryWork::default())
            .map(|slots| {
                slots
                    .into_iter()
                    .filter(|&(t, w)| t != NONE && w > 0.0)
                    .collect()
            })
            .unwrap_or_default()
    }

    /// [`Self::sender_texels_at`] as the GPU holds them (`CssmSenders`): the 2x2 filter's four
    /// slots in order, a missing texel as `(u32::MAX, 0.0)`; `None` when no texel stands for
    /// the point. Every load the GPU's `cssm_senders_at` makes is told to `tally`, at `at`
    /// (its end).
    pub fn sender_slots_at(
        &self,
        p: Vec2,
        at: Site,
        tally: &mut impl QueryTally,
    ) -> Option<[(u32, f32); 4]> {
        let centre = self.texel_at_point_counted(p, at, tally)?;
        let mut slots = [(NONE, 0.0); 4];
        slots[0] = (centre, 1.0);
        if !self.options.sender_filter {
            return Some(slots);
        }
        let finding = Site { finding: 1, ..at };
        tally.load(Site { tap: 26, ..finding }, Load::TexelChart(centre));
        let chart = self.file.texels[centre as usize].chart;
        let r = self.file.params.atlas_resolution as i64;
        let (fx, fy) = (p.x - 0.5, p.y - 0.5);
        let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
        let (wx, wy) = (fx - x0 as f32, fy - y0 as f32);
        let mut filtered = [(NONE, 0.0); 4];
        let mut total = 0.0;
        for (slot, (dx, dy, w)) in [
            (0, 0, (1.0 - wx) * (1.0 - wy)),
            (1, 0, wx * (1.0 - wy)),
            (0, 1, (1.0 - wx) * wy),
            (1, 1, wx * wy),
        ]
        .into_iter()
        .enumerate()
        {
            let (x, y) = (x0 + dx, y0 + dy);
            if x < 0 || y < 0 || x >= r || y >= r || w <= 0.0 {
                continue;
            }
            let tap = Site {
                sender: 1 + slot as u8,
                ..finding
            };
            tally.load(tap, Load::GridCell((y * r + x) as u32));
            let t = self.grid[(y * r + x) as usize];
            if t == NONE {
                continue;
            }
            tally.load(Site { tap: 1, ..tap }, Load::TexelChart(t));
            if self.file.texels[t as usize].chart == chart {
                filtered[slot] = (t, w);
                total += w;
            }
        }
        if total <= 0.0 {
            return Some(slots);
        }
        for (_, w) in filtered.iter_mut() {
            *w /= total;
        }
        Some(filtered)
    }

    /// Fraction of `p_i` visible from the surface point (`triangle`, `bary`), or `None` when
    /// no texel stands for that point.
    pub fn visibility_from_surface(
        &self,
        triangle: usize,
        bary: [f32; 3],
        p_i: Vec3,
        n_i: Option<Vec3>,
    ) -> Option<f32> {
        self.visibility_from_surface_counted(triangle, bary, p_i, n_i, &mut QueryWork::default())
    }

    /// [`Self::visibility_from_surface`], telling `tally` of every load the GPU's
    /// `cssm_visibility` makes for the same query.
    pub fn visibility_from_surface_counted(
        &self,
        triangle: usize,
        bary: [f32; 3],
        p_i: Vec3,
        n_i: Option<Vec3>,
        tally: &mut impl QueryTally,
    ) -> Option<f32> {
        let uv = self.atlas_point(triangle, bary)?;
        let at = Site::default();
        tally.load(
            Site { finding: 1, ..at },
            Load::TriangleUvs(triangle as u32),
        );
        let senders = self.sender_slots_at(uv, at, tally)?;
        self.answer_from_senders_counted(&senders, p_i, n_i, at, tally)
            .map(|answer| answer.visible)
    }

    /// [`Self::visibility_from_surface`] for the surface point at atlas coordinates `p`
    /// (texel units), as a G-buffer stores it.
    pub fn visibility_from_atlas(&self, p: Vec2, p_i: Vec3, n_i: Option<Vec3>) -> Option<f32> {
        self.visibility_from_senders(&self.sender_texels_at(p), p_i, n_i)
    }

    /// Fraction of the way between two surface points that is clear: `a` (its
    /// [`Self::sender_texels_at`], position, normal) and `b` likewise. With
    /// [`QueryOptions::both_ends`], `a`'s cube maps' answer for `b` and `b`'s for `a`
    /// combined by [`combine_ends`] (see the module docs); else, or when `b` has no texels,
    /// `a`'s alone; `b`'s alone when `a` has none; `None` when neither has.
    pub fn visibility_between(
        &self,
        a: &[(u32, f32)],
        p_a: Vec3,
        n_a: Vec3,
        b: &[(u32, f32)],
        p_b: Vec3,
        n_b: Vec3,
    ) -> Option<f32> {
        self.visibility_between_counted(a, p_a, n_a, b, p_b, n_b, &mut QueryWork::default())
    }

    /// [`Self::visibility_between`], telling `tally` of every load the GPU's
    /// `cssm_visibility_between` makes (end 0 `a`'s cube maps, end 1 `b`'s). `a` and `b` may be
    /// sender lists or [`Self::sender_slots_at`]'s slots.
    #[allow(clippy::too_many_arguments)]
    pub fn visibility_between_counted(
        &self,
        a: &[(u32, f32)],
        p_a: Vec3,
        n_a: Vec3,
        b: &[(u32, f32)],
        p_b: Vec3,
        n_b: Vec3,
        tally: &mut impl QueryTally,
    ) -> Option<f32> {
        let forward = self.answer_from_senders_counted(a, p_b, Some(n_b), Site::default(), tally);
        if !self.options.both_ends
            && let Some(f) = forward
        {
            return Some(f.visible);
        }
        let backward = self.answer_from_senders_counted(
            b,
            p_a,
            Some(n_a),
            Site {
                end: 1,
                ..Site::default()
            },
            tally,
        );
        match (forward, backward) {
            (Some(f), Some(r)) => Some(combine_ends(f, r)),
            (f, r) => f.or(r).map(|answer| answer.visible),
        }
    }

    /// [`Self::visibility_between`] for two points given as (`triangle`, `bary`) with their
    /// positions and normals, as `cssm check` draws them.
    pub fn visibility_between_surfaces(
        &self,
        (triangle_a, bary_a): (usize, [f32; 3]),
        p_a: Vec3,
        n_a: Vec3,
        (triangle_b, bary_b): (usize, [f32; 3]),
        p_b: Vec3,
        n_b: Vec3,
    ) -> Option<f32> {
        let a = self.sender_texels(triangle_a, bary_a);
        let b = if self.options.both_ends {
            self.sender_texels(triangle_b, bary_b)
        } else {
            Vec::new()
        };
        self.visibility_between(&a, p_a, n_a, &b, p_b, n_b)
    }

    /// Fraction of `p_i` visible from a surface point whose [`Self::sender_texels_at`] are
    /// `senders` (`None` when there are none): the weighted mean of their cube maps' answers.
    /// A receiver that asks many queries (a final-gather pixel) finds its senders once.
    pub fn visibility_from_senders(
        &self,
        senders: &[(u32, f32)],
        p_i: Vec3,
        n_i: Option<Vec3>,
    ) -> Option<f32> {
        self.answer_from_senders(senders, p_i, n_i)
            .map(|answer| answer.visible)
    }

    /// [`Self::visibility_from_senders`] with where the blocking pixels put the occluder: the
    /// weighted sum of the senders' [`Self::answer_oriented`].
    pub fn answer_from_senders(
        &self,
        senders: &[(u32, f32)],
        p_i: Vec3,
        n_i: Option<Vec3>,
    ) -> Option<EndAnswer> {
        self.answer_from_senders_counted(
            senders,
            p_i,
            n_i,
            Site::default(),
            &mut QueryWork::default(),
        )
    }

    /// [`Self::answer_from_senders`], telling `tally` of every load at `at` (its end): the
    /// GPU's `cssm_answer_senders`. `senders` may be [`Self::sender_slots_at`]'s four slots,
    /// whose empty ones are skipped as the GPU skips them (each sender's loads are then sited
    /// at its slot), or [`Self::sender_texels_at`]'s list.
    pub fn answer_from_senders_counted(
        &self,
        senders: &[(u32, f32)],
        p_i: Vec3,
        n_i: Option<Vec3>,
        at: Site,
        tally: &mut impl QueryTally,
    ) -> Option<EndAnswer> {
        let mut asked = senders
            .iter()
            .enumerate()
            .filter(|&(_, &(t, w))| t != NONE && w > 0.0)
            .peekable();
        asked.peek()?;
        Some(asked.fold(EndAnswer::default(), |sum, (slot, &(t, w))| {
            let sender = Site {
                sender: slot as u8,
                ..at
            };
            let answer = self.answer_oriented_counted(t, p_i, n_i, sender, tally);
            EndAnswer {
                visible: sum.visible + w * answer.visible,
                nearness: sum.nearness + w * answer.nearness,
            }
        }))
    }
}
