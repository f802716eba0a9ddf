//! Diagnostic of how the two ends' answers are combined (reports/visibility.md, "Which end to
//! trust"). Run
//! `cargo build --release --example endsdiag && ./target/release/examples/endsdiag FILE.cssm`
//! (the pairs of `cssm check`, seed 1, 100,000; only the exchanging pairs with texels at both
//! ends). Each end is asked as the query asks it (sender filter, 2x2 PCF, receiver-plane depth)
//! and, besides, with what the rules below need: where its blocking pixels' stored depths put
//! the occluder, wider pixel filters, a parallax-corrected second look and probes of the
//! segment near the sender ("What else was tried on the turned church"; `PROBES=0.5,1,2` sets
//! the probes' distances in texel sizes). With `ENDS_CSV=FILE` it also writes one line per pair:
//! truth, both ends' answers, blocked weights, occluder ratios, nearness, pixel angles, the
//! segment's length and where along it the exact ray is blocked (-1 when it is not).
//!
//! With `MIX=FINE.cssm` (the same scene and atlas baked at twice the cube resolution) it
//! measures instead what a per-texel cube resolution could buy: the query with the texels that
//! see the most depth edges answered from FINE, for several fractions of the texels, and the
//! runs those texels' maps would add; with `COVERAGE=1` as well, an upper bound of a per-pixel
//! coverage hint: each of the coarse file's 2x2 taps soft, the fraction of its four sub-pixels
//! in FINE that see past the receiver ("Per-texel cube resolution and coverage hints").
use cssm::{
    bake::check::{exact_visible, exchanges_light},
    formats::{
        self,
        cube::{self, DepthQuantizer},
        visibility::{EndAnswer, QueryOptions, VisibilityQuery, combine_ends},
    },
    raycast::{SceneBvh, SplitMix64, SurfacePoint, SurfaceSampler},
};
use glam::Vec3;

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
    file: &'a formats::CssmFile,
    quantizer: DepthQuantizer,
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
            for k in probes() {
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

/// The probes' distances from the sender point, in texel sizes (`PROBES`, default 1, 2, 4).
fn probes() -> Vec<f32> {
    std::env::var("PROBES").map_or(vec![1.0, 2.0, 4.0], |v| {
        v.split(',')
            .map(|x| {
                x.trim().parse().unwrap_or_else(|_| {
                    eprintln!(
                        "endsdiag: PROBES: '{x}' is not a number (texel sizes, e.g. 0.5,1,2)"
                    );
                    std::process::exit(2)
                })
            })
            .collect()
    })
}

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

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: endsdiag FILE.cssm");
        std::process::exit(2);
    };
    let file = formats::cssm::read(std::path::Path::new(&path)).unwrap();
    if let Some(fine) = std::env::var_os("MIX") {
        return mix(&file, std::path::Path::new(&fine));
    }
    let scene = formats::Scene::load(std::path::Path::new(&file.scene.dir)).unwrap();
    let bvh = SceneBvh::new(&scene);
    let eps = 1e-4 * scene.diameter();
    let ends = Ends {
        q: VisibilityQuery::new(&file, QueryOptions::default()),
        file: &file,
        quantizer: DepthQuantizer::new(file.params.near, file.params.far),
    };
    let sampler = SurfaceSampler::new(&scene);
    let mut rng = SplitMix64(1);
    let pairs: Vec<(SurfacePoint, SurfacePoint)> = (0..100_000)
        .map(|_| {
            let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
            (sampler.point(r()), sampler.point(r()))
        })
        .collect();
    let (mut count, mut query, mut either, mut both, mut split) = (0u32, 0u32, 0u32, 0u32, 0u32);
    let mut split_blocked_right = 0u32;
    let mut agree = [0u32; RULES.len()];
    // The fractions as an image uses them: their sum against the visible pairs' count (bias)
    // and their squared error against the 0/1 truth.
    let (mut bias, mut squared) = ([0f64; RULES.len()], [0f64; RULES.len()]);
    let mut visible = 0u32;
    let mut csv = std::env::var_os("ENDS_CSV").map(|p| {
        let file = std::fs::File::create(&p).unwrap_or_else(|e| {
            eprintln!(
                "endsdiag: cannot create ENDS_CSV {}: {e}",
                std::path::Path::new(&p).display()
            );
            std::process::exit(2)
        });
        std::io::BufWriter::new(file)
    });
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
        if let Some(out) = csv.as_mut() {
            use std::io::Write;
            let from = pj.position + pj.normal * eps;
            let seg = pi.position - from;
            let length = seg.length();
            let r_true = bvh
                .closest_hit(from, seg / length, 0.0, length)
                .map_or(-1.0, |(t, _)| t / length);
            writeln!(
                out,
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
            .unwrap();
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
    let pc = |x: u32| 100.0 * x as f64 / count.max(1) as f64;
    println!("{path}: {count} pairs that exchange light with texels at both ends");
    println!("  the library's query           {:.3}%", pc(query));
    println!("  both ends right               {:.3}%", pc(both));
    println!("  either end right (an oracle)  {:.3}%", pc(either));
    println!(
        "  ends split: {split} pairs, the blocked end right in {split_blocked_right} ({:.1}%)",
        100.0 * split_blocked_right as f64 / split.max(1) as f64
    );
    println!("  agreement, pairs gained, visible fraction's bias (of the visible pairs) and RMSE:");
    for (k, (name, _)) in RULES.iter().enumerate() {
        println!(
            "  {:>8.3}%  {:+6} pairs  bias {:+.4}  RMSE {:.4}  {name}",
            pc(agree[k]),
            agree[k] as i64 - agree[0] as i64,
            bias[k] / f64::from(visible.max(1)),
            (squared[k] / f64::from(count.max(1))).sqrt(),
        );
    }
}

/// One end's visible fraction and nearness as `Ends::answer` computes them from the coarse
/// file's 2x2 taps, but each tap soft: the fraction of its four sub-pixels in the fine file
/// (twice the resolution) that see past the receiver. An upper bound of what a per-pixel
/// coverage hint could give.
fn answer_coverage(ec: &Ends, ef: &Ends, senders: &[(u32, f32)], p_i: Vec3, n_i: Vec3) -> End {
    let n = ec.file.params.cube_resolution;
    let nf = ef.file.params.cube_resolution;
    assert_eq!(nf, 2 * n);
    let near = ec.file.params.near;
    let frame = ec.file.cube_frame;
    let mut e = End::default();
    for &(texel, ws) in senders {
        let t = &ec.file.texels[texel as usize];
        let normal = t.nrm();
        if (p_i - t.pos()).dot(normal) < -near {
            continue;
        }
        let centre = ec.q.cube_centre(texel);
        let offset = ec.file.pixel_grid.offset(t.x, t.y);
        let (cube_normal, cube_n_i) = (frame.to_cube(normal), frame.to_cube(n_i));
        let mut d = p_i - centre;
        let below = d.dot(normal);
        if below < 0.0 {
            d -= normal * below;
        }
        if d.length_squared() < near * near * 1e-6 {
            e.v += ws;
            continue;
        }
        let depth = cube::project(frame.to_cube(d)).3;
        let receiver_depth = |pixel: u32| -> f32 {
            let (ray, scale) = cube::cast_direction_at(nf, pixel, cube_normal, offset);
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
        for (pixel, wp) in bilinear_taps(frame.to_cube(d), n, offset) {
            let w = ws * wp;
            let (face, rest) = (pixel / (n * n), pixel % (n * n));
            let (x, y) = (rest % n, rest / n);
            for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let fine = face * nf * nf + (2 * y + dy) * nf + 2 * x + dx;
                let wq = 0.25 * w;
                if cube::pixel_is_dont_care_at(nf, fine, cube_normal, offset) {
                    continue;
                }
                let stored = ef.quantizer.depth(ef.q.depth_code(texel, fine));
                let receiver = receiver_depth(fine);
                if stored >= receiver {
                    e.v += wq;
                } else {
                    e.nearness += wq * (1.0 - stored / receiver).max(0.0);
                }
            }
        }
    }
    e
}

/// Per-texel score of how much sub-pixel edge a texel's cube map holds: its pixels with a
/// 4-neighbour (same face) whose depth differs by more than a quarter.
fn edge_score(q: &VisibilityQuery, quantizer: &DepthQuantizer, texel: u32, n: u32) -> u32 {
    let mut depth = vec![0f32; (6 * n * n) as usize];
    for (p, d) in depth.iter_mut().enumerate() {
        *d = quantizer.depth(q.depth_code(texel, p as u32));
    }
    let mut score = 0;
    for face in 0..6 {
        for y in 0..n {
            for x in 0..n {
                let i = (face * n * n + y * n + x) as usize;
                let differs = |j: usize| {
                    let (a, b) = (depth[i], depth[j]);
                    a.max(b) > 1.25 * a.min(b)
                };
                if (x + 1 < n && differs(i + 1)) || (y + 1 < n && differs(i + n as usize)) {
                    score += 1;
                }
            }
        }
    }
    score
}

/// Code changes along the sequence restricted to the texels `keep` says (a run count's
/// estimate for a file holding only those texels' maps).
fn changes(file: &formats::CssmFile, keep: &dyn Fn(u32) -> bool) -> u64 {
    let n = file.params.cube_resolution;
    let pixels = (6 * n * n) as usize;
    let mut last: Vec<Option<u16>> = vec![None; pixels];
    let mut count = 0u64;
    for (k, &texel) in file.sequence.iter().enumerate() {
        if !keep(texel) {
            continue;
        }
        for (p, slot) in last.iter_mut().enumerate() {
            let code = file.runs.lookup(k as u32, p as u32);
            if *slot != Some(code) {
                count += 1;
                *slot = Some(code);
            }
        }
    }
    count
}

/// `MIX=FINE.cssm`: the query with the texels of highest `edge_score` (in the coarse file)
/// answered from FINE's cube maps instead (the same scene and atlas at a finer cube
/// resolution), for several fractions of the texels; what a per-texel cube resolution could
/// buy and what its runs would cost.
fn mix(coarse: &formats::CssmFile, fine_path: &std::path::Path) {
    let fine = formats::cssm::read(fine_path).unwrap_or_else(|e| {
        eprintln!("endsdiag: MIX {}: {e}", fine_path.display());
        std::process::exit(2)
    });
    if fine.texels != coarse.texels
        || fine.params.cube_resolution != 2 * coarse.params.cube_resolution
    {
        eprintln!(
            "endsdiag: MIX {} must be the same scene and atlas at twice the cube resolution",
            fine_path.display()
        );
        std::process::exit(2);
    }
    let scene = formats::Scene::load(std::path::Path::new(&coarse.scene.dir)).unwrap();
    let bvh = SceneBvh::new(&scene);
    let eps = 1e-4 * scene.diameter();
    fn make(f: &formats::CssmFile) -> Ends<'_> {
        Ends {
            q: VisibilityQuery::new(f, QueryOptions::default()),
            file: f,
            quantizer: DepthQuantizer::new(f.params.near, f.params.far),
        }
    }
    let (ec, ef) = (make(coarse), make(&fine));
    let texels = coarse.texels.len();
    let n = coarse.params.cube_resolution;
    let scores: Vec<u32> = (0..texels as u32)
        .map(|t| edge_score(&ec.q, &ec.quantizer, t, n))
        .collect();
    let mut order: Vec<u32> = (0..texels as u32).collect();
    order.sort_by_key(|&t| std::cmp::Reverse((scores[t as usize], t)));
    let mut rank = vec![0usize; texels];
    for (r, &t) in order.iter().enumerate() {
        rank[t as usize] = r;
    }
    let sampler = SurfaceSampler::new(&scene);
    let mut rng = SplitMix64(1);
    let pairs: Vec<(SurfacePoint, SurfacePoint)> = (0..100_000)
        .map(|_| {
            let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
            (sampler.point(r()), sampler.point(r()))
        })
        .collect();
    if std::env::var_os("COVERAGE").is_some() {
        let (mut count, mut right) = (0u32, 0u32);
        for (pj, pi) in &pairs {
            if !exchanges_light(pj, pi, eps) {
                continue;
            }
            let sj = ec.q.sender_texels(pj.triangle, pj.bary);
            let si = ec.q.sender_texels(pi.triangle, pi.bary);
            if sj.is_empty() || si.is_empty() {
                continue;
            }
            count += 1;
            let truth = exact_visible(&bvh, pj, pi, eps);
            let a = answer_coverage(&ec, &ef, &sj, pi.position, pi.normal);
            let b = answer_coverage(&ec, &ef, &si, pj.position, pj.normal);
            right += u32::from((as_the_query(a.v, &a, b.v, &b) >= 0.5) == truth);
        }
        println!(
            "{count} pairs; coarse taps covered by the fine file's sub-pixels: {:.3}%",
            100.0 * right as f64 / count as f64
        );
        return;
    }
    // Per exchanging pair: the truth and each end's per-texel answers from both files.
    type PerTexel = Vec<(u32, End, End)>;
    let mut cases: Vec<(bool, PerTexel, PerTexel)> = Vec::new();
    for (pj, pi) in &pairs {
        if !exchanges_light(pj, pi, eps) {
            continue;
        }
        let sj = ec.q.sender_texels(pj.triangle, pj.bary);
        let si = ec.q.sender_texels(pi.triangle, pi.bary);
        if sj.is_empty() || si.is_empty() {
            continue;
        }
        let truth = exact_visible(&bvh, pj, pi, eps);
        let per = |senders: &[(u32, f32)], p_j: Vec3, p_i: Vec3, n_i: Vec3| -> PerTexel {
            senders
                .iter()
                .map(|&s| {
                    (
                        s.0,
                        ec.answer(&[s], p_j, p_i, n_i),
                        ef.answer(&[s], p_j, p_i, n_i),
                    )
                })
                .collect()
        };
        cases.push((
            truth,
            per(&sj, pj.position, pi.position, pi.normal),
            per(&si, pi.position, pj.position, pj.normal),
        ));
    }
    let (runs_coarse, runs_fine) = (coarse.runs.runs.len(), fine.runs.runs.len());
    println!(
        "{} pairs; coarse {} runs, fine {} runs; texels {texels}",
        cases.len(),
        runs_coarse,
        runs_fine
    );
    for fraction in [0.0, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 0.75, 1.0] {
        let cut = (fraction * texels as f64).round() as usize;
        let refined = |t: u32| rank[t as usize] < cut;
        let sum = |per: &PerTexel| {
            let mut e = End::default();
            for (t, c, f) in per {
                let x = if refined(*t) { f } else { c };
                e.v += x.v;
                e.nearness += x.nearness;
            }
            e
        };
        let right = cases
            .iter()
            .filter(|(truth, a, b)| {
                let (a, b) = (sum(a), sum(b));
                (as_the_query(a.v, &a, b.v, &b) >= 0.5) == *truth
            })
            .count();
        let extra = if cut == 0 {
            0
        } else {
            changes(&fine, &refined)
        };
        println!(
            "refine {:5.1}% of texels (score >= {:4}): agreement {:.3}%, runs {} + {} = {:.2}x",
            100.0 * fraction,
            order
                .get(cut.saturating_sub(1))
                .map_or(0, |&t| scores[t as usize]),
            100.0 * right as f64 / cases.len() as f64,
            runs_coarse,
            extra,
            (runs_coarse as f64 + extra as f64) / runs_coarse as f64
        );
    }
}
