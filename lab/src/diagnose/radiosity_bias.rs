//! `cssm diagnose radiosity-bias`: where the radiosity's indirect light loses against the path
//! tracer's (reports/final-gather.md, "The clusters' transfer: the nave's missing light").
//!
//! Over `--receivers` texels drawn at random (seed 1; default 1,500), one bounce of the spot
//! lights' light, as irradiance at each texel's centre, by four computations that differ in one
//! thing each:
//!
//! - *path traced*: `--rays` cosine-distributed rays from the texel's centre (default 1,024),
//!   each bringing back the exact direct light reflected (Kd + Ks, as the atlas reflects it)
//!   where it first hits: what the reference path tracer computes there, without its noise;
//! - *texels, exact*: every texel a sender, its exact direct light, the radiosity's transfer
//!   (`irradiance_from_texel`) and an exact ray cast between the centres: the atlas'
//!   discretisation and the transfer;
//! - *texels, CSSM*: the same with the CSSM query (both ends) for the ray cast;
//! - *hierarchy*: the CPU twin of the GPU radiosity at the default threshold (CSSM, clusters;
//!   `--threshold` sets another);
//! - and the hierarchy's gather again with the clusters' transfer four ways: *today* as it was
//!   before the normals' moment (each cluster's net projected area, `A dot(n_s, w)`, and its
//!   representative's visibility), *moment* (`transfer::irradiance_from_cluster`), *moment and
//!   back refined* (a cluster whose representative faces away from the receiver refined), and
//!   *moment and other side* (`transfer::visibility_sender`: the library's gather now), with
//!   the links each gathers per receiver.
//!
//! It prints each one's area-weighted sum against the path traced one, by receivers' material.
//! With `--leak` it prints instead where the light the CSSM query lets through and an exact ray
//! cast stops is stopped: the receiver's, the sender's and the blocker's materials, and where
//! along the segment the blocker lies.
use std::{f32::consts::PI, io::Write, path::PathBuf};

use cssm_formats::{
    CssmFile, Scene, Texel,
    visibility::{QueryOptions, VisibilityQuery},
};
use cssm_raycast::{SceneBvh, SplitMix64};
use cssm_runtime::{
    direct::cpu::{facing_normal, render_atlas},
    radiosity::{self, cpu, transfer::irradiance_from_texel},
};
use glam::Vec3;
use rayon::prelude::*;

/// `cssm diagnose radiosity-bias`'s arguments.
#[derive(clap::Args, Clone, Debug)]
pub struct RadiosityBiasArgs {
    /// The .cssm file to diagnose. The scene it was baked from (the directory its header
    /// records) must still be there, unchanged; its lights and materials are the ones used.
    #[arg(value_name = "FILE.cssm")]
    pub file: PathBuf,
    /// Receiving texels to draw at random (seed 1; fewer when the atlas has fewer texels).
    #[arg(long, default_value_t = 1500, value_name = "N")]
    pub receivers: usize,
    /// Cosine-distributed rays per receiver for the path traced irradiance, the reference the
    /// others are measured against.
    #[arg(long, default_value_t = 1024, value_name = "N")]
    pub rays: u32,
    /// The hierarchy's oracle threshold: a cluster is refined while the tone-mapped upper
    /// bound of what it sends is above this; smaller is slower and closer (the default is the
    /// radiosity's).
    #[arg(
        long,
        default_value_t = radiosity::DEFAULT_THRESHOLD,
        allow_negative_numbers = true,
        value_name = "T"
    )]
    pub threshold: f32,
    /// Print instead where the light the CSSM query lets through and an exact ray between the
    /// texel centres stops is stopped: by receiver, sender and blocker materials, and by where
    /// along the segment the blocker lies (sixths, from the receiver). The path tracing runs
    /// first all the same: a few --rays save its time.
    #[arg(long)]
    pub leak: bool,
}

/// Runs `cssm diagnose radiosity-bias` with `args`, printing its figures on standard output
/// (and its progress on standard error).
///
/// # Errors
/// A message naming the file and the problem: `args.file` unreadable or not a `.cssm` file,
/// the scene its header records (or its textures) not loading or changed since the bake,
/// `--receivers 0`, `--rays 0`, a threshold that is not a finite number.
pub fn run(args: &RadiosityBiasArgs, scenes: cssm_formats::LoadOptions) -> Result<(), String> {
    diagnose(args, scenes, &mut std::io::stdout().lock())
}

/// [`run`], printing to `out`.
pub(super) fn diagnose(
    args: &RadiosityBiasArgs,
    scenes: cssm_formats::LoadOptions,
    out: &mut dyn Write,
) -> Result<(), String> {
    if args.receivers == 0 {
        return Err("--receivers 0: draw at least one receiving texel (default 1500)".to_string());
    }
    if args.rays == 0 {
        return Err("--rays 0: trace at least one ray per receiver (default 1024)".to_string());
    }
    if !args.threshold.is_finite() {
        return Err(format!(
            "--threshold {}: not a finite number (default {})",
            args.threshold,
            radiosity::DEFAULT_THRESHOLD
        ));
    }
    let (receivers, rays, threshold) = (args.receivers, args.rays, args.threshold);
    let (file, scene) = super::load(&args.file, scenes)?;
    let path = args.file.display();
    let bvh = SceneBvh::new(&scene);
    let materials = cssm_runtime::load::cpu_materials(&scene)
        .map_err(|e| format!("{path}: the textures of the scene it was baked from: {e}"))?
        .0;
    let direct = render_atlas(&scene, &materials, &file.texels, &bvh);
    let albedo: Vec<Vec3> = radiosity::texel_albedo(&materials, &file)
        .iter()
        .map(|a| Vec3::new(a[0], a[1], a[2]))
        .collect();
    let query = VisibilityQuery::new(&file, QueryOptions::default());
    let count = file.texels.len();
    let mut rng = SplitMix64(1);
    let chosen: Vec<u32> = (0..receivers.min(count))
        .map(|_| ((rng.next_f64() * count as f64) as u32).min(count as u32 - 1))
        .collect();
    let eps = 1e-4 * scene.diameter();
    // The exact direct light leaving a surface point, as `render_atlas` computes it for a
    // texel (a texel of no area standing there).
    let leaving = |triangle: u32, y: Vec3, towards: Vec3| -> Vec3 {
        let t = Texel {
            position: y.to_array(),
            normal: facing_normal(&scene, triangle, towards).to_array(),
            area: 0.0,
            material: scene.triangle_materials[triangle as usize],
            chart: 0,
            object: 0,
            x: 0,
            y: 0,
        };
        render_atlas(&scene, &materials, &[t], &bvh)[0]
    };
    eprintln!(
        "{} texels; path tracing {} receivers x {rays} rays",
        count,
        chosen.len()
    );
    let traced: Vec<Vec3> = chosen
        .par_iter()
        .map(|&r| {
            let t = &file.texels[r as usize];
            let (p, n) = (t.pos(), t.nrm());
            let (u, v) = n.any_orthonormal_pair();
            let mut rng = SplitMix64(0x5eed ^ u64::from(r));
            let mut sum = Vec3::ZERO;
            for _ in 0..rays {
                let (a, b) = (rng.next_f64() as f32, rng.next_f64() as f32);
                let (rad, phi) = (a.sqrt(), 2.0 * PI * b);
                let d =
                    (u * rad * phi.cos() + v * rad * phi.sin() + n * (1.0 - a).sqrt()).normalize();
                let origin = p + n * eps;
                if let Some((dist, tri)) = bvh.closest_hit(origin, d, 0.0, f32::INFINITY) {
                    sum += leaving(tri, origin + d * dist, -d);
                }
            }
            sum * (PI / rays as f32)
        })
        .collect();
    if args.leak {
        return print_leaks(&scene, &file, &bvh, &query, &direct, &chosen, eps, out)
            .map_err(super::output_error);
    }
    eprintln!("texel senders, exact and CSSM");
    let (exact, cssm): (Vec<Vec3>, Vec<Vec3>) = chosen
        .par_iter()
        .map(|&r| {
            let t = &file.texels[r as usize];
            let (p, n) = (t.pos(), t.nrm());
            let (mut e, mut c) = (Vec3::ZERO, Vec3::ZERO);
            for (s, ts) in file.texels.iter().enumerate() {
                let (y, m) = (ts.pos(), ts.nrm());
                if s == r as usize || n.dot(y - p) <= 0.0 || m.dot(p - y) <= 0.0 {
                    continue;
                }
                let gathered = irradiance_from_texel(p, n, y, m, ts.area, direct[s]).0;
                if gathered == Vec3::ZERO {
                    continue;
                }
                if bvh.segment_clear(p + n * eps, y + m * eps) {
                    e += gathered;
                }
                let v = query
                    .visibility_between(&[(s as u32, 1.0)], y, m, &[(r, 1.0)], p, n)
                    .unwrap_or(0.0);
                c += gathered * v;
            }
            (e, c)
        })
        .unzip();
    eprintln!("hierarchy");
    let hierarchy = cpu::radiosity(
        &query,
        &direct,
        &albedo,
        &cpu::Traversal {
            threshold,
            exposure: 1.0,
        },
        1,
    )
    .texel_irradiance;
    // The hierarchy's one bounce for the chosen receivers with the clusters' transfer the
    // ways `MODES` lists.
    let variants = cluster_variants(&query, &direct, &albedo, &chosen, threshold);
    let lum = |c: Vec3| c.dot(Vec3::new(0.2126, 0.7152, 0.0722));
    let mut by_material: std::collections::BTreeMap<u32, [f64; 9]> = Default::default();
    for (k, &r) in chosen.iter().enumerate() {
        let t = &file.texels[r as usize];
        let w = f64::from(t.area);
        let row = by_material.entry(t.material).or_default();
        row[0] += w * f64::from(lum(traced[k]));
        row[1] += w * f64::from(lum(exact[k]));
        row[2] += w * f64::from(lum(cssm[k]));
        row[3] += w * f64::from(lum(hierarchy[r as usize]));
        row[4] += w;
        for (v, slot) in variants[k].iter().zip(&mut row[5..]) {
            *slot += w * f64::from(lum(v.0));
        }
    }
    let mut all = [0f64; 9];
    writeln!(
        out,
        "{path}: one bounce, irradiance at {} texel centres ({rays} rays each), area-weighted",
        chosen.len()
    )
    .map_err(super::output_error)?;
    writeln!(
        out,
        "{:>24} {:>10} {:>10} {:>10} {:>10} {:>12} {:>12} {:>12} {:>12}",
        "material",
        "area",
        "texels",
        "CSSM",
        "hierarchy",
        MODES[0].0,
        MODES[1].0,
        MODES[2].0,
        MODES[3].0
    )
    .map_err(super::output_error)?;
    for (m, row) in &by_material {
        for (a, b) in all.iter_mut().zip(row) {
            *a += b;
        }
        print_row(out, &scene.materials[*m as usize].name, row).map_err(super::output_error)?;
    }
    print_row(out, "all", &all).map_err(super::output_error)?;
    for (k, (name, _)) in MODES.iter().enumerate() {
        let links: u64 = variants.iter().map(|v| u64::from(v[k].1)).sum();
        writeln!(
            out,
            "{name}: {:.1} links per receiver",
            links as f64 / variants.len() as f64
        )
        .map_err(super::output_error)?;
    }
    writeln!(out, "(each against the path traced irradiance)").map_err(super::output_error)
}

/// One row of the table: `row`'s area, then each computation against the path traced one.
fn print_row(out: &mut dyn Write, name: &str, row: &[f64; 9]) -> std::io::Result<()> {
    let r = |k: usize| row[k] / row[0];
    writeln!(
        out,
        "{name:>24} {:>10.2} {:>10.4} {:>10.4} {:>10.4} {:>12.4} {:>12.4} {:>12.4} {:>12.4}",
        row[4],
        r(1),
        r(2),
        r(3),
        r(5),
        r(6),
        r(7),
        r(8)
    )
}

/// How a variant of the gather treats a cluster.
#[derive(Clone, Copy)]
struct Mode {
    /// The cluster's projected area from its normals' second moment instead of its mean
    /// normal.
    moment: bool,
    /// Refine a cluster whose representative faces away from the receiver (its visibility
    /// would be its own back's).
    refine_back: bool,
    /// Where the representative faces away from the receiver, ask the visibility of the
    /// cluster's texel whose normal is the most opposite to the representative's instead.
    other_side: bool,
}

const MODES: [(&str, Mode); 4] = [
    (
        "today",
        Mode {
            moment: false,
            refine_back: false,
            other_side: false,
        },
    ),
    (
        "moment",
        Mode {
            moment: true,
            refine_back: false,
            other_side: false,
        },
    ),
    (
        "m.+back ref.",
        Mode {
            moment: true,
            refine_back: true,
            other_side: false,
        },
    ),
    (
        "m.+other side",
        Mode {
            moment: true,
            refine_back: false,
            other_side: true,
        },
    ),
];

/// [`cpu::gather_texel`] of one bounce from `direct` for the receivers `chosen`, for each of
/// [`MODES`]: the irradiance and the links gathered.
fn cluster_variants(
    query: &VisibilityQuery,
    direct: &[Vec3],
    albedo: &[Vec3],
    chosen: &[u32],
    threshold: f32,
) -> Vec<[(Vec3, u32); 4]> {
    use cssm_runtime::radiosity::transfer::{
        irradiance_bound, irradiance_from, irradiance_from_cluster, tone_mapped, visibility_sender,
    };
    // One bounce's gather: the emitter flags are not read.
    let twin = cpu::TwinScene::baked(query, &[]);
    let (nodes, leaves) = (&twin.hierarchy.nodes, &twin.hierarchy.leaf_texels);
    let (texels, spreads) = (&twin.texels, &twin.spreads);
    // Radiance per node: the area-weighted mean of its texels' (as `cpu::pull`).
    let mut radiance = vec![Vec3::ZERO; nodes.len()];
    for i in (0..nodes.len()).rev() {
        let node = &nodes[i];
        if node.count == 1 {
            radiance[i] = direct[leaves[node.first as usize] as usize];
        } else {
            let (l, r) = (i + 1, nodes[i + 1].skip as usize);
            let (al, ar) = (nodes[l].area, nodes[r].area);
            radiance[i] = if al + ar > 0.0 {
                (radiance[l] * al + radiance[r] * ar) / (al + ar)
            } else {
                0.5 * (radiance[l] + radiance[r])
            };
        }
    }
    let gather = |receiver: u32, mode: Mode| -> (Vec3, u32) {
        let t = &texels[receiver as usize];
        let (p, n) = (t.pos(), t.nrm());
        let rho = albedo[receiver as usize].max_element();
        let (mut e, mut links) = (Vec3::ZERO, 0);
        let mut s = 0usize;
        while s < nodes.len() {
            let node = &nodes[s];
            let l = radiance[s];
            let y = &texels[node.representative as usize];
            let back = (p - y.pos()).dot(y.nrm()) <= 0.0;
            if node.count > 1
                && (tone_mapped(irradiance_bound(p, n, node, l) * (rho / PI), 1.0) > threshold
                    || (mode.refine_back && back))
            {
                s += 1;
                continue;
            }
            links += 1;
            let sender = node.representative;
            if sender != receiver && l.cmpgt(Vec3::ZERO).any() {
                let unoccluded = if node.count == 1 {
                    irradiance_from_texel(p, n, y.pos(), y.nrm(), node.area, l).0
                } else if mode.moment {
                    irradiance_from_cluster(p, n, y.pos(), node, &spreads[s], l).0
                } else {
                    irradiance_from(p, n, y.pos(), Vec3::from(node.normal), node.area, l).0
                };
                if unoccluded.cmpgt(Vec3::ZERO).any() {
                    let (sender, y) = if mode.other_side {
                        let other = visibility_sender(node, &spreads[s], texels, p);
                        (other, &texels[other as usize])
                    } else {
                        (sender, y)
                    };
                    let v = query
                        .visibility_between(
                            &[(receiver, 1.0)],
                            p,
                            n,
                            &[(sender, 1.0)],
                            y.pos(),
                            y.nrm(),
                        )
                        .unwrap_or(1.0);
                    e += unoccluded * v;
                }
            }
            s = node.skip as usize;
        }
        (e, links)
    };
    chosen
        .par_iter()
        .map(|&r| MODES.map(|(_, mode)| gather(r, mode)))
        .collect()
}

/// `--leak`: the light that the CSSM query lets through (visible fraction > 0) where the exact
/// ray between the texel centres is blocked, by (receiver, sender, blocker) materials, and by
/// where along the segment the blocker lies (sixths, from the receiver). It takes what `diagnose`
/// has computed by then.
#[allow(clippy::too_many_arguments)]
fn print_leaks(
    scene: &Scene,
    file: &CssmFile,
    bvh: &SceneBvh,
    query: &VisibilityQuery,
    direct: &[Vec3],
    chosen: &[u32],
    eps: f32,
    out: &mut dyn Write,
) -> std::io::Result<()> {
    let name = |m: u32| scene.materials[m as usize].name.clone();
    let lum = |c: Vec3| f64::from(c.dot(Vec3::new(0.2126, 0.7152, 0.0722)));
    let mut combos: std::collections::BTreeMap<(String, String, String), (f64, u32)> =
        Default::default();
    let mut along = [0f64; 6];
    for &r in chosen {
        let t = &file.texels[r as usize];
        let (p, n) = (t.pos(), t.nrm());
        for (s, ts) in file.texels.iter().enumerate() {
            let (y, m) = (ts.pos(), ts.nrm());
            if s == r as usize || n.dot(y - p) <= 0.0 || m.dot(p - y) <= 0.0 {
                continue;
            }
            let gathered = irradiance_from_texel(p, n, y, m, ts.area, direct[s]).0;
            if gathered == Vec3::ZERO {
                continue;
            }
            let (a, b) = (p + n * eps, y + m * eps);
            let length = (b - a).length();
            let Some((hit, triangle)) =
                bvh.closest_hit(a, (b - a) / length, 1e-5 * length, length * (1.0 - 1e-5))
            else {
                continue;
            };
            let v = query
                .visibility_between(&[(s as u32, 1.0)], y, m, &[(r, 1.0)], p, n)
                .unwrap_or(0.0);
            if v <= 0.0 {
                continue;
            }
            let w = lum(gathered) * f64::from(v);
            let blocker = scene.triangle_materials[triangle as usize];
            let entry = combos
                .entry((name(t.material), name(ts.material), name(blocker)))
                .or_default();
            entry.0 += w;
            entry.1 += 1;
            along[((hit / length).clamp(0.0, 0.999) * 6.0) as usize] += w;
        }
    }
    let total: f64 = along.iter().sum();
    let mut rows: Vec<_> = combos.into_iter().collect();
    rows.sort_by(|a, b| b.1.0.total_cmp(&a.1.0));
    writeln!(
        out,
        "light let through where an exact ray is blocked: {total:.4} in all"
    )?;
    for ((receiver, sender, blocker), (w, pairs)) in rows.iter().take(15) {
        writeln!(
            out,
            "{receiver:>20} <- {sender:>20} through {blocker:>20}: {w:.4} ({pairs} pairs)"
        )?;
    }
    let shares: Vec<String> = along
        .iter()
        .map(|w| format!("{:.0}%", 100.0 * w / total))
        .collect();
    writeln!(
        out,
        "where the blocker lies, sixths of the segment from the receiver: {}",
        shares.join(" ")
    )?;
    Ok(())
}
