//! `cssm diagnose filters`: what the "filters" class of `cssm check` is (reports/visibility.md,
//! "The filters"). Over the pairs of `cssm check` (seed 1, `--pairs`, 100,000 by default; only
//! the exchanging pairs with texels at both ends): each sender filter variant's agreement, both
//! ends and one, other thresholds and wider tents; then, for each wrong answer whose sender
//! texel is right by the cube class's test, which single change would have made it right, the
//! other end's own texel classified as `check` classifies the sender's (`-v` prints each case).
use std::{io::Write, path::PathBuf};

use cssm_bake::check::{exact_visible, exchanges_light};
use cssm_formats::{
    CssmFile,
    visibility::{QueryOptions, VisibilityQuery},
};
use cssm_raycast::{SceneBvh, SurfacePoint};
use glam::{Vec2, Vec3};

/// Why a counted pair's texels are there: the loop keeps only pairs with texels at both ends.
const KEPT: &str = "a counted pair has texels at both ends";

/// `cssm diagnose filters`'s arguments.
#[derive(clap::Args, Clone, Debug)]
pub struct FiltersArgs {
    /// The .cssm file to diagnose. The scene it was baked from (the directory its header
    /// records) must still be there, unchanged.
    #[arg(value_name = "FILE.cssm")]
    pub file: PathBuf,
    /// Random surface point pairs to draw, as `cssm check` draws them (seed 1); only those
    /// that exchange light with texels at both ends count. The reports' figures are over
    /// 100000.
    #[arg(long, default_value_t = 100_000, value_name = "N")]
    pub pairs: u32,
    /// Print every wrong answer the breakdown counts: which change would have made it right,
    /// the truth, both ends' answers, and each sender texel of both ends (weight, normal's dot,
    /// offset from the point's plane and distance in texel sizes, its cube map's answer, an
    /// exact ray's).
    #[arg(short, long)]
    pub verbose: bool,
}

struct Ctx<'a> {
    q: VisibilityQuery<'a>,
    file: &'a CssmFile,
    bvh: &'a SceneBvh,
    eps: f32,
}

#[derive(Clone, Copy, Default)]
struct Filt {
    min_dot: f32,      // keep texels whose normal . point normal >= this
    max_plane: f32,    // keep texels whose |offset from point plane| <= this * texel size
    max_dist: f32,     // keep texels within this * texel size of the point
    front_other: bool, // keep texels that see the other point in front (cube-style front test)
}

impl<'a> Ctx<'a> {
    fn atlas_point(&self, p: &SurfacePoint) -> Vec2 {
        let uv = self.file.triangle_uvs[p.triangle];
        Vec2::from(uv[0]) * p.bary[0]
            + Vec2::from(uv[1]) * p.bary[1]
            + Vec2::from(uv[2]) * p.bary[2]
    }
    fn senders(&self, p: &SurfacePoint, filt: Option<Filt>, other: Vec3) -> Vec<(u32, f32)> {
        let a = self.atlas_point(p);
        let s = self.q.sender_texels_at(a);
        let Some(f) = filt else { return s };
        let centre = self.q.texel_at_point(a);
        let mut out: Vec<(u32, f32)> = s
            .iter()
            .copied()
            .filter(|&(t, _)| {
                if Some(t) == centre {
                    return true;
                }
                let tx = &self.file.texels[t as usize];
                let size = tx.area.sqrt();
                let d = tx.pos() - p.position;
                tx.nrm().dot(p.normal) >= f.min_dot
                    && d.dot(p.normal).abs() <= f.max_plane * size
                    && d.length() <= f.max_dist * size
                    && (!f.front_other || (other - tx.pos()).dot(tx.nrm()) > 0.0)
            })
            .collect();
        let tot: f32 = out.iter().map(|x| x.1).sum();
        if tot <= 0.0 {
            return centre.map(|c| vec![(c, 1.0)]).unwrap_or_default();
        }
        for x in out.iter_mut() {
            x.1 /= tot;
        }
        out
    }
    fn wide(&self, p: &SurfacePoint, radius: f32) -> Vec<(u32, f32)> {
        let a = self.atlas_point(p);
        let Some(c) = self.q.texel_at_point(a) else {
            return vec![];
        };
        let chart = self.file.texels[c as usize].chart;
        let mut out = vec![];
        let mut tot = 0.0;
        let (cx, cy) = (a.x.floor() as i64, a.y.floor() as i64);
        for dy in -3..=3i64 {
            for dx in -3..=3i64 {
                let Some(t) = self.q.cell(cx + dx, cy + dy) else {
                    continue;
                };
                if self.file.texels[t as usize].chart != chart {
                    continue;
                }
                let ox = ((cx + dx) as f32 + 0.5 - a.x).abs() / radius;
                let oy = ((cy + dy) as f32 + 0.5 - a.y).abs() / radius;
                let mut w = (1.0 - ox).max(0.0) * (1.0 - oy).max(0.0);
                if radius < 0.0 {
                    // 2x2 bilinear cells, flattened weights (tent of radius -radius)
                    let (bx, by) = ((a.x - 0.5).floor() as i64, (a.y - 0.5).floor() as i64);
                    let inside = (cx + dx == bx || cx + dx == bx + 1)
                        && (cy + dy == by || cy + dy == by + 1);
                    let ox2 = ((cx + dx) as f32 + 0.5 - a.x).abs() / -radius;
                    let oy2 = ((cy + dy) as f32 + 0.5 - a.y).abs() / -radius;
                    w = if inside {
                        (1.0 - ox2).max(0.0) * (1.0 - oy2).max(0.0)
                    } else {
                        0.0
                    };
                }
                if w > 0.0 {
                    out.push((t, w));
                    tot += w;
                }
            }
        }
        if tot <= 0.0 {
            return vec![(c, 1.0)];
        }
        for x in out.iter_mut() {
            x.1 /= tot;
        }
        out
    }
    fn vis(&self, s: &[(u32, f32)], p: &SurfacePoint) -> f32 {
        self.q
            .visibility_from_senders(s, p.position, Some(p.normal))
            .unwrap_or(f32::NAN)
    }
    /// class of the end `a` seen towards `b`: 0 ok, 1 atlas, 2 near, 3 cube
    fn class(&self, a: &SurfacePoint, b: &SurfacePoint, truth: bool) -> u8 {
        let Some(texel) = self.q.texel_at(a.triangle, a.bary) else {
            return 9;
        };
        let t = &self.file.texels[texel as usize];
        let to = b.position + b.normal * self.eps;
        let from_texel = self.bvh.segment_clear(t.pos() + t.nrm() * self.eps, to);
        let from_cube = self.bvh.segment_clear(self.q.cube_centre(texel), to);
        let cube = self
            .q
            .visibility_oriented(texel, b.position, Some(b.normal))
            >= 0.5;
        if from_texel != truth {
            1
        } else if from_cube != from_texel {
            2
        } else if cube != from_cube {
            3
        } else {
            0
        }
    }
}

/// Runs `cssm diagnose filters` with `args`, printing its figures on standard output.
///
/// # Errors
/// A message naming the file and the problem: `args.file` unreadable or not a `.cssm` file,
/// the scene its header records not loading or changed since the bake, `--pairs 0`.
pub fn run(args: &FiltersArgs, scenes: cssm_formats::LoadOptions) -> Result<(), String> {
    diagnose(args, scenes, &mut std::io::stdout().lock())
}

/// [`run`], printing to `out`.
pub(super) fn diagnose(
    args: &FiltersArgs,
    scenes: cssm_formats::LoadOptions,
    out: &mut dyn Write,
) -> Result<(), String> {
    super::check_pairs(args.pairs)?;
    let (file, scene) = super::load(&args.file, scenes)?;
    let bvh = SceneBvh::new(&scene);
    let eps = 1e-4 * scene.diameter();
    let ctx = Ctx {
        q: VisibilityQuery::new(&file, QueryOptions::default()),
        file: &file,
        bvh: &bvh,
        eps,
    };
    let pairs = super::draw_pairs(&scene, args.pairs);
    let verbose = args.verbose;
    // rules
    let rules: Vec<(&str, Option<Filt>)> = vec![
        ("base", None),
        (
            "dot0.99",
            Some(Filt {
                min_dot: 0.99,
                max_plane: f32::INFINITY,
                max_dist: f32::INFINITY,
                front_other: false,
            }),
        ),
        (
            "dot0.9",
            Some(Filt {
                min_dot: 0.9,
                max_plane: f32::INFINITY,
                max_dist: f32::INFINITY,
                front_other: false,
            }),
        ),
        (
            "dot0.5",
            Some(Filt {
                min_dot: 0.5,
                max_plane: f32::INFINITY,
                max_dist: f32::INFINITY,
                front_other: false,
            }),
        ),
        (
            "plane0.25",
            Some(Filt {
                min_dot: -2.0,
                max_plane: 0.25,
                max_dist: f32::INFINITY,
                front_other: false,
            }),
        ),
        (
            "plane0.5",
            Some(Filt {
                min_dot: -2.0,
                max_plane: 0.5,
                max_dist: f32::INFINITY,
                front_other: false,
            }),
        ),
        (
            "dot.99+pl.25",
            Some(Filt {
                min_dot: 0.99,
                max_plane: 0.25,
                max_dist: f32::INFINITY,
                front_other: false,
            }),
        ),
        (
            "dist2",
            Some(Filt {
                min_dot: -2.0,
                max_plane: f32::INFINITY,
                max_dist: 2.0,
                front_other: false,
            }),
        ),
        (
            "dist1.5",
            Some(Filt {
                min_dot: -2.0,
                max_plane: f32::INFINITY,
                max_dist: 1.5,
                front_other: false,
            }),
        ),
        (
            "front",
            Some(Filt {
                min_dot: -2.0,
                max_plane: f32::INFINITY,
                max_dist: f32::INFINITY,
                front_other: true,
            }),
        ),
        (
            "dot.99+front",
            Some(Filt {
                min_dot: 0.99,
                max_plane: f32::INFINITY,
                max_dist: f32::INFINITY,
                front_other: true,
            }),
        ),
        (
            "own",
            Some(Filt {
                min_dot: 2.0,
                max_plane: 0.0,
                max_dist: 0.0,
                front_other: false,
            }),
        ),
    ];
    let mut agree = vec![0u32; rules.len()];
    let mut agree_one = vec![0u32; rules.len()];
    let mut n = 0u32;
    let mut thr = [0u32; 4];
    let mut wide = [0u32; 12];
    // filter-class breakdown for base
    let mut fclass = std::collections::BTreeMap::<String, u32>::new();
    for (pj, pi) in &pairs {
        if !exchanges_light(pj, pi, eps) {
            continue;
        }
        if ctx.q.texel_at(pj.triangle, pj.bary).is_none()
            || ctx.q.texel_at(pi.triangle, pi.bary).is_none()
        {
            continue;
        }
        n += 1;
        let truth = exact_visible(&bvh, pj, pi, eps);
        for (k, (_, r)) in rules.iter().enumerate() {
            let sj = ctx.senders(pj, *r, pi.position);
            let si = ctx.senders(pi, *r, pj.position);
            let f = ctx.vis(&sj, pi);
            let b = ctx.vis(&si, pj);
            if ((0.5 * (f + b)) >= 0.5) == truth {
                agree[k] += 1;
            }
            if (f >= 0.5) == truth {
                agree_one[k] += 1;
            }
            if k == 0 {
                for (ti, th) in [0.45f32, 0.55, 0.6].iter().enumerate() {
                    if ((0.5 * (f + b)) >= *th) == truth {
                        thr[ti] += 1;
                    }
                }
                let sh = |v: f32| v * v * (3.0 - 2.0 * v);
                if ((0.5 * (sh(f) + sh(b))) >= 0.5) == truth {
                    thr[3] += 1;
                }
            }
        }
        for (k, r) in [1.0f32, 1.5, 2.0, 2.5, -1.5, -2.0].iter().enumerate() {
            let f = ctx.vis(&ctx.wide(pj, *r), pi);
            let b = ctx.vis(&ctx.wide(pi, *r), pj);
            if ((0.5 * (f + b)) >= 0.5) == truth {
                wide[k] += 1;
            }
            if (f >= 0.5) == truth {
                wide[6 + k] += 1;
            }
        }
        // base breakdown
        let sj = ctx.senders(pj, None, pi.position);
        let si = ctx.senders(pi, None, pj.position);
        let f = ctx.vis(&sj, pi);
        let b = ctx.vis(&si, pj);
        if ((0.5 * (f + b)) >= 0.5) == truth {
            continue;
        }
        let cj = ctx.class(pj, pi, truth);
        if cj != 0 {
            continue;
        }
        // sender's own cube right. own values:
        let tj = ctx.q.texel_at(pj.triangle, pj.bary).expect(KEPT);
        let ti = ctx.q.texel_at(pi.triangle, pi.bary).expect(KEPT);
        let f0 = ctx.q.visibility_oriented(tj, pi.position, Some(pi.normal));
        let b0 = ctx.q.visibility_oriented(ti, pj.position, Some(pj.normal));
        let ci = ctx.class(pi, pj, truth);
        let t = if truth { 1.0 } else { 0.0 };
        let which = if ((0.5 * (f0 + b)) >= 0.5) == truth {
            "sender-filter"
        } else if ((0.5 * (f + b0)) >= 0.5) == truth {
            "other-end-filter"
        } else if ((0.5 * (f0 + b0)) >= 0.5) == truth {
            "both-filters"
        } else {
            "other-end-own"
        };
        let mixed = |s: &[(u32, f32)], o: &SurfacePoint| {
            let v: Vec<bool> = s
                .iter()
                .map(|&(tt, _)| {
                    let tx = &file.texels[tt as usize];
                    bvh.segment_clear(tx.pos() + tx.nrm() * eps, o.position + o.normal * eps)
                })
                .collect();
            v.iter().any(|&x| x) && v.iter().any(|&x| !x)
        };
        let odd = |s: &[(u32, f32)], p: &SurfacePoint| {
            s.iter().any(|&(tt, _)| {
                let tx = &file.texels[tt as usize];
                let size = tx.area.sqrt();
                let d = tx.pos() - p.position;
                tx.nrm().dot(p.normal) < 0.99
                    || d.dot(p.normal).abs() > 0.1 * size
                    || d.length() > 1.5 * size
            })
        };
        *fclass
            .entry(format!("ZZ sender-texels-exact-mixed={}", mixed(&sj, pi)))
            .or_default() += 1;
        *fclass
            .entry(format!("ZZ other-texels-exact-mixed={}", mixed(&si, pj)))
            .or_default() += 1;
        *fclass
            .entry(format!(
                "ZZ sender-texels-odd(dot<.99|plane>.1|dist>1.5)={}",
                odd(&sj, pj)
            ))
            .or_default() += 1;
        *fclass
            .entry(format!("ZZ other-texels-odd={}", odd(&si, pi)))
            .or_default() += 1;
        *fclass.entry("ZZ total".to_string()).or_default() += 1;
        let key = format!("{which} other-class={ci} truth={truth}");
        *fclass.entry(key).or_default() += 1;
        if verbose {
            let desc = |s: &[(u32, f32)], p: &SurfacePoint, o: &SurfacePoint| -> String {
                s.iter()
                    .map(|&(tt, w)| {
                        let tx = &file.texels[tt as usize];
                        let size = tx.area.sqrt();
                        let d = tx.pos() - p.position;
                        let v = ctx.q.visibility_oriented(tt, o.position, Some(o.normal));
                        let ex = bvh
                            .segment_clear(tx.pos() + tx.nrm() * eps, o.position + o.normal * eps);
                        format!(
                            "[w{:.2} dot{:.3} pl{:.2} dist{:.2} v{:.2} ex{}]",
                            w,
                            tx.nrm().dot(p.normal),
                            d.dot(p.normal) / size,
                            d.length() / size,
                            v,
                            ex as u8
                        )
                    })
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            writeln!(
                out,
                "{which} truth{t} f{f:.2} f0{f0:.2} b{b:.2} b0{b0:.2} ci{ci} \
                 dist{:.1}\n  S {}\n  R {}",
                (pi.position - pj.position).length(),
                desc(&sj, pj, pi),
                desc(&si, pi, pj)
            )
            .map_err(super::output_error)?;
        }
    }
    writeln!(out, "exchanging pairs with texels at both ends: {n}").map_err(super::output_error)?;
    for (k, (name, _)) in rules.iter().enumerate() {
        writeln!(
            out,
            "{name:>14}: both {:.3}%  one {:.3}%",
            100.0 * agree[k] as f64 / n as f64,
            100.0 * agree_one[k] as f64 / n as f64
        )
        .map_err(super::output_error)?;
    }
    writeln!(
        out,
        "both ends, threshold 0.45/0.55/0.6, mean of smoothsteps: {:?}",
        thr[..4]
            .iter()
            .map(|&a| format!("{:.3}", 100.0 * a as f64 / n as f64))
            .collect::<Vec<_>>()
    )
    .map_err(super::output_error)?;
    writeln!(
        out,
        "tent radius 1/1.5/2/2.5/2x2-flat1.5/2x2-flat2: both ends {:?}, one end {:?}",
        wide[..6]
            .iter()
            .map(|&a| format!("{:.3}", 100.0 * a as f64 / n as f64))
            .collect::<Vec<_>>(),
        wide[6..]
            .iter()
            .map(|&a| format!("{:.3}", 100.0 * a as f64 / n as f64))
            .collect::<Vec<_>>()
    )
    .map_err(super::output_error)?;
    for (k, v) in &fclass {
        writeln!(out, "{k}: {v}").map_err(super::output_error)?;
    }
    Ok(())
}
