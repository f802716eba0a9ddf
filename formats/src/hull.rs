//! Whether convex hulls overlap: the limit of moving objects (§3.3, "visibility tests with
//! moving objects are possible as long as the convex hulls of the individual objects do not
//! overlap"), found so that it is reported instead of silently answering wrong.
//!
//! The test is GJK (Gilbert, Johnson and Keerthi 1988) on the Minkowski difference of two point
//! sets, whose support function is a maximum over the points, so no hull is ever built.

use glam::{Affine3A, Vec3};

use crate::{ObjectKind, Scene};

/// The point of `points` furthest along `d`.
fn support(points: &[Vec3], d: Vec3) -> Vec3 {
    let mut best = points[0];
    let mut best_dot = best.dot(d);
    for &p in &points[1..] {
        let dot = p.dot(d);
        if dot > best_dot {
            best = p;
            best_dot = dot;
        }
    }
    best
}

/// Whether the convex hulls of `a` and `b` (non-empty point sets) intersect. Touching hulls may
/// answer either way; callers shrink one set by a margin where touching is allowed.
///
/// ```
/// use cssm_formats::hull::hulls_intersect;
/// use glam::Vec3;
/// let cube = |c: Vec3| -> Vec<Vec3> {
///     (0..8).map(|i| c + Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, (i >> 2) as f32)).collect()
/// };
/// assert!(hulls_intersect(&cube(Vec3::ZERO), &cube(Vec3::splat(0.5))));
/// assert!(!hulls_intersect(&cube(Vec3::ZERO), &cube(Vec3::new(1.5, 0.2, 0.0))));
/// ```
///
/// # Panics
/// If either set is empty.
pub fn hulls_intersect(a: &[Vec3], b: &[Vec3]) -> bool {
    let difference = |d: Vec3| support(a, d) - support(b, -d);
    let mut d = a[0] - b[0];
    if d.length_squared() < 1e-30 {
        return true;
    }
    let mut simplex: Vec<Vec3> = vec![difference(d)];
    d = -simplex[0];
    // GJK converges in a few iterations; the bound only guards against cycling in rounding.
    for _ in 0..64 {
        if d.length_squared() < 1e-30 {
            return true;
        }
        let p = difference(d);
        if p.dot(d) < 0.0 {
            // The support point does not pass the origin: a separating plane.
            return false;
        }
        simplex.push(p);
        match nearest_simplex(&mut simplex) {
            Some(next) => d = next,
            None => return true,
        }
    }
    true
}

/// Reduces `simplex` (its last point the newest) to the sub-simplex nearest the origin and
/// returns the direction from it towards the origin, or `None` when the simplex contains the
/// origin.
fn nearest_simplex(simplex: &mut Vec<Vec3>) -> Option<Vec3> {
    let same = |a: Vec3, b: Vec3| a.dot(b) > 0.0;
    match simplex.len() {
        2 => {
            let (a, b) = (simplex[1], simplex[0]);
            let (ab, ao) = (b - a, -a);
            if same(ab, ao) {
                Some(ab.cross(ao).cross(ab)).filter(|d| d.length_squared() > 0.0)
            } else {
                *simplex = vec![a];
                Some(ao)
            }
        }
        3 => {
            let (a, b, c) = (simplex[2], simplex[1], simplex[0]);
            let (ab, ac, ao) = (b - a, c - a, -a);
            let abc = ab.cross(ac);
            if same(abc.cross(ac), ao) {
                if same(ac, ao) {
                    *simplex = vec![c, a];
                    Some(ac.cross(ao).cross(ac))
                } else {
                    *simplex = vec![b, a];
                    nearest_simplex(simplex)
                }
            } else if same(ab.cross(abc), ao) {
                *simplex = vec![b, a];
                nearest_simplex(simplex)
            } else if same(abc, ao) {
                Some(abc)
            } else if abc.length_squared() == 0.0 {
                // Degenerate (collinear) triangle: keep the newest edge.
                *simplex = vec![b, a];
                nearest_simplex(simplex)
            } else {
                *simplex = vec![b, c, a];
                Some(-abc)
            }
        }
        _ => {
            let (a, b, c, d) = (simplex[3], simplex[2], simplex[1], simplex[0]);
            let (ab, ac, ad, ao) = (b - a, c - a, d - a, -a);
            let (abc, acd, adb) = (ab.cross(ac), ac.cross(ad), ad.cross(ab));
            // Orient each face normal away from the opposite vertex.
            let outward = |n: Vec3, away: Vec3| if n.dot(away) > 0.0 { -n } else { n };
            let abc = outward(abc, ad);
            let acd = outward(acd, ab);
            let adb = outward(adb, ac);
            if same(abc, ao) {
                *simplex = vec![c, b, a];
                return nearest_simplex(simplex);
            }
            if same(acd, ao) {
                *simplex = vec![d, c, a];
                return nearest_simplex(simplex);
            }
            if same(adb, ao) {
                *simplex = vec![b, d, a];
                return nearest_simplex(simplex);
            }
            None
        }
    }
}

/// Where the hulls of a posed scene's objects overlap (§3.3's limit).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HullOverlaps {
    /// Pairs of rigid objects (indices into `Scene::objects`, first < second) whose hulls
    /// overlap.
    pub rigid_pairs: Vec<(usize, usize)>,
    /// Per rigid object (index, count): how many triangles of the static part reach into its
    /// hull. The CSM cannot answer for a segment that starts on one of them.
    pub static_triangles: Vec<(usize, usize)>,
}

impl HullOverlaps {
    /// Whether nothing overlaps.
    pub fn is_empty(&self) -> bool {
        self.rigid_pairs.is_empty() && self.static_triangles.is_empty()
    }

    /// One line per overlap, naming the objects of `scene`.
    pub fn describe(&self, scene: &Scene) -> Vec<String> {
        let name = |o: usize| scene.objects[o].name.as_str();
        let mut lines: Vec<String> = self
            .rigid_pairs
            .iter()
            .map(|&(a, b)| {
                format!(
                    "the convex hulls of objects '{}' and '{}' overlap: visibility between them \
                     is unreliable (§3.3)",
                    name(a),
                    name(b)
                )
            })
            .collect();
        lines.extend(self.static_triangles.iter().map(|&(o, n)| {
            format!(
                "{n} triangles of the static scene reach into the convex hull of object '{}': \
                 its shadow map is unreliable for light leaving them (§3.3)",
                name(o)
            )
        }));
        lines
    }
}

/// Finds the overlaps of `scene`'s objects placed at `poses` (object-to-world, one per object;
/// `scene.objects[o].transform` is where they were loaded). Hulls that only touch (a box
/// resting on the floor) do not count: each rigid object's points are first drawn towards their
/// centre by `margin`, a fraction of the object's size (1e-3 is a good choice).
///
/// # Panics
/// If `poses` does not have one entry per object.
pub fn overlaps(scene: &Scene, poses: &[Affine3A], margin: f32) -> HullOverlaps {
    assert_eq!(poses.len(), scene.objects.len(), "one pose per object");
    let points_of = |o: usize, to: Affine3A| -> Vec<Vec3> {
        let object = &scene.objects[o];
        let mut points: Vec<Vec3> = object
            .triangles
            .clone()
            .flat_map(|t| scene.triangle(t as usize))
            .map(|p| to.transform_point3(p))
            .collect();
        points.sort_by(|a, b| a.to_array().partial_cmp(&b.to_array()).unwrap());
        points.dedup();
        points
    };
    let rigid: Vec<usize> = (0..scene.objects.len())
        .filter(|&o| scene.objects[o].kind == ObjectKind::Rigid)
        .collect();
    let shrunk: Vec<(usize, Vec<Vec3>, Vec3, Vec3)> = rigid
        .iter()
        .map(|&o| {
            let motion = poses[o] * scene.objects[o].transform.inverse();
            let points = points_of(o, motion);
            let (lo, hi) = points
                .iter()
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                    (lo.min(p), hi.max(p))
                });
            let centre = 0.5 * (lo + hi);
            let points: Vec<Vec3> = points
                .iter()
                .map(|&p| centre + (p - centre) * (1.0 - margin))
                .collect();
            (o, points, lo, hi)
        })
        .collect();
    let mut found = HullOverlaps::default();
    for (i, (a, pa, lo_a, hi_a)) in shrunk.iter().enumerate() {
        for (b, pb, lo_b, hi_b) in &shrunk[i + 1..] {
            let boxes_meet = lo_a.cmple(*hi_b).all() && lo_b.cmple(*hi_a).all();
            if boxes_meet && hulls_intersect(pa, pb) {
                found.rigid_pairs.push((*a, *b));
            }
        }
    }
    for (o, points, lo, hi) in &shrunk {
        let count = scene
            .objects
            .iter()
            .filter(|s| s.kind == ObjectKind::Static)
            .flat_map(|s| s.triangles.clone())
            .filter(|&t| {
                let corners = scene.triangle(t as usize);
                let (t_lo, t_hi) = (
                    corners[0].min(corners[1]).min(corners[2]),
                    corners[0].max(corners[1]).max(corners[2]),
                );
                t_lo.cmple(*hi).all() && lo.cmple(t_hi).all() && hulls_intersect(points, &corners)
            })
            .count();
        if count > 0 {
            found.static_triangles.push((*o, count));
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SplitMix64, as uniform floats in `[0, 1)`.
    struct SplitMix64Like(u64);
    impl SplitMix64Like {
        fn next(&mut self) -> f32 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    fn cube(centre: Vec3, half: f32) -> Vec<Vec3> {
        (0..8)
            .map(|i| {
                centre
                    + half
                        * Vec3::new(
                            if i & 1 == 0 { -1.0 } else { 1.0 },
                            if i & 2 == 0 { -1.0 } else { 1.0 },
                            if i & 4 == 0 { -1.0 } else { 1.0 },
                        )
            })
            .collect()
    }

    #[test]
    fn gjk_agrees_with_the_boxes_separating_axes() {
        // Two axis-aligned cubes overlap exactly when their intervals overlap on every axis.
        let mut rng = SplitMix64Like(11);
        for _ in 0..5000 {
            let c = Vec3::new(rng.next() * 4.0, rng.next() * 4.0, rng.next() * 4.0) - 2.0;
            let (ha, hb) = (0.2 + rng.next(), 0.2 + rng.next());
            let a = cube(Vec3::ZERO, ha);
            let b = cube(c, hb);
            let gap = c.abs() - Vec3::splat(ha + hb);
            let truth = gap.max_element() < 0.0;
            // Leave out the near-touching cases, where rounding may go either way.
            if gap.max_element().abs() < 1e-4 {
                continue;
            }
            assert_eq!(
                hulls_intersect(&a, &b),
                truth,
                "centre {c}, halves {ha} {hb}"
            );
        }
    }

    #[test]
    fn a_point_inside_a_tetrahedron_and_one_outside() {
        let tetra = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z];
        assert!(hulls_intersect(&tetra, &[Vec3::splat(0.2)]));
        assert!(!hulls_intersect(&tetra, &[Vec3::splat(0.4)]));
        // A triangle crossing the tetrahedron with none of its corners inside.
        let triangle = [
            Vec3::new(-1.0, 0.1, 0.1),
            Vec3::new(2.0, 0.1, 0.1),
            Vec3::new(0.1, 0.1, -3.0),
        ];
        assert!(hulls_intersect(&tetra, &triangle));
    }
}
