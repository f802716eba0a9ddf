//! Animated rigid objects: an `[[objects]]` entry's `[objects.animation]` (keyframes, a spin or
//! both; `docs/scene-format.md`), checked into an [`Animation`] whose [`Animation::pose_at`]
//! gives the object's object-to-world transform at a time in seconds.
//!
//! The entry's `translation` and `rotation_deg` stay the pose it is loaded (and baked) at; the
//! animation's poses are absolute, in world space, and keep the entry's `scale`.

use std::path::Path;

use glam::{Affine3A, EulerRot, Quat, Vec3};
use serde::Deserialize;

use super::SceneError;

/// How keyframes go on after the last one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Repeat {
    /// From the last keyframe back to time 0 and round again (the default).
    #[default]
    Loop,
    /// Forwards to the last keyframe, then backwards to time 0, and again.
    PingPong,
    /// The last keyframe's pose is held for ever.
    Once,
}

/// One pose of a keyframed object: world-space translation and rotation at `time`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Keyframe {
    /// Seconds from the start; keyframes are in strictly increasing time, the first at 0 or
    /// later (before it the first pose holds).
    pub time: f32,
    /// Where the object's origin is.
    pub translation: Vec3,
    /// The object's rotation (from `rotation_deg`, XYZ Euler angles applied X, then Y, then Z).
    pub rotation: Quat,
}

/// A constant turn about a world-space axis through the object's origin (its translation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spin {
    /// Unit axis, world space; the turn is counter-clockwise looking down it (right-handed).
    pub axis: Vec3,
    /// Degrees per second, non-zero (negative turns the other way).
    pub deg_per_s: f32,
}

impl Spin {
    /// Seconds of one full turn.
    pub fn period(&self) -> f32 {
        360.0 / self.deg_per_s.abs()
    }

    /// The rotation after `time` seconds.
    pub fn rotation_at(&self, time: f32) -> Quat {
        Quat::from_axis_angle(self.axis, (self.deg_per_s * time).to_radians())
    }
}

/// The motion of one rigid object over time: keyframes, a spin, or both (the spin turns the
/// keyframes' pose about the axis through its translation).
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    /// Keyframes, at least two, in strictly increasing time; empty for a spin alone.
    pub keyframes: Vec<Keyframe>,
    /// What follows the last keyframe.
    pub repeat: Repeat,
    /// A constant turn on top of the keyframes' pose (or of the entry's pose, without them).
    pub spin: Option<Spin>,
    /// The entry's `translation`: the pose without keyframes.
    pub translation: Vec3,
    /// The entry's rotation: the pose without keyframes.
    pub rotation: Quat,
    /// The entry's uniform `scale`, kept at every pose.
    pub scale: f32,
}

impl Animation {
    /// The object's object-to-world transform at `time` seconds (any finite time; before 0 the
    /// keyframes hold their first pose, a spin turns backwards): scale, then the keyframes'
    /// rotation (slerp between the two keyframes about `time`) and the spin's, then the
    /// translation (linear between the keyframes). Composed as `SceneObject::transform` is.
    pub fn pose_at(&self, time: f32) -> Affine3A {
        let (translation, mut rotation) = self.keyframe_pose(time);
        if let Some(spin) = &self.spin {
            rotation = (spin.rotation_at(time) * rotation).normalize();
        }
        Affine3A::from_scale_rotation_translation(Vec3::splat(self.scale), rotation, translation)
    }

    /// Seconds after which the motion repeats (or, for [`Repeat::Once`], ends): the keyframes'
    /// last time (twice that for [`Repeat::PingPong`]), else the spin's full turn.
    pub fn duration(&self) -> f32 {
        match (self.keyframes.last(), &self.spin) {
            (Some(last), _) => match self.repeat {
                Repeat::Loop | Repeat::Once => last.time,
                Repeat::PingPong => 2.0 * last.time,
            },
            (None, Some(spin)) => spin.period(),
            (None, None) => 0.0,
        }
    }

    /// The keyframes' translation and rotation at `time`, or the entry's without keyframes.
    fn keyframe_pose(&self, time: f32) -> (Vec3, Quat) {
        let (Some(first), Some(last)) = (self.keyframes.first(), self.keyframes.last()) else {
            return (self.translation, self.rotation);
        };
        let end = last.time;
        let local = match self.repeat {
            Repeat::Once => time,
            Repeat::Loop => time.rem_euclid(end),
            Repeat::PingPong => {
                let t = time.rem_euclid(2.0 * end);
                if t <= end { t } else { 2.0 * end - t }
            }
        };
        // (A NaN time shows the first pose rather than reaching past the keyframes.)
        if local.is_nan() || local <= first.time {
            return (first.translation, first.rotation);
        }
        if local >= end {
            return (last.translation, last.rotation);
        }
        // The first keyframe after `local`; the one before it is at or before `local`.
        let next = self.keyframes.partition_point(|k| k.time <= local);
        let (a, b) = (&self.keyframes[next - 1], &self.keyframes[next]);
        let s = ((local - a.time) / (b.time - a.time)).clamp(0.0, 1.0);
        (
            a.translation.lerp(b.translation, s),
            a.rotation.slerp(b.rotation, s).normalize(),
        )
    }
}

/// The rotation of XYZ Euler angles in degrees, applied X, then Y, then Z: the rotation of
/// [`super::placement`].
pub fn euler_rotation(rotation_deg: Vec3) -> Quat {
    let r = rotation_deg.to_array().map(f32::to_radians);
    Quat::from_euler(EulerRot::ZYX, r[2], r[1], r[0])
}

/// `transform` turned by `angle_deg` about the axis `axis` (unit, world space) through the
/// world-space point `centre`: what `cssm render --animate` does with an object that has no
/// animation of its own, spinning it in place.
pub fn turned_about(transform: Affine3A, centre: Vec3, axis: Vec3, angle_deg: f32) -> Affine3A {
    let turn = Affine3A::from_translation(centre)
        * Affine3A::from_quat(Quat::from_axis_angle(axis, angle_deg.to_radians()))
        * Affine3A::from_translation(-centre);
    turn * transform
}

// ---------------------------------------------------------------------------------------------
// scene.toml

/// `[objects.animation]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct AnimationToml {
    keyframes: Option<Vec<KeyframeToml>>,
    #[serde(default)]
    repeat: Repeat,
    spin: Option<SpinToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyframeToml {
    time: f32,
    translation: Option<[f32; 3]>,
    rotation_deg: Option<[f32; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SpinToml {
    axis: [f32; 3],
    deg_per_s: f32,
}

/// Checks object `name`'s animation from `path` (its `scene.toml`), the entry's pose being
/// `translation`, `rotation_deg` and `scale` (checked already): keyframes, if given, at least
/// two, with finite values and strictly increasing times from 0 on; a spin with a finite non-zero
/// axis and a finite non-zero speed; one of the two at least. Every error names the file, the
/// object and the problem.
/// Most keyframes of one object: each is kept for every frame's pose, and a file's count must
/// not size the allocation.
pub const MAX_KEYFRAMES: usize = 100_000;

pub(super) fn check_animation(
    a: &AnimationToml,
    name: &str,
    (translation, rotation_deg, scale): (Vec3, Vec3, f32),
    path: &Path,
) -> Result<Animation, SceneError> {
    let bad = |message: String| SceneError::Invalid {
        path: path.to_path_buf(),
        message: format!("object `{name}`: animation: {message}"),
    };
    if a.keyframes.is_none() && a.spin.is_none() {
        return Err(bad(
            "gives neither keyframes nor spin (give one or both, or remove it)".into(),
        ));
    }
    let mut keyframes: Vec<Keyframe> = Vec::new();
    if let Some(list) = &a.keyframes {
        match list.len() {
            0 => return Err(bad("keyframes is empty: give at least two".into())),
            1 => {
                return Err(bad(
                    "keyframes has only one: give at least two (a fixed pose is the entry's \
                     translation and rotation_deg)"
                        .into(),
                ));
            }
            n if n > MAX_KEYFRAMES => {
                return Err(bad(format!(
                    "keyframes has {n}; at most {MAX_KEYFRAMES} are read"
                )));
            }
            _ => {}
        }
        for (i, k) in list.iter().enumerate() {
            let at = |problem: String| bad(format!("keyframes[{i}] (time {}): {problem}", k.time));
            if !(k.time.is_finite() && k.time >= 0.0) {
                return Err(at("time must be finite and 0 or more".into()));
            }
            if let Some(previous) = keyframes.last()
                && k.time <= previous.time
            {
                return Err(at(format!(
                    "times must increase strictly; keyframes[{}] is at {}",
                    i - 1,
                    previous.time
                )));
            }
            let t = k.translation.map_or(translation, Vec3::from);
            let r = k.rotation_deg.map_or(rotation_deg, Vec3::from);
            if !t.is_finite() {
                return Err(at("translation must be finite".into()));
            }
            if !r.is_finite() {
                return Err(at("rotation_deg must be finite".into()));
            }
            keyframes.push(Keyframe {
                time: k.time,
                translation: t,
                rotation: euler_rotation(r),
            });
        }
    }
    let spin = match &a.spin {
        None => None,
        Some(s) => {
            let axis = Vec3::from(s.axis);
            if !axis.is_finite() || axis.length_squared() == 0.0 {
                return Err(bad(format!(
                    "spin.axis {} must be a finite non-zero vector",
                    super::fmt3(axis)
                )));
            }
            if !(s.deg_per_s.is_finite() && s.deg_per_s != 0.0) {
                return Err(bad(format!(
                    "spin.deg_per_s {} must be finite and non-zero",
                    s.deg_per_s
                )));
            }
            Some(Spin {
                axis: axis.normalize(),
                deg_per_s: s.deg_per_s,
            })
        }
    };
    Ok(Animation {
        keyframes,
        repeat: a.repeat,
        spin,
        translation,
        rotation: euler_rotation(rotation_deg),
        scale,
    })
}

#[cfg(test)]
mod tests {
    use glam::{Affine3A, Quat, Vec3};

    use super::{Animation, Keyframe, Repeat, Spin, euler_rotation, turned_about};
    use crate::scene::tests::{QUAD_MTL, QUAD_OBJ, SCENE_TOML, err, scene};
    use crate::scene::{Scene, placement};

    const TRI_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

    fn close(a: Affine3A, b: Affine3A) -> bool {
        a.abs_diff_eq(b, 1e-4)
    }

    /// Two keyframes: at 0 s at the origin unturned, at 2 s at (4, 0, 0) turned 90° about y.
    fn two_keyframes(repeat: Repeat) -> Animation {
        Animation {
            keyframes: vec![
                Keyframe {
                    time: 0.0,
                    translation: Vec3::ZERO,
                    rotation: Quat::IDENTITY,
                },
                Keyframe {
                    time: 2.0,
                    translation: Vec3::new(4.0, 0.0, 0.0),
                    rotation: euler_rotation(Vec3::new(0.0, 90.0, 0.0)),
                },
            ],
            repeat,
            spin: None,
            translation: Vec3::ZERO,
            rotation: Quat::IDENTITY,
            scale: 2.0,
        }
    }

    /// The pose of translation `x` along x, turned `deg` about y, scale 2.
    fn pose(x: f32, deg: f32) -> Affine3A {
        placement(Vec3::new(x, 0.0, 0.0), Vec3::new(0.0, deg, 0.0), 2.0)
    }

    #[test]
    fn keyframes_interpolate_translation_linearly_and_rotation_by_slerp() {
        let a = two_keyframes(Repeat::Loop);
        assert!(close(a.pose_at(0.0), pose(0.0, 0.0)));
        // Halfway: half the way and half the angle (slerp of one axis is linear in angle).
        assert!(
            close(a.pose_at(1.0), pose(2.0, 45.0)),
            "{:?}",
            a.pose_at(1.0)
        );
        assert!(close(a.pose_at(0.5), pose(1.0, 22.5)));
        // Just before the end: nearly the last keyframe.
        assert!(close(a.pose_at(1.999), pose(3.998, 89.955)));
        assert_eq!(a.duration(), 2.0);
    }

    #[test]
    fn endpoints_and_the_three_repeats() {
        // Loop: the end wraps to the start.
        let a = two_keyframes(Repeat::Loop);
        assert!(close(a.pose_at(2.0), pose(0.0, 0.0)));
        assert!(close(a.pose_at(2.5), pose(1.0, 22.5)));
        assert!(close(a.pose_at(-0.5), pose(3.0, 67.5)));
        // Ping-pong: forwards, then back.
        let a = two_keyframes(Repeat::PingPong);
        assert_eq!(a.duration(), 4.0);
        assert!(close(a.pose_at(2.0), pose(4.0, 90.0)));
        assert!(close(a.pose_at(3.0), pose(2.0, 45.0)));
        assert!(close(a.pose_at(4.5), pose(1.0, 22.5)));
        // Once: the last pose holds, the first before the start.
        let a = two_keyframes(Repeat::Once);
        assert!(close(a.pose_at(2.0), pose(4.0, 90.0)));
        assert!(close(a.pose_at(100.0), pose(4.0, 90.0)));
        assert!(close(a.pose_at(-1.0), pose(0.0, 0.0)));
    }

    #[test]
    fn a_late_first_keyframe_holds_until_its_time() {
        let mut a = two_keyframes(Repeat::Loop);
        a.keyframes.insert(
            0,
            Keyframe {
                time: 0.5,
                translation: Vec3::new(-4.0, 0.0, 0.0),
                rotation: Quat::IDENTITY,
            },
        );
        a.keyframes[1].time = 1.0;
        assert!(close(a.pose_at(0.25), pose(-4.0, 0.0)));
        assert!(close(a.pose_at(0.75), pose(-2.0, 0.0)));
        assert!(close(a.pose_at(1.5), pose(2.0, 45.0)));
        // Three keyframes: the middle segment is found.
        assert!(close(a.pose_at(2.25), pose(-4.0, 0.0)), "wraps at 2 s");
    }

    #[test]
    fn a_spin_turns_about_its_axis_through_the_translation() {
        let a = Animation {
            keyframes: Vec::new(),
            repeat: Repeat::Loop,
            spin: Some(Spin {
                axis: Vec3::Y,
                deg_per_s: 90.0,
            }),
            translation: Vec3::new(10.0, 0.0, 0.0),
            rotation: Quat::IDENTITY,
            scale: 1.0,
        };
        assert_eq!(a.duration(), 4.0);
        assert!(close(
            a.pose_at(0.0),
            Affine3A::from_translation(a.translation)
        ));
        // 1 s: 90° about y: x goes to -z, the origin stays at the translation.
        let p = a.pose_at(1.0);
        assert!(p.transform_point3(Vec3::ZERO).distance(a.translation) < 1e-5);
        assert!(p.transform_vector3(Vec3::X).distance(-Vec3::Z) < 1e-5);
        assert!(close(a.pose_at(4.0), a.pose_at(0.0)));
        // On top of keyframes: the keyframes' rotation, then the spin's.
        let mut k = two_keyframes(Repeat::Loop);
        k.spin = a.spin;
        let expected = Affine3A::from_scale_rotation_translation(
            Vec3::splat(2.0),
            Quat::from_rotation_y(90f32.to_radians()) * euler_rotation(Vec3::new(0.0, 45.0, 0.0)),
            Vec3::new(2.0, 0.0, 0.0),
        );
        assert!(close(k.pose_at(1.0), expected));
        assert_eq!(k.duration(), 2.0, "the keyframes set the duration");
    }

    #[test]
    fn euler_rotation_is_the_placements() {
        let r = Vec3::new(30.0, 45.0, 60.0);
        let m = placement(Vec3::ZERO, r, 1.0);
        assert!(close(Affine3A::from_quat(euler_rotation(r)), m));
    }

    #[test]
    fn turned_about_keeps_the_centre() {
        let t = placement(Vec3::new(5.0, 1.0, 0.0), Vec3::new(0.0, 20.0, 0.0), 1.5);
        let centre = Vec3::new(5.5, 1.0, 0.5);
        let turned = turned_about(t, centre, Vec3::Y, 73.0);
        let c_object = t.inverse().transform_point3(centre);
        assert!(turned.transform_point3(c_object).distance(centre) < 1e-4);
        assert!(close(turned_about(t, centre, Vec3::Y, 360.0), t));
    }

    fn with_animation(animation: &str) -> String {
        format!(
            "{SCENE_TOML}\n[[objects]]\nname = \"tri\"\nmesh = \"tri.obj\"\n\
             translation = [1.0, 2.0, 3.0]\nrotation_deg = [0.0, 30.0, 0.0]\nscale = 2.0\n\n\
             [objects.animation]\n{animation}\n"
        )
    }

    fn load(animation: &str) -> Result<Scene, String> {
        let toml = with_animation(animation);
        let dir = scene(&[
            ("scene.toml", &toml),
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", QUAD_MTL),
            ("tri.obj", TRI_OBJ),
        ]);
        Scene::load(dir.path()).map_err(|e| e.to_string())
    }

    fn load_err(animation: &str) -> String {
        let toml = with_animation(animation);
        err(&[
            ("scene.toml", &toml),
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", QUAD_MTL),
            ("tri.obj", TRI_OBJ),
        ])
    }

    #[test]
    fn scene_toml_keyframes_and_spin_load() {
        let s = load(
            "repeat = \"ping-pong\"\nkeyframes = [\n\
             { time = 0.0 },\n\
             { time = 1.5, translation = [4.0, 2.0, 3.0] },\n\
             { time = 3.0, translation = [4.0, 2.0, 3.0], rotation_deg = [0.0, 120.0, 0.0] },\n]\n\
             spin = { axis = [0.0, 2.0, 0.0], deg_per_s = -45.0 }",
        )
        .unwrap();
        let o = &s.objects[1];
        let a = o.animation.as_ref().expect("an animation");
        assert_eq!(a.repeat, Repeat::PingPong);
        assert_eq!(a.keyframes.len(), 3);
        assert_eq!(
            a.spin,
            Some(Spin {
                axis: Vec3::Y,
                deg_per_s: -45.0
            })
        );
        // A keyframe without translation or rotation_deg has the entry's: at time 0 the pose is
        // the loaded one.
        assert!(close(o.pose_at(0.0), o.transform));
        assert_eq!(s.animation_duration(), Some(6.0));
        // The static part does not move; a scene's poses are one per object.
        assert_eq!(s.objects[0].pose_at(1.0), Affine3A::IDENTITY);
        assert_eq!(s.poses_at(1.0).len(), 2);
        // 1.5 s: at the second keyframe, turned -67.5° by the spin.
        let expected = placement(
            Vec3::new(4.0, 2.0, 3.0),
            Vec3::new(0.0, 30.0 - 67.5, 0.0),
            2.0,
        );
        assert!(close(o.pose_at(1.5), expected), "{:?}", o.pose_at(1.5));

        let s = load("spin = { axis = [0.0, 1.0, 0.0], deg_per_s = 30.0 }").unwrap();
        assert!(
            s.objects[1]
                .animation
                .as_ref()
                .unwrap()
                .keyframes
                .is_empty()
        );
        assert_eq!(s.animation_duration(), Some(12.0));
        let s = load("keyframes = [{ time = 0.0 }, { time = 2.0 }]").unwrap();
        assert_eq!(
            s.objects[1].animation.as_ref().unwrap().repeat,
            Repeat::Loop
        );
    }

    #[test]
    fn bad_animations_name_the_file_the_object_and_the_problem() {
        let cases: &[(&str, &str)] = &[
            ("", "neither keyframes nor spin"),
            ("keyframes = []", "keyframes is empty"),
            ("keyframes = [{ time = 0.0 }]", "only one"),
            (
                "keyframes = [{ time = 1.0 }, { time = 0.5 }]",
                "keyframes[1] (time 0.5): times must increase strictly; keyframes[0] is at 1",
            ),
            (
                "keyframes = [{ time = 1.0 }, { time = 1.0 }]",
                "times must increase strictly",
            ),
            (
                "keyframes = [{ time = -1.0 }, { time = 1.0 }]",
                "keyframes[0] (time -1): time must be finite and 0 or more",
            ),
            (
                "keyframes = [{ time = 0.0 }, { time = nan }]",
                "time must be finite",
            ),
            (
                "keyframes = [{ time = 0.0 }, { time = 1.0, translation = [inf, 0.0, 0.0] }]",
                "keyframes[1] (time 1): translation must be finite",
            ),
            (
                "keyframes = [{ time = 0.0, rotation_deg = [0.0, nan, 0.0] }, { time = 1.0 }]",
                "keyframes[0] (time 0): rotation_deg must be finite",
            ),
            (
                "spin = { axis = [0.0, 0.0, 0.0], deg_per_s = 10.0 }",
                "spin.axis [0, 0, 0] must be a finite non-zero vector",
            ),
            (
                "spin = { axis = [0.0, 1.0, 0.0], deg_per_s = 0.0 }",
                "spin.deg_per_s 0 must be finite and non-zero",
            ),
            (
                "spin = { axis = [0.0, 1.0, 0.0], deg_per_s = inf }",
                "must be finite and non-zero",
            ),
            ("repeat = \"bounce\"", "bounce"),
            (
                "keyframes = [{ time = 0.0, scale = 2.0 }, { time = 1.0 }]",
                "scale",
            ),
            ("speed = 3", "speed"),
        ];
        for (animation, needle) in cases {
            let e = load_err(animation);
            assert!(e.contains("scene.toml"), "{animation}: {e}");
            assert!(
                e.contains(needle),
                "{animation}: expected '{needle}' in: {e}"
            );
            if !["bounce", "scale", "speed"].contains(needle) {
                assert!(e.contains("object `tri`: animation: "), "{animation}: {e}");
            }
        }
    }
}
