//! The CPU reference visibility query over a baked CSSM (§3.2.2).
//!
//! To test whether a point `p_i` is visible from the surface point `p_j`, take the depth cube
//! map of the texel that stands for `p_j`, project `p_i` into it (pixel `q`, depth `q_z`) and
//! decode the stored depth `z_xy` of that pixel: `p_i` is occluded when `z_xy < q_z - bias`.
//! Pixels wholly behind `p_j`'s tangent plane hold "don't care" depths and answer *occluded*:
//! light leaves a surface only on its front side. Percentage-closer filtering (§3.2.2, "the same
//! generalized PCF used with CSMs") blends the tests of the 2x2 pixels around the projection.
//!
//! The GPU query of the runtime computes exactly this; this module is its reference.

use glam::{Vec2, Vec3};

use crate::{
    cssm::CssmFile,
    cube::{self, DepthQuantizer},
};

/// Options of a query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QueryOptions {
    /// Constant depth bias, as a multiple of the bake's near distance.
    pub bias_near: f32,
    /// Depth bias proportional to the query depth.
    pub bias_relative: f32,
    /// Blend the 2x2 pixels around the projection (PCF) instead of one pixel.
    pub pcf: bool,
}

impl Default for QueryOptions {
    fn default() -> Self {
        Self {
            bias_near: 1.0,
            bias_relative: 0.0,
            pcf: false,
        }
    }
}

/// Answers visibility queries from a baked CSSM without decompressing it.
pub struct VisibilityQuery<'a> {
    file: &'a CssmFile,
    quantizer: DepthQuantizer,
    /// Depth-map index of every texel (inverse of the sequence).
    map_of_texel: Vec<u32>,
    /// Texel index of every atlas cell, `u32::MAX` where undefined.
    grid: Vec<u32>,
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
            options,
        }
    }

    /// The file queried.
    pub fn file(&self) -> &CssmFile {
        self.file
    }

    /// The texel standing for the point with barycentric coordinates `bary` on scene triangle
    /// `triangle`: the atlas cell under its atlas coordinates, or, where that cell is undefined
    /// (chart borders), the nearest defined cell of the same chart within two texels.
    pub fn texel_at(&self, triangle: usize, bary: [f32; 3]) -> Option<u32> {
        let uv = self.file.triangle_uvs.get(triangle)?;
        let p =
            Vec2::from(uv[0]) * bary[0] + Vec2::from(uv[1]) * bary[1] + Vec2::from(uv[2]) * bary[2];
        let r = self.file.params.atlas_resolution as i64;
        let (cx, cy) = (p.x.floor() as i64, p.y.floor() as i64);
        let cell = |x: i64, y: i64| -> u32 {
            if x < 0 || y < 0 || x >= r || y >= r {
                NONE
            } else {
                self.grid[(y * r + x) as usize]
            }
        };
        let direct = cell(cx, cy);
        if direct != NONE {
            return Some(direct);
        }
        // Chart of the triangle: the chart of any defined texel near its atlas footprint.
        let mut best: Option<(f32, u32)> = None;
        for dy in -2..=2 {
            for dx in -2..=2 {
                let t = cell(cx + dx, cy + dy);
                if t == NONE {
                    continue;
                }
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
    pub fn visibility(&self, texel: u32, p_i: Vec3) -> f32 {
        let n = self.file.params.cube_resolution;
        let normal = self.file.texels[texel as usize].nrm();
        let d = p_i - self.cube_centre(texel);
        if d == Vec3::ZERO {
            return 1.0;
        }
        let (face, u, v, depth) = cube::project(d);
        let bias =
            self.options.bias_near * self.file.params.near + self.options.bias_relative * depth;
        let test = |pixel: u32| -> f32 {
            if cube::pixel_is_dont_care(n, pixel, normal) {
                return 0.0;
            }
            let stored = self.quantizer.depth(self.depth_code(texel, pixel));
            if stored >= depth - bias { 1.0 } else { 0.0 }
        };
        if !self.options.pcf {
            return test(cube::pixel_index(n, face, u, v));
        }
        // Bilinear weights over the 2x2 pixel centres around the projection, clamped to the face.
        let fx = ((u + 1.0) * 0.5 * n as f32 - 0.5).clamp(0.0, n as f32 - 1.0);
        let fy = ((v + 1.0) * 0.5 * n as f32 - 0.5).clamp(0.0, n as f32 - 1.0);
        let (x0, y0) = (fx.floor() as u32, fy.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(n - 1), (y0 + 1).min(n - 1));
        let (wx, wy) = (fx - x0 as f32, fy - y0 as f32);
        let base = face * n * n;
        let at = |x: u32, y: u32| test(base + y * n + x);
        (1.0 - wy) * ((1.0 - wx) * at(x0, y0) + wx * at(x1, y0))
            + wy * ((1.0 - wx) * at(x0, y1) + wx * at(x1, y1))
    }

    /// Whether `p_i` is visible from the cube map of `texel` (PCF: at least half visible).
    pub fn visible(&self, texel: u32, p_i: Vec3) -> bool {
        self.visibility(texel, p_i) >= 0.5
    }
}
