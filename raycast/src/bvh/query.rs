//! Ray queries through a [`SceneBvh`]: one traversal per ray with the watertight test at the
//! leaves, for closest hits, segment tests and the first and second hits of the depth cube maps
//! (§3.2.1).

use glam::{UVec2, Vec3, Vec3A};
use obvhs::{ray::Ray, traverse};

use super::{DualHit, FrontHit, HitReducer, SceneBvh, WatertightRay, reduce_hits};

impl SceneBvh {
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
