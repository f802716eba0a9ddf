//! Visibility among moving rigid objects (§3.3), the CPU reference of the runtime's query.
//!
//! A scene with rigid `[[objects]]` is baked so that every texel's depth cube map sees its own
//! object only (the static part counts as one object, however many static objects it was
//! loaded from), and every rigid object has a coherent shadow map in its own space
//! ([`crate::csm`]). Between a point `p_a` on object `A` and `p_b` on object `B`, with the
//! objects wherever they are now:
//!
//! 1. **Self-occlusion** with the CSSMs, each in the frame the object was baked in: when `A`
//!    and `B` are the same object, the one query of [`VisibilityQuery::visibility_between`]
//!    (both ends where the options say so); otherwise `A`'s texels test `p_b` against `A`'s
//!    geometry and `B`'s test `p_a` against `B`'s, and the segment is clear only where both are
//!    (§3.3: "there is an occlusion ... if one of the two depth tests reports a
//!    self-occlusion"), so the fractions multiply.
//! 2. **Every other rigid object** `C` tests the segment with its CSM, in `C`'s own space under
//!    its current pose; the fractions multiply.
//!
//! Limits, as the paper's: the CSM of `C` is right only for segments whose ends lie outside
//! `C`'s convex hull, so objects' hulls must not overlap ([`crate::hull`] finds where they do);
//! and the static part has no CSM (it encloses the others), so a segment between two points that
//! are both on rigid objects is not tested against the static part.

use glam::{Affine3A, Vec3};

use crate::{
    CssmFile, ObjectKind,
    csm::CsmData,
    texel::Texel,
    visibility::{QueryOptions, VisibilityQuery, combine_ends},
};

/// One end of a query: a surface point where the objects stand now.
#[derive(Clone, Copy, Debug)]
pub struct ObjectPoint<'s> {
    /// Its texels with weights ([`VisibilityQuery::sender_texels_at`], found in the atlas, which
    /// moves with the object); empty when no texel stands for it.
    pub senders: &'s [(u32, f32)],
    /// Position in world space, the objects posed.
    pub position: Vec3,
    /// Unit surface normal in world space, the objects posed.
    pub normal: Vec3,
    /// Index into the scene's objects of the object the point lies on.
    pub object: u32,
}

/// Where one object stands now, as the query needs it (the GPU query uploads the same).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// World space now to the world space the object was baked in.
    pub to_baked: Affine3A,
    /// World space now to the object's own space (its CSM's).
    pub to_object: Affine3A,
    /// The group whose CSSM maps see this object: 0 for the static part, `1 + i` for the
    /// `i`-th rigid object (counting from 0).
    pub group: u32,
}

impl Placement {
    /// Where an object baked at `baked` (object to world, as loaded) stands at `pose`; `group`
    /// as [`object_groups`] gives it.
    pub fn new(baked: Affine3A, pose: Affine3A, group: u32) -> Self {
        let to_object = pose.inverse();
        Self {
            to_baked: baked * to_object,
            to_object,
            group,
        }
    }

    /// Normal matrix of [`Placement::to_baked`] (its inverse transpose; the rotation itself for
    /// rigid poses).
    pub fn normal_to_baked(&self) -> glam::Mat3A {
        self.to_baked.matrix3.inverse().transpose()
    }

    /// `n` (world space now) as a unit normal in the baked frame; `n` itself if it degenerates.
    pub fn normal(&self, n: Vec3) -> Vec3 {
        Vec3::from(self.normal_to_baked() * glam::Vec3A::from(n)).normalize_or(n)
    }
}

/// Texel `t` where its object's motion `motion` (object `t.object`'s transform now times the
/// inverse of its transform as loaded: baked frame to world now) puts it (§3.3: a rigid object's
/// atlas moves with it): position and normal carried, area scaled by the square of the
/// motion's uniform scale (`|det|^(2/3)`; the objects move rigidly, with at most a uniform
/// scale). The runtime's WGSL twin is `visibility/posed.wgsl::posed_texel`.
pub fn posed_texel(t: &Texel, motion: &Affine3A) -> Texel {
    let mut posed = *t;
    posed.position = motion.transform_point3(t.pos()).to_array();
    posed.normal = motion
        .transform_vector3(t.nrm())
        .normalize_or(t.nrm())
        .to_array();
    posed.area = t.area * motion.matrix3.determinant().abs().powf(2.0 / 3.0);
    posed
}

/// Every texel of `texels` where [`posed_texel`] puts it, `motions[o]` the motion of object `o`.
///
/// # Panics
/// If a texel's object has no motion.
pub fn posed_texels(texels: &[Texel], motions: &[Affine3A]) -> Vec<Texel> {
    texels
        .iter()
        .map(|t| posed_texel(t, &motions[t.object as usize]))
        .collect()
}

/// The group of every object of `objects` (a scene's, in order): 0 for the static ones, which
/// never move and whose texels' maps see them all, `1 + i` for the `i`-th rigid object.
pub fn object_groups(objects: &[crate::SceneObject]) -> Vec<u32> {
    let mut rigid = 0;
    objects
        .iter()
        .map(|o| match o.kind {
            ObjectKind::Static => 0,
            ObjectKind::Rigid => {
                rigid += 1;
                rigid
            }
        })
        .collect()
}

/// Answers visibility queries between surface points of a scene whose rigid objects move
/// (§3.3): each object's CSSM for self-occlusion, the other objects' CSMs for the rest.
///
/// ```
/// # fn demo(file: &cssm_formats::CssmFile, scene: &cssm_formats::Scene) -> Result<(), String> {
/// use cssm_formats::moving::MovingQuery;
/// let mut query = MovingQuery::new(file, scene, Default::default())?;
/// // Lift the first rigid object by one unit.
/// let mut poses: Vec<_> = scene.objects.iter().map(|o| o.transform).collect();
/// if let Some(o) = poses.get_mut(1) {
///     *o = glam::Affine3A::from_translation(glam::Vec3::Y) * *o;
/// }
/// query.set_poses(&poses)?;
/// # Ok(()) }
/// ```
pub struct MovingQuery<'a> {
    query: VisibilityQuery<'a>,
    /// Each object's transform as baked (object space to world space).
    baked: Vec<Affine3A>,
    /// Each object's current placement.
    placements: Vec<Placement>,
    /// The CSM of every rigid object that has one.
    csms: Vec<&'a CsmData>,
}

impl<'a> MovingQuery<'a> {
    /// Prepares queries over `file` (validated, and [`crate::cssm::validate_for_scene`] against
    /// `scene`), the objects where `scene` placed them. `Err` when a rigid object of `scene` has
    /// no CSM in the file, or a texel lies on no object of `scene`.
    pub fn new(
        file: &'a CssmFile,
        scene: &crate::Scene,
        options: QueryOptions,
    ) -> Result<Self, String> {
        let objects = scene.objects.len();
        if let Some((i, t)) = file
            .texels
            .iter()
            .enumerate()
            .find(|(_, t)| t.object as usize >= objects)
        {
            return Err(format!(
                "texel {i} lies on object {}, the scene has {objects}",
                t.object
            ));
        }
        let groups = object_groups(&scene.objects);
        let mut csms = Vec::new();
        for (i, o) in scene.objects.iter().enumerate() {
            if o.kind == ObjectKind::Rigid {
                let csm = file
                    .csms
                    .iter()
                    .find(|c| c.object as usize == i)
                    .ok_or_else(|| {
                        format!(
                            "rigid object {i} ('{}') has no coherent shadow map in the file",
                            o.name
                        )
                    })?;
                csms.push(csm);
            }
        }
        let placements = scene
            .objects
            .iter()
            .zip(&groups)
            .map(|(o, &group)| Placement::new(o.transform, o.transform, group))
            .collect();
        Ok(Self {
            query: VisibilityQuery::new(file, options),
            baked: scene.objects.iter().map(|o| o.transform).collect(),
            placements,
            csms,
        })
    }

    /// The CSSM query underneath.
    pub fn cssm(&self) -> &VisibilityQuery<'a> {
        &self.query
    }

    /// Places every object: `poses[o]` is object `o`'s object-to-world transform now (a static
    /// object's should stay as loaded). `Err` unless there is one pose per object, each
    /// invertible.
    pub fn set_poses(&mut self, poses: &[Affine3A]) -> Result<(), String> {
        if poses.len() != self.placements.len() {
            return Err(format!(
                "{} poses for {} objects",
                poses.len(),
                self.placements.len()
            ));
        }
        for (o, pose) in poses.iter().enumerate() {
            let det = pose.matrix3.determinant();
            if !(det.is_finite() && det.abs() > 1e-12 && pose.translation.is_finite()) {
                return Err(format!("pose of object {o} is not invertible"));
            }
        }
        for ((placement, pose), baked) in self.placements.iter_mut().zip(poses).zip(&self.baked) {
            *placement = Placement::new(*baked, *pose, placement.group);
        }
        Ok(())
    }

    /// Every object's placement now, in object order.
    pub fn placements(&self) -> &[Placement] {
        &self.placements
    }

    /// The coherent shadow maps the query tests, in object order (one per rigid object).
    pub fn csms(&self) -> &[&'a CsmData] {
        &self.csms
    }

    /// `p` and its normal `n` (world space now) in the frame object `object` was baked in.
    /// The static part never moves: its frame is the world's, and its points pass unchanged
    /// (so that a scene without rigid objects answers exactly as [`VisibilityQuery`]).
    fn to_baked(&self, object: u32, p: Vec3, n: Vec3) -> (Vec3, Vec3) {
        let placement = &self.placements[object as usize];
        if placement.group == 0 {
            return (p, n);
        }
        (placement.to_baked.transform_point3(p), placement.normal(n))
    }

    /// Fraction of the segment between `a` and `b` that is clear (see the module docs); `None`
    /// when neither end has texels.
    pub fn visibility_between(&self, a: &ObjectPoint, b: &ObjectPoint) -> Option<f32> {
        let (group_a, group_b) = (
            self.placements[a.object as usize].group,
            self.placements[b.object as usize].group,
        );
        // 1. Self-occlusion: each end's maps answer for the other end, in the end's own baked
        // frame (one frame when both lie on one object).
        let (p_b, n_b) = self.to_baked(a.object, b.position, b.normal);
        let forward = self.query.answer_from_senders(a.senders, p_b, Some(n_b));
        let (p_a, n_a) = self.to_baked(b.object, a.position, a.normal);
        let backward = self.query.answer_from_senders(b.senders, p_a, Some(n_a));
        let own = if group_a == group_b {
            // VisibilityQuery::visibility_between's combination.
            match (forward, backward) {
                (Some(f), Some(r)) if self.query.options.both_ends => Some(combine_ends(f, r)),
                (Some(f), _) => Some(f.visible),
                (None, r) => r.map(|r| r.visible),
            }
        } else {
            match (forward, backward) {
                (Some(f), Some(r)) => Some(f.visible * r.visible),
                (f, r) => f.or(r).map(|answer| answer.visible),
            }
        }?;
        // 2. Every other rigid object, with its CSM where it stands now.
        let mut clear = own;
        for csm in &self.csms {
            let placement = &self.placements[csm.object as usize];
            if placement.group == group_a || placement.group == group_b || clear <= 0.0 {
                continue;
            }
            let to_object = &placement.to_object;
            clear *= csm.visibility(
                to_object.transform_point3(a.position),
                to_object.transform_point3(b.position),
            );
        }
        Some(clear)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn posed_texels_move_turn_and_scale_with_their_object() {
        let texel = Texel {
            position: [1.0, 2.0, 3.0],
            normal: [0.0, 0.0, 1.0],
            area: 0.5,
            material: 0,
            chart: 0,
            object: 1,
            x: 0,
            y: 0,
        };
        let still = Texel { object: 0, ..texel };
        let motion = Affine3A::from_scale_rotation_translation(
            Vec3::splat(2.0),
            Quat::from_rotation_x(std::f32::consts::FRAC_PI_2),
            Vec3::new(10.0, 0.0, 0.0),
        );
        let posed = posed_texels(&[texel, still], &[Affine3A::IDENTITY, motion]);
        // Rotated a quarter turn about x: (1, 2, 3) -> (1, -3, 2), scaled 2, moved by 10 in x.
        assert!(posed[0].pos().abs_diff_eq(Vec3::new(12.0, -6.0, 4.0), 1e-5));
        assert!(posed[0].nrm().abs_diff_eq(Vec3::new(0.0, -1.0, 0.0), 1e-6));
        assert!((posed[0].area - 2.0).abs() < 1e-5);
        assert_eq!(posed[1], still, "the static part stays");
    }
}
