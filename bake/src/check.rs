//! Measures a baked CSSM against exact ray casts (§3.2.2): random pairs of surface points, drawn
//! uniformly by area, are tested with the CSSM query and with an obvhs ray cast, and the
//! agreement is reported as a confusion matrix. Both points have texels, so the query asks both
//! ends when [`QueryOptions::both_ends`] is set (the default), as the runtime's radiosity and
//! final gather do.
//!
//! Ground truth is *front-side* visibility, the visibility light transport needs: the segment
//! from `p_j` lifted off its surface along its normal to `p_i` lifted towards `p_j`'s side of
//! its own surface must hit nothing. (A CSSM, like any shadow map, only sees out of a surface's
//! front side; whether `p_i` is seen from its back is the receiver's cosine term, not visibility.)
//!
//! Besides all pairs, the agreement is tallied over the pairs that *exchange light*: each point
//! in front of the other's surface, so both cosines of the transfer are positive. Only those
//! pairs' visibility reaches an image; a pair facing away from each other carries no light
//! whatever the visibility says. A bake that widens its intervals past surfaces facing away
//! ([`crate::cubemap::SecondLayer::Facing`]) is exact on the first set and only there.

use cssm_formats::{
    CssmFile, Scene,
    visibility::{QueryOptions, VisibilityQuery},
};
use rayon::prelude::*;

use crate::raycast::SceneBvh;
/// The sampler and generator of the pairs, shared with the runtime's tests and benchmarks.
pub use cssm_raycast::{SplitMix64, SurfacePoint, SurfaceSampler};

/// Confusion matrix of CSSM answers against exact ray casts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Agreement {
    /// Truly visible, reported visible.
    pub visible_visible: u64,
    /// Truly visible, reported occluded.
    pub visible_occluded: u64,
    /// Truly occluded, reported visible.
    pub occluded_visible: u64,
    /// Truly occluded, reported occluded.
    pub occluded_occluded: u64,
    /// Pairs where no texel stood for either point (skipped).
    pub unmapped: u64,
}

impl Agreement {
    /// Pairs tested.
    pub fn total(&self) -> u64 {
        self.visible_visible
            + self.visible_occluded
            + self.occluded_visible
            + self.occluded_occluded
    }
    /// Fraction of pairs where the CSSM agrees with the ray cast.
    pub fn agreement(&self) -> f64 {
        (self.visible_visible + self.occluded_occluded) as f64 / self.total().max(1) as f64
    }
    /// Truly occluded pairs reported visible, as a fraction of the truly occluded.
    pub fn false_visible_rate(&self) -> f64 {
        self.occluded_visible as f64
            / (self.occluded_visible + self.occluded_occluded).max(1) as f64
    }
    /// Truly visible pairs reported occluded, as a fraction of the truly visible.
    pub fn false_occluded_rate(&self) -> f64 {
        self.visible_occluded as f64 / (self.visible_visible + self.visible_occluded).max(1) as f64
    }
    fn count(&mut self, truth: bool, cssm: bool) {
        match (truth, cssm) {
            (true, true) => self.visible_visible += 1,
            (true, false) => self.visible_occluded += 1,
            (false, true) => self.occluded_visible += 1,
            (false, false) => self.occluded_occluded += 1,
        }
    }
    fn add(self, o: Self) -> Self {
        Self {
            visible_visible: self.visible_visible + o.visible_visible,
            visible_occluded: self.visible_occluded + o.visible_occluded,
            occluded_visible: self.occluded_visible + o.occluded_visible,
            occluded_occluded: self.occluded_occluded + o.occluded_occluded,
            unmapped: self.unmapped + o.unmapped,
        }
    }
}

impl std::fmt::Display for Agreement {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "                     CSSM visible  CSSM occluded")?;
        writeln!(
            f,
            "ray cast visible   {:>14} {:>14}",
            self.visible_visible, self.visible_occluded
        )?;
        writeln!(
            f,
            "ray cast occluded  {:>14} {:>14}",
            self.occluded_visible, self.occluded_occluded
        )?;
        write!(
            f,
            "agreement {:.3}% of {} pairs; occluded reported visible {:.3}%; visible reported occluded {:.3}%",
            100.0 * self.agreement(),
            self.total(),
            100.0 * self.false_visible_rate(),
            100.0 * self.false_occluded_rate()
        )
    }
}

/// Where the disagreements over the pairs that exchange light come from, seen from the sender
/// end: each wrong answer is put in the first class that explains it, so the classes say which
/// setting to raise. The sender's texel is the one under its point.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Causes {
    /// The texel's centre sees the receiver otherwise than the sender point does (exact ray
    /// casts from both): the atlas is too coarse here (`--atlas`).
    pub atlas: u64,
    /// The cube map's centre, lifted by the near distance, sees otherwise than the texel's
    /// centre: the near distance (`--near`).
    pub near: u64,
    /// The texel's own cube map (its 2x2 PCF, no other texel) answers otherwise than an exact
    /// ray from its centre: the cube map's resolution or its depth intervals (`--cube`).
    pub cube: u64,
    /// The texel's own cube map answers right and the filters (sender filter, both ends) turn
    /// the answer wrong.
    pub filter: u64,
}

impl Causes {
    fn add(self, o: Self) -> Self {
        Self {
            atlas: self.atlas + o.atlas,
            near: self.near + o.near,
            cube: self.cube + o.cube,
            filter: self.filter + o.filter,
        }
    }
}

/// Agreement over all pairs and over the pairs that exchange light (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Measurement {
    /// Every pair drawn.
    pub all: Agreement,
    /// The pairs where each point lies in front of the other's surface.
    pub exchanging: Agreement,
    /// The causes of the disagreements counted in `exchanging`.
    pub causes: Causes,
}

impl Measurement {
    fn add(self, o: Self) -> Self {
        Self {
            all: self.all.add(o.all),
            exchanging: self.exchanging.add(o.exchanging),
            causes: self.causes.add(o.causes),
        }
    }
}

/// Puts the disagreement on the pair (`p_j`, `p_i`), whose true visibility is `truth`, into
/// its class of [`Causes`].
fn classify(
    bvh: &SceneBvh,
    query: &VisibilityQuery,
    p_j: &SurfacePoint,
    p_i: &SurfacePoint,
    truth: bool,
    eps: f32,
    causes: &mut Causes,
) {
    let Some(texel) = query.texel_at(p_j.triangle, p_j.bary) else {
        causes.filter += 1;
        return;
    };
    let t = &query.file().texels[texel as usize];
    let to = p_i.position + p_i.normal * eps;
    let from_texel = bvh.segment_clear(t.pos() + t.nrm() * eps, to);
    let from_cube = bvh.segment_clear(query.cube_centre(texel), to);
    let cube = query.visibility_oriented(texel, p_i.position, Some(p_i.normal)) >= 0.5;
    if from_texel != truth {
        causes.atlas += 1;
    } else if from_cube != from_texel {
        causes.near += 1;
    } else if cube != from_cube {
        causes.cube += 1;
    } else {
        causes.filter += 1;
    }
}

/// True when `p_i` and `p_j` each lie more than `eps` in front of the other's surface: both
/// cosines of their light transfer are positive.
pub fn exchanges_light(p_j: &SurfacePoint, p_i: &SurfacePoint, eps: f32) -> bool {
    let d = p_i.position - p_j.position;
    d.dot(p_j.normal) > eps && -d.dot(p_i.normal) > eps
}

/// Exact front-side visibility of `p_i` from `p_j` by ray casting (see the module docs).
pub fn exact_visible(bvh: &SceneBvh, p_j: &SurfacePoint, p_i: &SurfacePoint, eps: f32) -> bool {
    let from = p_j.position + p_j.normal * eps;
    // Coplanar pairs (a zero dot product up to rounding) are lifted on the front side.
    let side = if (p_j.position - p_i.position).dot(p_i.normal) >= -eps {
        1.0
    } else {
        -1.0
    };
    let to = p_i.position + p_i.normal * (side * eps);
    bvh.segment_clear(from, to)
}

/// Tests `pairs` random pairs (seeded) of `scene` with the CSSM `file` and with ray casts.
///
/// # Errors
/// As [`measure_posed`]'s, for a scene with rigid objects.
pub fn measure(
    scene: &Scene,
    file: &CssmFile,
    pairs: u64,
    seed: u64,
    options: QueryOptions,
) -> Result<Measurement, String> {
    measure_with_progress(scene, file, pairs, seed, options, &mut |_, _| {})
}

/// [`measure`], calling `progress(done, pairs)` after every block of 65,536 pairs. A scene with
/// rigid objects is measured with them where it placed them, through the moving-objects query
/// ([`measure_posed`], without its hull overlaps).
///
/// # Errors
/// As [`measure_posed`]'s, for a scene with rigid objects: a file that lacks a rigid object's
/// CSM (none `cssm bake` writes) is refused, since its CSSM alone would miss the occlusion
/// between objects.
pub fn measure_with_progress(
    scene: &Scene,
    file: &CssmFile,
    pairs: u64,
    seed: u64,
    options: QueryOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Measurement, String> {
    if scene
        .objects
        .iter()
        .any(|o| o.kind == cssm_formats::ObjectKind::Rigid)
    {
        let poses: Vec<_> = scene.objects.iter().map(|o| o.transform).collect();
        return measure_posed_with_progress(scene, file, &poses, pairs, seed, options, progress)
            .map(|m| m.measurement);
    }
    let bvh = SceneBvh::new(scene);
    let query = VisibilityQuery::new(file, options);
    let eps = 1e-4 * scene.diameter();
    Ok(tally(
        scene,
        &bvh,
        pairs,
        seed,
        progress,
        &|p_j, p_i| {
            query.visibility_between_surfaces(
                (p_j.triangle, p_j.bary),
                p_j.position,
                p_j.normal,
                (p_i.triangle, p_i.bary),
                p_i.position,
                p_i.normal,
            )
        },
        &|p_j, p_i, truth, causes| classify(&bvh, &query, p_j, p_i, truth, eps, causes),
    ))
}

/// What [`measure_posed`] found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PosedMeasurement {
    /// The agreement, as [`measure`]'s (no causes: they are the static query's).
    pub measurement: Measurement,
    /// Where the objects' convex hulls overlap at the poses (§3.3's limit).
    pub overlaps: cssm_formats::hull::HullOverlaps,
}

/// Measures the moving-objects query (§3.3, [`cssm_formats::moving::MovingQuery`]) against
/// exact ray casts with `scene`'s objects at `poses` (object-to-world, one per object): the
/// pairs are drawn on the posed surfaces and the ray casts see the posed scene. `Err` when the
/// poses do not fit the scene or the file lacks a rigid object's CSM.
pub fn measure_posed(
    scene: &Scene,
    file: &CssmFile,
    poses: &[glam::Affine3A],
    pairs: u64,
    seed: u64,
    options: QueryOptions,
) -> Result<PosedMeasurement, String> {
    measure_posed_with_progress(scene, file, poses, pairs, seed, options, &mut |_, _| {})
}

/// [`measure_posed`] with progress as [`measure_with_progress`]'s.
pub fn measure_posed_with_progress(
    scene: &Scene,
    file: &CssmFile,
    poses: &[glam::Affine3A],
    pairs: u64,
    seed: u64,
    options: QueryOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<PosedMeasurement, String> {
    let posed = scene.posed(poses)?;
    let mut query = cssm_formats::moving::MovingQuery::new(file, scene, options)?;
    query.set_poses(poses)?;
    let bvh = SceneBvh::new(&posed);
    let cssm = query.cssm();
    let measurement = tally(
        &posed,
        &bvh,
        pairs,
        seed,
        progress,
        &|p_j, p_i| {
            let (senders_j, senders_i) = (
                cssm.sender_texels(p_j.triangle, p_j.bary),
                cssm.sender_texels(p_i.triangle, p_i.bary),
            );
            let end = |p: &SurfacePoint, senders| cssm_formats::moving::ObjectPoint {
                senders,
                position: p.position,
                normal: p.normal,
                object: posed.object_of(p.triangle) as u32,
            };
            query.visibility_between(&end(p_j, &senders_j), &end(p_i, &senders_i))
        },
        &|_, _, _, _| {},
    );
    Ok(PosedMeasurement {
        measurement,
        overlaps: cssm_formats::hull::overlaps(scene, poses, 1e-3),
    })
}

/// Draws `pairs` pairs of points on `scene` (seeded), asks `answer` and the ray casts of `bvh`
/// for each, and tallies them; `explain` classifies the exchanging pairs they disagree on.
#[allow(clippy::too_many_arguments)]
fn tally(
    scene: &Scene,
    bvh: &SceneBvh,
    pairs: u64,
    seed: u64,
    progress: &mut dyn FnMut(u64, u64),
    answer: &(dyn Fn(&SurfacePoint, &SurfacePoint) -> Option<f32> + Sync),
    explain: &(dyn Fn(&SurfacePoint, &SurfacePoint, bool, &mut Causes) + Sync),
) -> Measurement {
    let sampler = SurfaceSampler::new(scene);
    let mut rng = SplitMix64(seed);
    let eps = 1e-4 * scene.diameter();
    // Pairs are drawn in blocks from one sequential generator (the same pairs for a seed, however
    // many threads), so memory stays bounded whatever `--pairs` asks for.
    const BLOCK: u64 = 1 << 16;
    let mut total = Measurement::default();
    let mut drawn = 0;
    while drawn < pairs {
        let count = BLOCK.min(pairs - drawn);
        drawn += count;
        let samples: Vec<(SurfacePoint, SurfacePoint)> = (0..count)
            .map(|_| {
                let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
                let a = sampler.point(r());
                let b = sampler.point(r());
                (a, b)
            })
            .collect();
        let block = samples
            .par_chunks(1024)
            .map(|chunk| {
                let mut m = Measurement::default();
                for (p_j, p_i) in chunk {
                    let exchanging = exchanges_light(p_j, p_i, eps);
                    let Some(fraction) = answer(p_j, p_i) else {
                        m.all.unmapped += 1;
                        if exchanging {
                            m.exchanging.unmapped += 1;
                        }
                        continue;
                    };
                    let truth = exact_visible(bvh, p_j, p_i, eps);
                    let cssm = fraction >= 0.5;
                    m.all.count(truth, cssm);
                    if exchanging {
                        m.exchanging.count(truth, cssm);
                        if truth != cssm {
                            explain(p_j, p_i, truth, &mut m.causes);
                        }
                    }
                }
                m
            })
            .reduce(Measurement::default, Measurement::add);
        total = total.add(block);
        progress(drawn, pairs);
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn point(position: Vec3, normal: Vec3) -> SurfacePoint {
        SurfacePoint {
            triangle: 0,
            bary: [1.0, 0.0, 0.0],
            position,
            normal,
        }
    }

    #[test]
    fn pairs_exchange_light_only_when_each_faces_the_other() {
        let floor = point(Vec3::ZERO, Vec3::Y);
        let ceiling = point(Vec3::new(1.0, 2.0, 0.0), -Vec3::Y);
        let roof = point(Vec3::new(1.0, 2.0, 0.0), Vec3::Y);
        let beside = point(Vec3::new(3.0, 0.0, 0.0), Vec3::Y);
        let below = point(Vec3::new(0.0, -1.0, 0.0), Vec3::Y);
        assert!(exchanges_light(&floor, &ceiling, 1e-4));
        assert!(exchanges_light(&ceiling, &floor, 1e-4));
        // The roof's outside faces away from the floor.
        assert!(!exchanges_light(&floor, &roof, 1e-4));
        // Coplanar: both cosines are zero.
        assert!(!exchanges_light(&floor, &beside, 1e-4));
        // Behind the floor's own surface.
        assert!(!exchanges_light(&floor, &below, 1e-4));
    }
}
