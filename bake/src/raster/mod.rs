//! A second renderer of the depth cube maps (§3.2.1), for scenes of few triangles: instead of one
//! BVH traversal per pixel, it goes triangle by triangle and face by face, finds the pixels whose
//! ray may meet the triangle (a conservative scanline cover of its projection), and runs the BVH's
//! own watertight ray/triangle test ([`WatertightRay`]) on those rays only. Each pixel's hits are
//! reduced by the BVH's own order-independent [`HitReducer`], so the intervals — and the `.cssm`
//! file — are byte-identical to [`cubemap::render`]'s (the tests in `tests.rs` and
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
//!
//! - [`RasterScene`] (here): the triangles as the rasteriser reads them.
//! - `render`: [`render()`], one texel's cube map, with the per-thread buffers it reuses.
//! - `cover`: the conservative cover of a triangle on a cube face, scanned row by row.
//!
//! [`WatertightRay`]: crate::raycast::WatertightRay
//! [`HitReducer`]: crate::raycast::HitReducer
//! [`cubemap::render`]: crate::cubemap::render
//! [`cube::cast_direction`]: cssm_formats::cube::cast_direction

mod cover;
mod render;
#[cfg(test)]
mod tests;

use glam::Vec3;

use crate::raycast::SceneBvh;

pub use render::render;

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
