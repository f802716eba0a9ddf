//! Exact ray casting against the scene with obvhs: the reference for every visibility answer,
//! and the tool the bake renders the depth cube maps with (§3.2.1).
//!
//! - [`SceneBvh`] and the answers it gives ([`DualHit`], [`FrontHit`]) are defined here; `build`
//!   builds it from a scene, `query` casts rays through it.
//! - `watertight`: the ray/triangle test every renderer of the cube maps shares
//!   ([`WatertightRay`], and [`SharedAxisRays`] for many rays from one origin at once).
//! - `reduce`: a ray's hits, met in any order, reduced to its first and second hit
//!   ([`HitReducer`], [`reduce_hits`]).

mod build;
mod query;
mod reduce;
#[cfg(test)]
mod tests;
mod watertight;

use glam::Vec3;
use obvhs::cwbvh::CwBvh;

pub use build::scene_triangles;
pub use reduce::{HitReducer, reduce_hits};
pub use watertight::{SharedAxisRays, WatertightRay};

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
