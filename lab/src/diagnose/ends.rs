//! `cssm diagnose ends`: how the two ends' answers are combined (reports/visibility.md,
//! "Which end to trust"). Over the pairs of `cssm check` (seed 1, `--pairs`, 100,000 by
//! default; only the exchanging pairs with texels at both ends), each end is asked as the query
//! asks it (sender filter, 2x2 PCF, receiver-plane depth) and, besides, with what the rules
//! below need: where its blocking pixels' stored depths put the occluder, wider pixel filters,
//! a parallax-corrected second look and probes of the segment near the sender ("What else was
//! tried on the turned church"; `--probes 0.5,1,2` sets the probes' distances in texel sizes).
//! With `--csv FILE` it also writes one line per pair: truth, both ends' answers, blocked
//! weights, occluder ratios, nearness, pixel angles, the segment's length and where along it
//! the exact ray is blocked (-1 when it is not).
//!
//! With `--mix FINE.cssm` (the same scene and atlas baked at twice the cube resolution) it
//! measures instead what a per-texel cube resolution could buy: the query with the texels that
//! see the most depth edges answered from FINE, for several fractions of the texels, and the
//! runs those texels' maps would add; with `--coverage` as well, an upper bound of a per-pixel
//! coverage hint: each of the coarse file's 2x2 taps soft, the fraction of its four sub-pixels
//! in FINE that see past the receiver ("Per-texel cube resolution and coverage hints").
use std::{
    io::Write,
    path::{Path, PathBuf},
};

use cssm_bake::check::{exact_visible, exchanges_light};
use cssm_formats::{
    CssmFile,
    cube::{self, DepthQuantizer},
    visibility::{EndAnswer, QueryOptions, VisibilityQuery, combine_ends},
};
use cssm_raycast::SceneBvh;
use glam::Vec3;

mod mix;

/// `cssm diagnose ends`'s arguments.
#[derive(clap::Args, Clone, Debug)]
pub struct EndsArgs {
    /// The .cssm file to diagnose. The scene it was baked from (the directory its header
    /// records) must still be there, unchanged.
    #[arg(value_name = "FILE.cssm")]
    pub file: PathBuf,
    /// Random surface point pairs to draw, as `cssm check` draws them (seed 1); only those
    /// that exchange light with texels at both ends count. The reports' figures are over
    /// 100000.
    #[arg(long, default_value_t = 100_000, value_name = "N")]
    pub pairs: u32,
    /// Where the probes rule tests the segment near the sender point against each texel's
    /// depths: distances from the sender point in texel sizes, positive and increasing (the
    /// probing of a pair stops at the first beyond half its segment).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "1,2,4",
        allow_negative_numbers = true,
        value_name = "SIZES",
        conflicts_with = "mix"
    )]
    pub probes: Vec<f32>,
    /// Also write one line per counted pair to FILE (comma-separated, no header): the truth (1
    /// visible, 0 blocked); then, the first point's end before the other's, the two ends'
    /// visible fractions, blocked tap weights, occluder ratios (stored over receiver depth),
    /// nearness, pixel angles (radians); the segment's length and where along it the exact ray
    /// is blocked (a fraction, -1 when it is not).
    #[arg(long, value_name = "FILE", conflicts_with = "mix")]
    pub csv: Option<PathBuf>,
    /// Measure instead what a per-texel cube resolution could buy: FINE.cssm is the same scene
    /// and atlas baked at twice the cube resolution (`cssm bake` with the same atlas and twice
    /// --cube); the texels whose maps see the most depth edges answer from it, for several
    /// fractions of the texels, with the runs their maps would add.
    #[arg(long, value_name = "FINE.cssm")]
    pub mix: Option<PathBuf>,
    /// With --mix: measure instead the upper bound of a per-pixel coverage hint, each 2x2 tap
    /// of FILE.cssm made soft by the fraction of its four sub-pixels in FINE.cssm that see past
    /// the receiver.
    #[arg(long, requires = "mix")]
    pub coverage: bool,
}

/// `--probes`: positive, finite and increasing (the probing stops at the first distance
/// beyond half the segment, so later ones must be farther).
fn check_probes(probes: &[f32]) -> Result<(), String> {
    let list = || {
        probes
            .iter()
            .map(f32::to_string)
            .collect::<Vec<_>>()
            .join(",")
    };
    if let Some(bad) = probes.iter().find(|&&k| !(k.is_finite() && k > 0.0)) {
        return Err(format!(
            "--probes {}: {bad} is not a positive number of texel sizes (e.g. 0.5,1,2)",
            list()
        ));
    }
    if probes.windows(2).any(|w| w[1] <= w[0]) {
        return Err(format!(
            "--probes {}: the distances must increase (e.g. 0.5,1,2)",
            list()
        ));
    }
    Ok(())
}

/// One end's answer for the other end's point.
#[derive(Default, Clone, Copy)]
struct End {
    /// Visible fraction, as `VisibilityQuery::visibility_from_senders` computes it.
    v: f32,
    /// Weight of the 2x2 taps that are blocked by a stored depth under half the receiver's
    /// depth: the occluder lies in this end's half of the segment.
    blocked_near: f32,
    /// Sum over the blocked taps of weight x (1 - stored depth / receiver depth).
    nearness: f32,
    /// Mean stored depth / receiver depth over the blocked taps (1 when none is blocked).
    occluder_ratio: f32,
    /// Visible fraction with a tent of radius 1.5 pixels over the pixels (up to 3x3 taps).
    tent_1_5: f32,
    /// Visible fraction with a tent of radius 2 pixels (up to 4x4 taps).
    tent_2: f32,
    /// Weight of the blocked taps.
    blocked: f32,
    /// Visible fraction with each texel's lookup turned towards where its blocked taps put the
    /// occluder on the segment from the sender point (not the texel's centre): parallax.
    v_parallax: f32,
    /// Visible fraction with each texel also probing points of the segment from the sender
    /// point at a few texel sizes out (occluders nearer the sender than a texel).
    v_probe: f32,
    /// Angle one pixel spans at the lookup direction (radians, mean over the senders).
    pixel_angle: f32,
}

/// The 2x2 pixels around the projection of the cube-frame direction `d` on a map of
/// resolution `n` whose grid is shifted by `offset`, with their bilinear weights (clamped to
/// the face), as the query takes them.
fn bilinear_taps(d: Vec3, n: u32, offset: glam::Vec2) -> [(u32, f32); 4] {
    let (face, u, v, _) = cube::project(d);
    let fx = ((u + 1.0) * 0.5 * n as f32 - 0.5 - offset.x).clamp(0.0, n as f32 - 1.0);
    let fy = ((v + 1.0) * 0.5 * n as f32 - 0.5 - offset.y).clamp(0.0, n as f32 - 1.0);
    let base = face * n * n;
    let (x0, y0) = (fx.floor() as u32, fy.floor() as u32);
    let (x1, y1) = ((x0 + 1).min(n - 1), (y0 + 1).min(n - 1));
    let (wx, wy) = (fx - x0 as f32, fy - y0 as f32);
    [
        (base + y0 * n + x0, (1.0 - wx) * (1.0 - wy)),
        (base + y0 * n + x1, wx * (1.0 - wy)),
        (base + y1 * n + x0, (1.0 - wx) * wy),
        (base + y1 * n + x1, wx * wy),
    ]
}

struct Ends<'a> {
    q: VisibilityQuery<'a>,
    file: &'a CssmFile,
    quantizer: DepthQuantizer,
    /// The probes' distances from the sender point, in texel sizes, increasing (`--probes`).
    probes: &'a [f32],
}

impl Ends<'_> {
    /// What the cube maps of `senders` say of the point `p_i` with normal `n_i`; the
    /// arithmetic of `VisibilityQuery::visibility_oriented`, keeping each tap.
    fn answer(&self, senders: &[(u32, f32)], p_j: Vec3, p_i: Vec3, n_i: Vec3) -> End {
        let n = self.file.params.cube_resolution;
        let near = self.file.params.near;
        let mut e = End::default();
        let mut ratio_sum = 0.0;
        let mut blocked = 0.0;
        for &(texel, ws) in senders {
            let t = &self.file.texels[texel as usize];
            let normal = t.nrm();
            if (p_i - t.pos()).dot(normal) < -near {
                continue;
            }
            let centre = self.q.cube_centre(texel);
            let offset = self.file.pixel_grid.offset(t.x, t.y);
            let frame = self.file.cube_frame;
            let (cube_normal, cube_n_i) = (frame.to_cube(normal), frame.to_cube(n_i));
            let mut d = p_i - centre;
            let below = d.dot(normal);
            if below < 0.0 {
                d -= normal * below;
            }
            if d.length_squared() < near * near * 1e-6 {
                e.v += ws;
                e.v_parallax += ws;
                e.v_probe += ws;
                e.tent_1_5 += ws;
                e.tent_2 += ws;
                continue;
            }
            let (face, u, v, depth) = cube::project(frame.to_cube(d));
            e.pixel_angle += ws * (2.0 / n as f32) / (1.0 + u * u + v * v).powf(0.75);
            let receiver_depth = |pixel: u32| -> f32 {
                let (ray, scale) = cube::cast_direction_at(n, pixel, cube_normal, offset);
                let denom = ray.dot(cube_n_i);
                if denom.abs() < 1e-4 {
                    return depth;
                }
                let along = (p_i - centre).dot(n_i) / denom * scale;
                if along.is_finite() && along > 0.0 {
                    along.clamp(0.5 * depth, 1.5 * depth)
                } else {
                    depth
                }
            };
            // (visible, stored / receiver depth) of one pixel; don't care is blocked.
            let tap = |pixel: u32| -> (bool, f32) {
                if cube::pixel_is_dont_care_at(n, pixel, cube_normal, offset) {
                    return (false, 1.0);
                }
                let stored = self.quantizer.depth(self.q.depth_code(texel, pixel));
                let receiver = receiver_depth(pixel);
                (stored >= receiver, stored / receiver)
            };
            // This texel's own first look: visible and blocked weights, and the blocked taps'
            // ratio sum (the parallax look below starts from it).
            let (mut v0, mut b0, mut rs0) = (0.0, 0.0, 0.0);
            for (pixel, wp) in bilinear_taps(frame.to_cube(d), n, offset) {
                let w = ws * wp;
                let (visible, ratio) = tap(pixel);
                if visible {
                    v0 += wp;
                    e.v += w;
                } else {
                    b0 += wp;
                    rs0 += wp * ratio;
                    blocked += w;
                    ratio_sum += w * ratio;
                    e.nearness += w * (1.0 - ratio).max(0.0);
                    if ratio < 0.5 {
                        e.blocked_near += w;
                    }
                }
            }
            // Parallax: the 2x2 PCF again, looking towards where the segment from p_j passes
            // the occluder the first lookup found.
            let visible_from = |d: Vec3| -> f32 {
                bilinear_taps(frame.to_cube(d), n, offset)
                    .iter()
                    .filter(|&&(pixel, _)| tap(pixel).0)
                    .map(|&(_, wp)| wp)
                    .sum()
            };
            let v1 = if b0 > 0.0 {
                let r = (rs0 / b0).clamp(PARALLAX_MIN_R, 1.0);
                let mut d2 = (p_j - centre) / r + (p_i - p_j);
                let below = d2.dot(normal);
                if below < 0.0 {
                    d2 -= normal * below;
                }
                visible_from(d2)
            } else {
                v0
            };
            e.v_parallax += ws * v1;
            // Probes: is the segment's point s out from p_j behind a stored depth?
            let segment = p_i - p_j;
            let length = segment.length();
            let size = t.area.sqrt();
            let mut probe_v = v0;
            for &k in self.probes {
                let s = k * size;
                if s > 0.5 * length {
                    break;
                }
                let x = p_j + segment * (s / length);
                let dx = x - centre;
                if dx.dot(normal) <= 0.0 {
                    continue;
                }
                let depth = cube::project(frame.to_cube(dx)).3;
                let mut vis = 0.0;
                for (pixel, wp) in bilinear_taps(frame.to_cube(dx), n, offset) {
                    if cube::pixel_is_dont_care_at(n, pixel, cube_normal, offset)
                        || self.quantizer.depth(self.q.depth_code(texel, pixel)) >= depth
                    {
                        vis += wp;
                    }
                }
                probe_v = probe_v.min(vis);
            }
            e.v_probe += ws * probe_v;
            // Wider tents over the face's pixels (clamped to the face, as the 2x2 is).
            let fx = ((u + 1.0) * 0.5 * n as f32 - 0.5 - offset.x).clamp(0.0, n as f32 - 1.0);
            let fy = ((v + 1.0) * 0.5 * n as f32 - 0.5 - offset.y).clamp(0.0, n as f32 - 1.0);
            let base = face * n * n;
            let (cx, cy) = (fx.round() as i64, fy.round() as i64);
            for (radius, slot) in [(1.5f32, &mut e.tent_1_5), (2.0, &mut e.tent_2)] {
                let (mut visible, mut total) = (0.0, 0.0);
                for y in cy - 2..=cy + 2 {
                    for x in cx - 2..=cx + 2 {
                        if x < 0 || y < 0 || x >= n as i64 || y >= n as i64 {
                            continue;
                        }
                        let w = (1.0 - (x as f32 - fx).abs() / radius).max(0.0)
                            * (1.0 - (y as f32 - fy).abs() / radius).max(0.0);
                        if w > 0.0 {
                            total += w;
                            if tap(base + y as u32 * n + x as u32).0 {
                                visible += w;
                            }
                        }
                    }
                }
                if total > 0.0 {
                    *slot += ws * visible / total;
                }
            }
        }
        e.blocked = blocked;
        e.occluder_ratio = if blocked > 0.0 {
            ratio_sum / blocked
        } else {
            1.0
        };
        e
    }
}

/// A rule combining the two ends' answers into a visible fraction.
type Rule = (&'static str, fn(&End, &End) -> f32);

fn weighted(a: f32, wa: f32, b: f32, wb: f32) -> f32 {
    (wa * a + wb * b) / (wa + wb)
}

/// The visible fractions `va` and `vb` of the ends `a` and `b` combined as the query combines
/// its ends (`visibility::combine_ends`: weights from each end's nearness).
fn as_the_query(va: f32, a: &End, vb: f32, b: &End) -> f32 {
    combine_ends(
        EndAnswer {
            visible: va,
            nearness: a.nearness,
        },
        EndAnswer {
            visible: vb,
            nearness: b.nearness,
        },
    )
}

/// Where the occluder lies along the segment, as a fraction from `a`'s end to `b`'s: what the
/// blocked taps' stored depths say (each an upper bound of the distance from its own end).
fn occluder_at(a: &End, b: &End) -> Option<f32> {
    match (a.blocked > 0.0, b.blocked > 0.0) {
        (true, true) => Some(0.5 * (a.occluder_ratio + 1.0 - b.occluder_ratio)),
        (true, false) => Some(a.occluder_ratio),
        (false, true) => Some(1.0 - b.occluder_ratio),
        (false, false) => None,
    }
}

/// Each end weighted by the inverse of its edge's uncertainty in world units at the
/// occluder: pixel angle (to the power `angle_power`) times distance to the occluder.
fn by_footprint(a: &End, b: &End, angle_power: f32, distance_power: f32) -> f32 {
    let Some(r) = occluder_at(a, b) else {
        return 0.5 * (a.v + b.v);
    };
    let r = r.clamp(0.02, 0.98);
    // An end whose senders all lie behind the other point has no lookup and no angle.
    let angle = |e: &End| {
        if e.pixel_angle > 0.0 {
            e.pixel_angle
        } else {
            1.0
        }
    };
    let wa = 1.0 / (angle(a).powf(angle_power) * r.powf(distance_power));
    let wb = 1.0 / (angle(b).powf(angle_power) * (1.0 - r).powf(distance_power));
    weighted(a.v, wa, b.v, wb)
}

/// The parallax look's nearest occluder, as a fraction of the way to the other point.
const PARALLAX_MIN_R: f32 = 0.05;

const RULES: [Rule; 21] = [
    ("the mean (today)", |a, b| 0.5 * (a.v + b.v)),
    ("an end blocked in its own half decides", |a, b| {
        if a.blocked_near >= 0.5 || b.blocked_near >= 0.5 {
            0.0
        } else {
            0.5 * (a.v + b.v)
        }
    }),
    (
        "the nearer end weighs more: exp(2 (1 - v) (1 - ratio))",
        |a, b| {
            let w = |e: &End| (2.0 * (1.0 - e.v) * (1.0 - e.occluder_ratio)).exp();
            weighted(a.v, w(a), b.v, w(b))
        },
    ),
    (
        "the nearer end weighs more: exp(1 (1 - v) (1 - ratio))",
        |a, b| {
            let w = |e: &End| (1.0 - e.v) * (1.0 - e.occluder_ratio);
            weighted(a.v, w(a).exp(), b.v, w(b).exp())
        },
    ),
    (
        "the nearer end weighs more: exp(4 (1 - v) (1 - ratio))",
        |a, b| {
            let w = |e: &End| 4.0 * (1.0 - e.v) * (1.0 - e.occluder_ratio);
            weighted(a.v, w(a).exp(), b.v, w(b).exp())
        },
    ),
    ("the nearer end weighs more: exp(2 nearness)", |a, b| {
        as_the_query(a.v, a, b.v, b)
    }),
    ("leaning to the lower: 0.9 mean + 0.1 min", |a, b| {
        0.9 * 0.5 * (a.v + b.v) + 0.1 * a.v.min(b.v)
    }),
    ("nearer end and leaning", |a, b| {
        let w = |e: &End| (2.0 * (1.0 - e.v) * (1.0 - e.occluder_ratio)).exp();
        0.95 * weighted(a.v, w(a), b.v, w(b)) + 0.05 * a.v.min(b.v)
    }),
    ("pixel tent radius 1.5 at each end", |a, b| {
        0.5 * (a.tent_1_5 + b.tent_1_5)
    }),
    ("pixel tent radius 2 at each end", |a, b| {
        0.5 * (a.tent_2 + b.tent_2)
    }),
    ("mean of 2x2 and tent 2", |a, b| {
        0.25 * (a.v + b.v + a.tent_2 + b.tent_2)
    }),
    (
        "an end weighs more where its tent 2 agrees with it",
        |a, b| {
            let w = |e: &End| 2.0 - (e.tent_2 - e.v).abs();
            weighted(a.v, w(a), b.v, w(b))
        },
    ),
    ("probes, nearer end weighs more", |a, b| {
        as_the_query(a.v_probe, a, b.v_probe, b)
    }),
    ("parallax, nearer end weighs more", |a, b| {
        as_the_query(a.v_parallax, a, b.v_parallax, b)
    }),
    ("parallax, mean", |a, b| 0.5 * (a.v_parallax + b.v_parallax)),
    ("footprint: 1 / (angle x distance)", |a, b| {
        by_footprint(a, b, 1.0, 1.0)
    }),
    ("footprint: 1 / distance", |a, b| {
        by_footprint(a, b, 0.0, 1.0)
    }),
    ("footprint: 1 / (angle x distance)^2", |a, b| {
        by_footprint(a, b, 2.0, 2.0)
    }),
    ("footprint: 1 / distance^2", |a, b| {
        by_footprint(a, b, 0.0, 2.0)
    }),
    ("footprint: 1 / (angle x distance^0.5)", |a, b| {
        by_footprint(a, b, 1.0, 0.5)
    }),
    ("footprint: 1 / distance^0.5", |a, b| {
        by_footprint(a, b, 0.0, 0.5)
    }),
];

/// Runs `cssm diagnose ends` with `args`, printing its figures on standard output.
///
/// # Errors
/// A message naming the file and the problem: `args.file` or `--mix` unreadable or not a
/// `.cssm` file, the scene its header records not loading or changed since the bake, `--mix`
/// not the same scene and atlas at twice the cube resolution, `--pairs 0`, `--probes` not
/// positive and increasing, the CSV not writable.
pub fn run(args: &EndsArgs, scenes: cssm_formats::LoadOptions) -> Result<(), String> {
    diagnose(args, scenes, &mut std::io::stdout().lock())
}

/// [`run`], printing to `out`.
pub(super) fn diagnose(
    args: &EndsArgs,
    scenes: cssm_formats::LoadOptions,
    out: &mut dyn Write,
) -> Result<(), String> {
    super::check_pairs(args.pairs)?;
    check_probes(&args.probes)?;
    if args.coverage && args.mix.is_none() {
        return Err("--coverage measures against the finer file of --mix FINE.cssm".to_string());
    }
    let path = args.file.display();
    if let Some(fine) = &args.mix {
        if args.csv.is_some() {
            return Err(
                "--csv writes the pairs of the rules; with --mix there are none".to_string(),
            );
        }
        return mix::mix(&args.file, fine, args, scenes, out);
    }
    let (file, scene) = super::load(&args.file, scenes)?;
    let bvh = SceneBvh::new(&scene);
    let eps = 1e-4 * scene.diameter();
    let ends = Ends {
        q: VisibilityQuery::new(&file, QueryOptions::default()),
        file: &file,
        quantizer: DepthQuantizer::new(file.params.near, file.params.far),
        probes: &args.probes,
    };
    let pairs = super::draw_pairs(&scene, args.pairs);
    let (mut count, mut query, mut either, mut both, mut split) = (0u32, 0u32, 0u32, 0u32, 0u32);
    let mut split_blocked_right = 0u32;
    let mut agree = [0u32; RULES.len()];
    // The fractions as an image uses them: their sum against the visible pairs' count (bias)
    // and their squared error against the 0/1 truth.
    let (mut bias, mut squared) = ([0f64; RULES.len()], [0f64; RULES.len()]);
    let mut visible = 0u32;
    let csv_error = |csv: &Path, e: std::io::Error| format!("--csv {}: {e}", csv.display());
    let mut csv = match &args.csv {
        Some(p) => Some((
            p,
            std::io::BufWriter::new(
                std::fs::File::create(p)
                    .map_err(|e| format!("--csv {}: cannot create the file: {e}", p.display()))?,
            ),
        )),
        None => None,
    };
    for (pj, pi) in &pairs {
        if !exchanges_light(pj, pi, eps) {
            continue;
        }
        let sj = ends.q.sender_texels(pj.triangle, pj.bary);
        let si = ends.q.sender_texels(pi.triangle, pi.bary);
        if sj.is_empty() || si.is_empty() {
            continue;
        }
        count += 1;
        let truth = exact_visible(&bvh, pj, pi, eps);
        visible += u32::from(truth);
        let a = ends.answer(&sj, pj.position, pi.position, pi.normal);
        let b = ends.answer(&si, pi.position, pj.position, pj.normal);
        let library = ends
            .q
            .visibility_between(&sj, pj.position, pj.normal, &si, pi.position, pi.normal)
            .unwrap_or(f32::NAN);
        query += u32::from((library >= 0.5) == truth);
        let (a_right, b_right) = ((a.v >= 0.5) == truth, (b.v >= 0.5) == truth);
        if let Some((csv_path, csv)) = csv.as_mut() {
            let from = pj.position + pj.normal * eps;
            let seg = pi.position - from;
            let length = seg.length();
            let r_true = bvh
                .closest_hit(from, seg / length, 0.0, length)
                .map_or(-1.0, |(t, _)| t / length);
            writeln!(
                csv,
                "{},{},{},{},{},{},{},{},{},{},{},{},{}",
                u8::from(truth),
                a.v,
                b.v,
                a.blocked,
                b.blocked,
                a.occluder_ratio,
                b.occluder_ratio,
                a.nearness,
                b.nearness,
                a.pixel_angle,
                b.pixel_angle,
                length,
                r_true
            )
            .map_err(|e| csv_error(csv_path, e))?;
        }
        either += u32::from(a_right || b_right);
        both += u32::from(a_right && b_right);
        if a_right != b_right {
            split += 1;
            split_blocked_right += u32::from(!truth);
        }
        for (k, (_, rule)) in RULES.iter().enumerate() {
            let v = rule(&a, &b);
            agree[k] += u32::from((v >= 0.5) == truth);
            let error = f64::from(v) - f64::from(u8::from(truth));
            bias[k] += error;
            squared[k] += error * error;
        }
    }
    if let Some((csv_path, mut csv)) = csv {
        csv.flush().map_err(|e| csv_error(csv_path, e))?;
    }
    let pc = |x: u32| 100.0 * x as f64 / count.max(1) as f64;
    let mut print = || -> std::io::Result<()> {
        writeln!(
            out,
            "{path}: {count} pairs that exchange light with texels at both ends"
        )?;
        writeln!(out, "  the library's query           {:.3}%", pc(query))?;
        writeln!(out, "  both ends right               {:.3}%", pc(both))?;
        writeln!(out, "  either end right (an oracle)  {:.3}%", pc(either))?;
        writeln!(
            out,
            "  ends split: {split} pairs, the blocked end right in {split_blocked_right} ({:.1}%)",
            100.0 * split_blocked_right as f64 / split.max(1) as f64
        )?;
        writeln!(
            out,
            "  agreement, pairs gained, visible fraction's bias (of the visible pairs) and RMSE:"
        )?;
        for (k, (name, _)) in RULES.iter().enumerate() {
            writeln!(
                out,
                "  {:>8.3}%  {:+6} pairs  bias {:+.4}  RMSE {:.4}  {name}",
                pc(agree[k]),
                agree[k] as i64 - agree[0] as i64,
                bias[k] / f64::from(visible.max(1)),
                (squared[k] / f64::from(count.max(1))).sqrt(),
            )?;
        }
        Ok(())
    };
    print().map_err(super::output_error)
}
