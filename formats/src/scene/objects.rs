//! The objects of a scene: [`SceneObject`] (the static part, or one rigid `[[objects]]` entry)
//! as a contiguous range of the scene's merged triangles with its object-to-world transform, and
//! the lookups and checks over [`Scene::objects`].

use std::ops::Range;

use glam::Affine3A;

use super::Scene;
use super::animation::Animation;

/// What a [`SceneObject`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ObjectKind {
    /// The static part: the `mesh` of `scene.toml`, or every OBJ of a directory without one.
    Static,
    /// A rigid object that may move: one `[[objects]]` entry of `scene.toml`.
    Rigid,
}

/// How far [`Scene::posed`] may move an object: its vertices within this many times the
/// diagonal of the scene's bounding box (as loaded) from the box's centre.
pub const MAX_POSE_REACH: f32 = 1000.0;

/// `x` for a message: plain where that is short, in scientific notation where not (1e24 prints
/// 25 digits plainly).
fn number(x: f32) -> String {
    if x != 0.0 && !(1e-3..1e6).contains(&x.abs()) {
        format!("{x:.3e}")
    } else {
        format!("{}", (x * 1000.0).round() / 1000.0)
    }
}

/// Name of the static object of every scene ([`SceneObject::whole_static`] and
/// [`Scene::load`]). A rigid object may carry the same name; [`SceneObject::kind`] tells them
/// apart.
pub const STATIC_OBJECT_NAME: &str = "static";

/// One object of a [`Scene`]: which of the scene's merged triangles are its own, and where it
/// stands. Its vertices are already in world space in [`Scene::positions`]; `transform` is the
/// object-to-world transform they were placed with, so that a moving object can be re-placed.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneObject {
    /// The `[[objects]]` name, or [`STATIC_OBJECT_NAME`] for the static part.
    pub name: String,
    /// Static part or rigid object.
    pub kind: ObjectKind,
    /// Its triangles: indices into [`Scene::triangles`] (and [`Scene::triangle_materials`]),
    /// contiguous, never empty in a loaded scene, counting only the triangles kept at load
    /// (degenerate ones are dropped).
    pub triangles: Range<u32>,
    /// Object space to world space as loaded: scale, then rotation (X, then Y, then Z), then
    /// translation, from the `[[objects]]` entry; the identity for the static part.
    pub transform: Affine3A,
    /// How a rigid object moves over time (`[objects.animation]`), if it does; `None` for the
    /// static part and for an entry without one. [`SceneObject::pose_at`] applies it.
    pub animation: Option<Animation>,
}

/// The object-to-world transform of an `[[objects]]` entry: `scale`, then the rotation by the
/// XYZ Euler angles `rotation_deg` (applied X, then Y, then Z), then `translation`.
///
/// ```
/// use cssm_formats::scene::placement;
/// use glam::Vec3;
/// let t = placement(Vec3::new(10.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 90.0), 2.0);
/// assert!(t.transform_point3(Vec3::X).distance(Vec3::new(10.0, 2.0, 0.0)) < 1e-5);
/// ```
pub fn placement(translation: glam::Vec3, rotation_deg: glam::Vec3, scale: f32) -> Affine3A {
    let rotation = glam::Mat3::from_rotation_z(rotation_deg.z.to_radians())
        * glam::Mat3::from_rotation_y(rotation_deg.y.to_radians())
        * glam::Mat3::from_rotation_x(rotation_deg.x.to_radians());
    Affine3A::from_mat3_translation(
        rotation * glam::Mat3::from_diagonal(glam::Vec3::splat(scale)),
        translation,
    )
}

impl SceneObject {
    /// The static object of a scene that is nothing else: named [`STATIC_OBJECT_NAME`], identity
    /// transform, triangles `0..triangle_count`. For scenes built by hand (tests, generated
    /// scenes): `objects: vec![SceneObject::whole_static(triangles.len())]`.
    ///
    /// # Panics
    /// If `triangle_count` does not fit in a `u32`.
    pub fn whole_static(triangle_count: usize) -> SceneObject {
        let end = u32::try_from(triangle_count).expect("more than 2^32 - 1 triangles");
        SceneObject {
            name: STATIC_OBJECT_NAME.into(),
            kind: ObjectKind::Static,
            triangles: 0..end,
            transform: Affine3A::IDENTITY,
            animation: None,
        }
    }

    /// Object space to world space at `time` seconds of the scene's animation: its
    /// [`Animation::pose_at`], or [`SceneObject::transform`] for an object that does not move.
    pub fn pose_at(&self, time: f32) -> Affine3A {
        self.animation
            .as_ref()
            .map_or(self.transform, |a| a.pose_at(time))
    }
}

impl Scene {
    /// Index into [`Scene::objects`] of the object that triangle `triangle` belongs to (binary
    /// search over the ranges).
    ///
    /// # Panics
    /// If no object holds `triangle` (out of range, or the objects break their invariants).
    pub fn object_of(&self, triangle: usize) -> usize {
        let i = self
            .objects
            .partition_point(|o| (o.triangles.end as usize) <= triangle);
        match self.objects.get(i) {
            Some(o) if (o.triangles.start as usize) <= triangle => i,
            _ => panic!(
                "triangle {triangle} belongs to no object ({} triangles, {} objects)",
                self.triangles.len(),
                self.objects.len()
            ),
        }
    }

    /// Object `object`'s triangles alone as a scene of their own, every corner mapped by
    /// `transform` (the identity: as placed in the scene; `objects[object].transform.inverse()`:
    /// in the object's own space). Materials and texture coordinates are not kept.
    ///
    /// # Panics
    /// If `object` is not an index into [`Scene::objects`].
    pub fn object_mesh(&self, object: usize, transform: Affine3A) -> Scene {
        let o = &self.objects[object];
        let mut positions = Vec::with_capacity(3 * o.triangles.len());
        let mut triangles = Vec::with_capacity(o.triangles.len());
        for t in o.triangles.clone() {
            let base = positions.len() as u32;
            positions.extend(
                self.triangle(t as usize)
                    .map(|p| transform.transform_point3(p)),
            );
            triangles.push([base, base + 1, base + 2]);
        }
        Scene::from_triangles(positions, triangles)
    }

    /// The scene with every object moved to `poses[o]` (object space to world space, one per
    /// object, as [`SceneObject::transform`]): each object's vertices taken back through its
    /// loaded transform and out through its pose, the objects' transforms replaced by the poses.
    /// Triangle indices, materials and texture coordinates stay, so a surface point
    /// (`triangle`, `bary`) names the same point of the same object in both scenes.
    ///
    /// `Err` when `poses` has not one transform per object, or a vertex is shared by two
    /// objects that move apart.
    pub fn posed(&self, poses: &[Affine3A]) -> Result<Scene, String> {
        if poses.len() != self.objects.len() {
            return Err(format!(
                "{} poses for the {} objects of '{}'",
                poses.len(),
                self.objects.len(),
                self.name
            ));
        }
        let mut posed = self.clone();
        let mut owner = vec![u32::MAX; self.positions.len()];
        for (i, (o, pose)) in self.objects.iter().zip(poses).enumerate() {
            let motion = *pose * o.transform.inverse();
            for t in o.triangles.clone() {
                for v in self.triangles[t as usize] {
                    let v = v as usize;
                    match owner[v] {
                        u32::MAX => {
                            owner[v] = i as u32;
                            posed.positions[v] = motion.transform_point3(self.positions[v]);
                        }
                        j if j as usize == i => {}
                        j => {
                            return Err(format!(
                                "vertex {v} is shared by objects '{}' and '{}'",
                                self.objects[j as usize].name, o.name
                            ));
                        }
                    }
                }
            }
            posed.objects[i].transform = *pose;
        }
        // A pose far from the scene: ray casts there overflow the BVH's float arithmetic (a
        // panic in obvhs from 1e24), and nearer, yet still far, the object exchanges no light
        // with the scene, so a check would agree on nothing and say nothing.
        let (lo, hi) = super::bounds_of(&self.positions);
        let (centre, size) = ((lo + hi) * 0.5, (hi - lo).length().max(f32::MIN_POSITIVE));
        let reach = MAX_POSE_REACH * size;
        for o in &self.objects {
            let far = o
                .triangles
                .clone()
                .flat_map(|t| self.triangles[t as usize])
                .find_map(|v| {
                    // In f64: the distance of a vertex at 1e22 squares past f32's range.
                    let distance = (posed.positions[v as usize] - centre).as_dvec3().length();
                    (distance > reach as f64 || distance.is_nan()).then_some(distance as f32)
                });
            if let Some(distance) = far {
                return Err(format!(
                    "object '{}' placed {} from the scene's centre ({}, {}, {}), beyond \
                     {MAX_POSE_REACH} times the scene's size ({}): place it within {} of it",
                    o.name,
                    number(distance),
                    number(centre.x),
                    number(centre.y),
                    number(centre.z),
                    number(size),
                    number(reach)
                ));
            }
        }
        Ok(posed)
    }

    /// Every object's [`SceneObject::pose_at`] `time`, in the order of [`Scene::objects`] (what
    /// [`Scene::posed`] and the renderer's `set_object_transform` take).
    pub fn poses_at(&self, time: f32) -> Vec<Affine3A> {
        self.objects.iter().map(|o| o.pose_at(time)).collect()
    }

    /// The longest [`Animation::duration`] of the scene's objects, in seconds; `None` when no
    /// object has an animation.
    pub fn animation_duration(&self) -> Option<f32> {
        self.objects
            .iter()
            .filter_map(|o| o.animation.as_ref())
            .map(Animation::duration)
            .reduce(f32::max)
    }

    /// The centre of object `object`'s bounding box as it stands in [`Scene::positions`]
    /// (world space, at [`SceneObject::transform`]).
    ///
    /// # Panics
    /// If `object` is not an index into [`Scene::objects`].
    pub fn object_centre(&self, object: usize) -> glam::Vec3 {
        let (lo, hi) = self.objects[object].triangles.clone().fold(
            (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY),
            |(lo, hi), t| {
                self.triangle(t as usize)
                    .iter()
                    .fold((lo, hi), |(lo, hi), p| (lo.min(*p), hi.max(*p)))
            },
        );
        (lo + hi) / 2.0
    }

    /// Checks the invariants of [`Scene::objects`]: at least one object; ranges non-empty,
    /// contiguous and in order, starting at 0 and ending at `triangles.len()`. `Err` says which
    /// object breaks them.
    pub fn check_objects(&self) -> Result<(), String> {
        if self.objects.is_empty() {
            return Err("the scene has no objects".into());
        }
        let mut next = 0u64;
        for (i, o) in self.objects.iter().enumerate() {
            let (start, end) = (o.triangles.start as u64, o.triangles.end as u64);
            if start != next {
                return Err(format!(
                    "object {i} (`{}`) starts at triangle {start}, expected {next}",
                    o.name
                ));
            }
            if end <= start {
                return Err(format!(
                    "object {i} (`{}`) has no triangles ({start}..{end})",
                    o.name
                ));
            }
            next = end;
        }
        if next != self.triangles.len() as u64 {
            return Err(format!(
                "the objects cover triangles 0..{next}, the scene has {}",
                self.triangles.len()
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use glam::{Affine3A, Mat3, Vec3};

    use super::{ObjectKind, STATIC_OBJECT_NAME, SceneObject};
    use crate::scene::tests::{QUAD_MTL, QUAD_OBJ, SCENE_TOML, scene};
    use crate::scene::{Camera, Scene};

    const TRI_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    /// A unit square in the xz plane, two triangles (no MTL).
    const SQUARE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 2 3\nf 1 3 4\n";

    /// `[[objects]]` entries appended to [`SCENE_TOML`].
    fn with_objects(objects: &str) -> String {
        format!("{SCENE_TOML}\n{objects}")
    }

    /// Vertex positions of a small OBJ (`v x y z` lines) and its faces (`f` lines), as triangles
    /// of 0-based position indices.
    fn parse_obj(text: &str) -> (Vec<Vec3>, Vec<[usize; 3]>) {
        let (mut v, mut f) = (Vec::new(), Vec::new());
        for line in text.lines() {
            let w: Vec<&str> = line.split_whitespace().collect();
            match w.first() {
                Some(&"v") => v.push(Vec3::new(
                    w[1].parse().unwrap(),
                    w[2].parse().unwrap(),
                    w[3].parse().unwrap(),
                )),
                Some(&"f") => {
                    // `i`, `i/t`, ...: the position index; polygons become fans, as tobj does.
                    let i: Vec<usize> = w[1..]
                        .iter()
                        .map(|c| c.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
                        .collect();
                    f.extend((1..i.len() - 1).map(|k| [i[0], i[k], i[k + 1]]));
                }
                _ => {}
            }
        }
        (v, f)
    }

    /// Every kept triangle of `object` is the next non-degenerate face of `obj` placed by the
    /// object's transform; every face of `obj` is accounted for.
    fn assert_object_is(s: &Scene, object: usize, obj: &str) {
        let o = &s.objects[object];
        let (v, faces) = parse_obj(obj);
        let kept: Vec<[Vec3; 3]> = faces
            .iter()
            .map(|f| f.map(|i| v[i]))
            .filter(|[a, b, c]| (*b - *a).cross(*c - *a).length_squared() > 0.0)
            .collect();
        assert_eq!(o.triangles.len(), kept.len(), "object `{}`", o.name);
        for (t, corners) in o.triangles.clone().zip(&kept) {
            let merged = s.triangle(t as usize);
            for (m, p) in merged.iter().zip(corners) {
                let placed = o.transform.transform_point3(*p);
                assert!(
                    (placed - *m).length() <= 1e-5 * (1.0 + m.length()),
                    "object `{}`, triangle {t}: {placed} != {m}",
                    o.name
                );
            }
            assert_eq!(s.object_of(t as usize), object);
        }
    }

    /// A bare scene with `triangle_count` triangles (all the same) and the given objects.
    fn bare(triangle_count: usize, objects: Vec<SceneObject>) -> Scene {
        Scene {
            name: "bare".into(),
            path: "/nonexistent".into(),
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            texcoords: Vec::new(),
            triangles: vec![[0, 1, 2]; triangle_count],
            triangle_materials: vec![0; triangle_count],
            objects,
            materials: Vec::new(),
            camera: Camera {
                position: Vec3::Z,
                target: Vec3::ZERO,
                up: Vec3::Y,
                fov_y_deg: 40.0,
                resolution: [4, 4],
            },
            lights: Vec::new(),
            content_hash: [0; 32],
            files: Vec::new(),
            warnings: Vec::new(),
        }
    }

    fn rigid(name: &str, triangles: std::ops::Range<u32>) -> SceneObject {
        SceneObject {
            name: name.into(),
            kind: ObjectKind::Rigid,
            triangles,
            transform: Affine3A::IDENTITY,
            animation: None,
        }
    }

    #[test]
    fn static_mesh_and_two_objects_give_three_objects() {
        let toml = with_objects(
            "[[objects]]\nname = \"bunny\"\nmesh = \"tri.obj\"\n\
             translation = [10.0, 0.0, 0.0]\nrotation_deg = [0.0, 0.0, 90.0]\nscale = 2.0\n\n\
             [[objects]]\nname = \"crate\"\nmesh = \"square.obj\"\n\
             translation = [1.0, 2.0, 3.0]\nrotation_deg = [30.0, 45.0, 60.0]\nscale = 0.5\n",
        );
        let dir = scene(&[
            ("scene.toml", &toml),
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", QUAD_MTL),
            ("tri.obj", TRI_OBJ),
            ("square.obj", SQUARE_OBJ),
        ]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.check_objects(), Ok(()));
        assert_eq!(s.triangles.len(), 5);
        let summary: Vec<(&str, ObjectKind, std::ops::Range<u32>)> = s
            .objects
            .iter()
            .map(|o| (o.name.as_str(), o.kind, o.triangles.clone()))
            .collect();
        assert_eq!(
            summary,
            vec![
                (STATIC_OBJECT_NAME, ObjectKind::Static, 0..2),
                ("bunny", ObjectKind::Rigid, 2..3),
                ("crate", ObjectKind::Rigid, 3..5),
            ]
        );
        // The static part stays where it is; the objects are placed as the loader placed them.
        assert_eq!(s.objects[0].transform, Affine3A::IDENTITY);
        let bunny = s.objects[1].transform;
        // (1,0,0) scaled by 2, rotated 90° about z -> (0,2,0), translated -> (10,2,0).
        assert!((bunny.transform_point3(Vec3::X) - Vec3::new(10.0, 2.0, 0.0)).length() < 1e-5);
        let (r, d) = (f32::to_radians, 0.5);
        let expected = Affine3A::from_mat3_translation(
            Mat3::from_rotation_z(r(60.0))
                * Mat3::from_rotation_y(r(45.0))
                * Mat3::from_rotation_x(r(30.0))
                * Mat3::from_diagonal(Vec3::splat(d)),
            Vec3::new(1.0, 2.0, 3.0),
        );
        assert!(s.objects[2].transform.abs_diff_eq(expected, 1e-6));
        assert_object_is(&s, 0, QUAD_OBJ);
        assert_object_is(&s, 1, TRI_OBJ);
        assert_object_is(&s, 2, SQUARE_OBJ);
        // The merged arrays are as before.
        assert_eq!(s.triangle_materials, vec![0, 0, 1, 1, 1]);
    }

    #[test]
    fn scene_toml_without_objects_is_one_static_object() {
        let dir = scene(&[
            ("scene.toml", SCENE_TOML),
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", QUAD_MTL),
        ]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.objects, vec![SceneObject::whole_static(2)]);
        assert_eq!(s.check_objects(), Ok(()));
    }

    #[test]
    fn directory_of_objs_is_one_static_object() {
        let b = "v 5 0 0\nv 6 0 0\nv 5 1 0\nf 1 2 3\n";
        let dir = scene(&[("b.obj", b), ("a.obj", TRI_OBJ), ("c.obj", SQUARE_OBJ)]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.triangles.len(), 4);
        assert_eq!(s.objects, vec![SceneObject::whole_static(4)]);
        assert_eq!(s.objects[0].name, STATIC_OBJECT_NAME);
        assert_eq!(s.objects[0].kind, ObjectKind::Static);
        assert_eq!(s.check_objects(), Ok(()));
        assert!((0..4).all(|t| s.object_of(t) == 0));
    }

    #[test]
    fn dropped_degenerate_triangles_keep_the_ranges() {
        // Static: the first face is degenerate (collinear), one kept.
        let main = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n";
        // `a`: kept, degenerate (repeated vertex), kept.
        let a = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1 1 2\nf 2 4 3\n";
        // `b`: kept, then degenerate (collinear).
        let b = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n";
        let toml = with_objects(
            "[[objects]]\nname = \"a\"\nmesh = \"a.obj\"\ntranslation = [0.0, 0.0, 5.0]\n\n\
             [[objects]]\nname = \"b\"\nmesh = \"b.obj\"\nrotation_deg = [90.0, 0.0, 0.0]\n\
             scale = 3.0\n",
        )
        .replace("mesh = \"quad.obj\"", "mesh = \"main.obj\"");
        let dir = scene(&[
            ("scene.toml", &toml),
            ("main.obj", main),
            ("a.obj", a),
            ("b.obj", b),
        ]);
        let s = Scene::load(dir.path()).unwrap();
        let w = s.warnings.join("\n");
        assert_eq!(w.matches("dropped 1 degenerate").count(), 3, "{w}");
        assert_eq!(s.triangles.len(), 4);
        let ranges: Vec<_> = s.objects.iter().map(|o| o.triangles.clone()).collect();
        assert_eq!(ranges, vec![0..1, 1..3, 3..4]);
        assert_eq!(s.check_objects(), Ok(()));
        assert_object_is(&s, 0, main);
        assert_object_is(&s, 1, a);
        assert_object_is(&s, 2, b);
        let owners: Vec<usize> = (0..4).map(|t| s.object_of(t)).collect();
        assert_eq!(owners, vec![0, 1, 1, 2]);
    }

    #[test]
    fn object_of_and_check_objects_on_hand_built_scenes() {
        let s = bare(3, vec![SceneObject::whole_static(3)]);
        assert_eq!(s.check_objects(), Ok(()));
        assert!((0..3).all(|t| s.object_of(t) == 0));

        let mut objects = vec![SceneObject::whole_static(2)];
        objects.extend([rigid("a", 2..3), rigid("b", 3..7), rigid("c", 7..8)]);
        let s = bare(8, objects);
        assert_eq!(s.check_objects(), Ok(()));
        let owners: Vec<usize> = (0..8).map(|t| s.object_of(t)).collect();
        assert_eq!(owners, vec![0, 0, 1, 2, 2, 2, 2, 3]);

        let broken = |objects: Vec<SceneObject>| bare(4, objects).check_objects().unwrap_err();
        assert!(broken(Vec::new()).contains("no objects"));
        // A gap, an overlap, an empty range, too few and too many triangles.
        let e = broken(vec![rigid("a", 0..1), rigid("b", 2..4)]);
        assert!(e.contains("`b`") && e.contains("expected 1"), "{e}");
        let e = broken(vec![rigid("a", 0..2), rigid("b", 1..4)]);
        assert!(e.contains("`b`") && e.contains("expected 2"), "{e}");
        let e = broken(vec![rigid("a", 0..4), rigid("b", 4..4)]);
        assert!(e.contains("`b`") && e.contains("no triangles"), "{e}");
        let e = broken(vec![rigid("a", 0..3)]);
        assert!(e.contains("0..3") && e.contains("has 4"), "{e}");
        let e = broken(vec![SceneObject::whole_static(5)]);
        assert!(e.contains("0..5") && e.contains("has 4"), "{e}");
    }

    #[test]
    #[should_panic(expected = "triangle 3 belongs to no object")]
    fn object_of_a_missing_triangle_panics() {
        bare(3, vec![SceneObject::whole_static(3)]).object_of(3);
    }
}
