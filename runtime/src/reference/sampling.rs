//! The path tracer's random numbers and the sampling of a bounce: each pixel's own SplitMix64
//! stream (so an image depends on the options only, never on the number of threads), and the
//! direction a path continues in, drawn from the mixture of the cosine-weighted diffuse lobe
//! and the normalised Phong lobe, with the mixture's density for MIS.

use cssm_raycast::SplitMix64;
use glam::Vec3;

use super::tracer::Vertex;
use crate::direct::cpu::brdf;

/// The random stream of pixel `pixel`: SplitMix64 started at `mix(seed) ^ mix(pixel)`, `mix`
/// being SplitMix64's output function (so neighbouring pixels' streams are unrelated, not
/// shifted copies of each other).
pub(super) fn pixel_rng(seed: u64, pixel: u64) -> SplitMix64 {
    let mix = |v: u64| SplitMix64(v).next_u64();
    SplitMix64(mix(seed) ^ mix(pixel ^ 0x5851_F42D_4C95_7F2D))
}

/// Uniform in `[0, 1)` with 24 random bits (every value exact in `f32`, never 1).
pub(super) fn uniform(rng: &mut SplitMix64) -> f32 {
    (rng.next_u64() >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Mean of the three channels.
pub(super) fn mean(c: Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

/// Unit vector at polar angle `acos(cos_theta)` and azimuth `2 pi u` around the unit `axis`.
fn around(axis: Vec3, cos_theta: f32, u: f32) -> Vec3 {
    let (t, b) = axis.any_orthonormal_pair();
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (s, c) = (std::f32::consts::TAU * u).sin_cos();
    (t * (c * sin_theta) + b * (s * sin_theta) + axis * cos_theta).normalize()
}

/// The probabilities of the diffuse and the glossy lobe of [`sample_bounce`] at `x`, `None`
/// for a black material.
fn lobe_choice(x: &Vertex) -> Option<f32> {
    let diffuse_weight = mean(x.albedo).max(0.0);
    let glossy_weight = mean(Vec3::from(x.material.ks)).max(0.0);
    (diffuse_weight + glossy_weight > 0.0)
        .then(|| diffuse_weight / (diffuse_weight + glossy_weight))
}

/// The density (per solid angle) with which [`sample_bounce`] draws the direction `wi` above
/// the surface at `x`: the mixture of the cosine lobe and the Phong lobe; zero below it.
pub(super) fn bounce_pdf(x: &Vertex, wi: Vec3) -> f32 {
    use std::f32::consts::PI;
    let Some(p_diffuse) = lobe_choice(x) else {
        return 0.0;
    };
    let cos_i = x.n.dot(wi);
    if cos_i <= 0.0 {
        return 0.0;
    }
    let ns = x.material.ns;
    let mirror = (-x.v).reflect(x.n);
    let mut pdf = p_diffuse * cos_i / PI;
    if p_diffuse < 1.0 {
        pdf += (1.0 - p_diffuse) * ((ns + 1.0) / (2.0 * PI) * wi.dot(mirror).max(0.0).powf(ns));
    }
    pdf
}

/// Draws the direction `wi` a path continues in from `x` (towards the next vertex) from the
/// mixture of a cosine-weighted hemisphere (diffuse lobe) and the normalised Phong lobe around
/// the mirror direction of `x.v` (glossy lobe), chosen in proportion to the mean albedo and the
/// mean Ks; returns `wi`, `BRDF(wi, x.v) cos / pdf(wi)` and `pdf(wi)`, pdf being the mixture's
/// ([`bounce_pdf`]). `None` ends the path: a black material, or a direction below the surface
/// (the glossy lobe reaches below the horizon at grazing angles; those samples carry no light).
pub(super) fn sample_bounce(x: &Vertex, rng: &mut SplitMix64) -> Option<(Vec3, Vec3, f32)> {
    let p_diffuse = lobe_choice(x)?;
    let ns = x.material.ns;
    let mirror = (-x.v).reflect(x.n);
    let (u0, u1, u2) = (uniform(rng), uniform(rng), uniform(rng));
    let wi = if u0 < p_diffuse {
        around(x.n, (1.0 - u1).sqrt(), u2)
    } else {
        around(mirror, (1.0 - u1).powf(1.0 / (ns + 1.0)), u2)
    };
    let cos_i = x.n.dot(wi);
    if cos_i <= 0.0 {
        return None;
    }
    let pdf = bounce_pdf(x, wi);
    if pdf.is_nan() || pdf <= 0.0 {
        return None;
    }
    let f = brdf(x.albedo, x.material, wi, x.n, x.v);
    Some((wi, f * (cos_i / pdf), pdf))
}
