//! `cssm diagnose ends --mix FINE.cssm [--coverage]`: what a per-texel cube resolution, or a
//! per-pixel coverage hint, could buy at most before any format change (reports/visibility.md,
//! "Per-texel cube resolution and coverage hints"). FINE.cssm is the same scene and atlas baked
//! at twice the cube resolution, so that each texel's maps can be taken from either file.
use std::{io::Write, path::Path};

use cssm_bake::check::{exact_visible, exchanges_light};
use cssm_formats::{
    CssmFile,
    cube::{self, DepthQuantizer},
    visibility::{QueryOptions, VisibilityQuery},
};
use cssm_raycast::SceneBvh;
use glam::Vec3;

use super::{End, Ends, EndsArgs, as_the_query, bilinear_taps};

/// One end's visible fraction and nearness as `Ends::answer` computes them from the coarse
/// file's 2x2 taps, but each tap soft: the fraction of its four sub-pixels in the fine file
/// (twice the resolution) that see past the receiver. An upper bound of what a per-pixel
/// coverage hint could give.
fn answer_coverage(ec: &Ends, ef: &Ends, senders: &[(u32, f32)], p_i: Vec3, n_i: Vec3) -> End {
    let n = ec.file.params.cube_resolution;
    let nf = ef.file.params.cube_resolution;
    assert_eq!(
        nf,
        2 * n,
        "`mix` takes a fine file of twice the cube resolution only"
    );
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
fn changes(file: &CssmFile, keep: &dyn Fn(u32) -> bool) -> u64 {
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

/// `--mix FINE.cssm`: the query with the texels of highest `edge_score` (in the coarse file)
/// answered from FINE's cube maps instead (the same scene and atlas at a finer cube
/// resolution), for several fractions of the texels; what a per-texel cube resolution could
/// buy and what its runs would cost.
pub(super) fn mix(
    coarse_path: &Path,
    fine_path: &Path,
    args: &EndsArgs,
    scenes: cssm_formats::LoadOptions,
    out: &mut dyn Write,
) -> Result<(), String> {
    let (coarse, scene) = crate::diagnose::load(coarse_path, scenes)?;
    let coarse = &coarse;
    let fine = cssm_formats::cssm::read(fine_path).map_err(|e| format!("--mix {e}"))?;
    let (n, nf) = (coarse.params.cube_resolution, fine.params.cube_resolution);
    if nf != 2 * n {
        return Err(format!(
            "--mix {}: cube resolution {nf}, not twice the {n} of {}; FINE.cssm is the same \
             scene and atlas baked at twice the cube resolution",
            fine_path.display(),
            coarse_path.display()
        ));
    }
    // Each texel's maps are taken from either file: the texels must be the same ones.
    if fine.texels != coarse.texels {
        return Err(format!(
            "--mix {}: its atlas texels are not those of {}; FINE.cssm is the same scene and \
             atlas baked at twice the cube resolution",
            fine_path.display(),
            coarse_path.display()
        ));
    }
    let bvh = SceneBvh::new(&scene);
    let eps = 1e-4 * scene.diameter();
    let make = |f| Ends {
        q: VisibilityQuery::new(f, QueryOptions::default()),
        file: f,
        quantizer: DepthQuantizer::new(f.params.near, f.params.far),
        probes: &args.probes,
    };
    let (ec, ef) = (make(coarse), make(&fine));
    let texels = coarse.texels.len();
    let scores: Vec<u32> = (0..texels as u32)
        .map(|t| edge_score(&ec.q, &ec.quantizer, t, n))
        .collect();
    let mut order: Vec<u32> = (0..texels as u32).collect();
    order.sort_by_key(|&t| std::cmp::Reverse((scores[t as usize], t)));
    let mut rank = vec![0usize; texels];
    for (r, &t) in order.iter().enumerate() {
        rank[t as usize] = r;
    }
    let pairs = crate::diagnose::draw_pairs(&scene, args.pairs);
    if args.coverage {
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
        return writeln!(
            out,
            "{count} pairs; coarse taps covered by the fine file's sub-pixels: {:.3}%",
            100.0 * right as f64 / count as f64
        )
        .map_err(crate::diagnose::output_error);
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
    writeln!(
        out,
        "{} pairs; coarse {} runs, fine {} runs; texels {texels}",
        cases.len(),
        runs_coarse,
        runs_fine
    )
    .map_err(crate::diagnose::output_error)?;
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
        writeln!(
            out,
            "refine {:5.1}% of texels (score >= {:4}): agreement {:.3}%, runs {} + {} = {:.2}x",
            100.0 * fraction,
            order
                .get(cut.saturating_sub(1))
                .map_or(0, |&t| scores[t as usize]),
            100.0 * right as f64 / cases.len() as f64,
            runs_coarse,
            extra,
            (runs_coarse as f64 + extra as f64) / runs_coarse as f64
        )
        .map_err(crate::diagnose::output_error)?;
    }
    Ok(())
}
