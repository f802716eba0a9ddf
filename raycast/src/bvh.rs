//! Exact ray casting against the scene with obvhs: the reference for every visibility answer,
//! and the tool the bake renders the depth cube maps with (§3.2.1).

use std::time::Duration;

use cssm_formats::Scene;
use glam::{UVec2, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    cwbvh::{CwBvh, builder::build_cwbvh_from_tris},
    ray::Ray,
    traverse,
    triangle::Triangle,
};

/// A BVH over the scene's triangles.
pub struct SceneBvh {
    bvh: CwBvh,
    /// Triangle corners in BVH primitive order (so no indirection while traversing).
    triangles: Vec<[Vec3; 3]>,
    /// Geometric normal (not normalised; its winding side is the front) of every triangle, by
    /// scene index.
    normals: Vec<Vec3>,
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
#[derive(Clone, Copy)]
struct WatertightRay {
    origin: Vec3,
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f32,
    sy: f32,
    sz: f32,
}

impl WatertightRay {
    fn new(origin: Vec3, dir: Vec3) -> Self {
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
            kx,
            ky,
            kz,
            sx: d[kx] / d[kz],
            sy: d[ky] / d[kz],
            sz: 1.0 / d[kz],
        }
    }

    /// Ray parameter of the hit with `tri`, `INFINITY` for a miss. Points on a shared edge hit
    /// both triangles (the caller merges equal distances).
    #[inline]
    fn intersect(&self, tri: &[Vec3; 3]) -> f32 {
        let o = self.origin;
        let a = (tri[0] - o).to_array();
        let b = (tri[1] - o).to_array();
        let c = (tri[2] - o).to_array();
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        if u == 0.0 || v == 0.0 || w == 0.0 {
            // Fall back to double precision on the edge, as the paper does.
            u = (cx as f64 * by as f64 - cy as f64 * bx as f64) as f32;
            v = (ax as f64 * cy as f64 - ay as f64 * cx as f64) as f32;
            w = (bx as f64 * ay as f64 - by as f64 * ax as f64) as f32;
        }
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return f32::INFINITY;
        }
        let det = u + v + w;
        if det == 0.0 {
            return f32::INFINITY;
        }
        let t = (u * self.sz * a[kz] + v * self.sz * b[kz] + w * self.sz * c[kz]) / det;
        if t.is_finite() { t } else { f32::INFINITY }
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
        let bvh = build_cwbvh_from_tris(
            &tris,
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

    /// First and second hit of `origin + t * dir`, `t > 0`; hits closer than `separation` to the
    /// first count as the first (a ray through a shared edge meets both triangles at one `t`).
    /// One traversal keeps the two nearest distinct hits and prunes beyond the second.
    pub fn dual_hit(&self, origin: Vec3, dir: Vec3, separation: f32) -> DualHit {
        let (mut first, mut second) = (f32::INFINITY, f32::INFINITY);
        self.for_each_hit(origin, dir, 0.0, f32::INFINITY, |t, _| {
            if t < first {
                if first - t > separation {
                    second = first;
                }
                first = t;
                // Keep second clear of the new first.
                if second - first <= separation {
                    second = f32::INFINITY;
                }
            } else if t - first > separation && t < second {
                second = t;
            }
            second
        });
        DualHit { first, second }
    }

    /// Like [`SceneBvh::dual_hit`], but the second hit is the nearest *front-facing* one (its
    /// triangle's front side towards the ray's origin) beyond the first. Back-facing surfaces
    /// between the two (the far side of a wall, of a column, of the teapot) are skipped: a
    /// point on them faces away from the origin, so it can exchange no light with it (its
    /// cosine is zero) and whether it is visible never matters. The result also says whether the
    /// first hit faces the origin.
    pub fn front_dual_hit(&self, origin: Vec3, dir: Vec3, separation: f32) -> FrontHit {
        let (mut first, mut second) = (f32::INFINITY, f32::INFINITY);
        let mut first_faces = false;
        self.for_each_hit(origin, dir, 0.0, f32::INFINITY, |t, triangle| {
            let faces = self.normals[triangle as usize].dot(dir) < 0.0;
            if t < first {
                if first_faces && first - t > separation {
                    second = first;
                }
                // Hits within `separation` are one surface: it faces the origin if any does.
                first_faces = faces || (first_faces && first - t <= separation);
                first = t;
                if second - first <= separation {
                    second = f32::INFINITY;
                }
            } else if t - first <= separation {
                first_faces |= faces;
            } else if faces && t < second {
                second = t;
            }
            second
        });
        FrontHit {
            first,
            first_faces,
            second,
        }
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
}
