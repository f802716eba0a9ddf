//! Building a [`SceneBvh`] from a scene (obvhs' compressed wide BVH over slightly widened
//! triangle boxes), and what it tells about the triangles it was built from.

use std::time::Duration;

use cssm_formats::Scene;
use glam::{Vec3, Vec3A};
use obvhs::{BvhBuildParams, aabb::Aabb, cwbvh::builder::build_cwbvh, triangle::Triangle};

use super::SceneBvh;

/// Widening of every triangle's box in the BVH, relative to the scene's largest coordinate: some
/// thousand times the rounding of a ray/box test.
const BOX_PAD: f32 = 1.0 / 16384.0;

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
}
