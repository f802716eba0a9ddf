//! The emitters (area lights) as a path samples them: every emitting triangle, chosen in
//! proportion to its power (area times the luminance of its mean emission) and a uniform point
//! on it, with the solid-angle density of that choice, and the power heuristic (Veach and
//! Guibas 1995) that weighs light sampling against BSDF sampling.

use cssm_formats::Scene;
use cssm_raycast::SplitMix64;
use glam::Vec3;

use super::sampling::uniform;
use crate::{common::tonemap::luminance, direct::cpu::front_normal, gpu_types::GpuMaterial};

/// The emitting triangles of a scene, for sampling points on them in proportion to their
/// power (area times the luminance of their mean emission).
pub(super) struct Emitters {
    /// Emitting triangles.
    triangles: Vec<u32>,
    /// Cumulative probability of choosing `triangles[..=i]`; the last is 1.
    cdf: Vec<f64>,
    /// Per scene triangle, the density of the sampled point per unit area (its choice
    /// probability over its area), zero for triangles that do not emit.
    area_pdf: Vec<f32>,
}

impl Emitters {
    pub(super) fn new(scene: &Scene, materials: &[GpuMaterial]) -> Self {
        let mut triangles = Vec::new();
        let mut power = Vec::new();
        for t in 0..scene.triangles.len() {
            let m = &materials[scene.triangle_materials[t] as usize];
            let [a, b, c] = scene.triangle(t);
            let area = 0.5 * (b - a).cross(c - a).length();
            let weight = area * luminance(Vec3::from(m.emission_mean));
            if weight > 0.0 && weight.is_finite() {
                triangles.push(t as u32);
                power.push(weight as f64);
            }
        }
        let total: f64 = power.iter().sum();
        let mut cdf = Vec::with_capacity(power.len());
        let mut area_pdf = vec![0.0f32; scene.triangles.len()];
        let mut sum = 0.0;
        for (&t, &w) in triangles.iter().zip(&power) {
            sum += w;
            cdf.push(sum / total);
            let [a, b, c] = scene.triangle(t as usize);
            let area = 0.5 * (b - a).cross(c - a).length() as f64;
            area_pdf[t as usize] = (w / total / area) as f32;
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Self {
            triangles,
            cdf,
            area_pdf,
        }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// A triangle in proportion to its power and a uniform point on it.
    pub(super) fn sample(&self, scene: &Scene, rng: &mut SplitMix64) -> (u32, Vec3) {
        let u = uniform(rng) as f64;
        let i = self
            .cdf
            .partition_point(|&c| c <= u)
            .min(self.cdf.len() - 1);
        let t = self.triangles[i];
        let [a, b, c] = scene.triangle(t as usize);
        let su = uniform(rng).sqrt();
        let (b0, b1) = (1.0 - su, uniform(rng) * su);
        (t, a * b0 + b * b1 + c * (1.0 - b0 - b1))
    }

    /// The solid-angle density with which [`Self::sample`] picks the point `y` of triangle `t`
    /// seen from `p`, `None` when `p` is not in front of the triangle (it sends nothing there).
    pub(super) fn solid_angle_pdf(&self, scene: &Scene, t: u32, p: Vec3, y: Vec3) -> Option<f32> {
        let d = y - p;
        let dist2 = d.length_squared();
        let cos_l = front_normal(scene, t).dot(-d) / dist2.sqrt();
        (cos_l > 0.0 && dist2 > 0.0).then(|| self.area_pdf[t as usize] * dist2 / cos_l)
    }
}

/// The power heuristic (exponent 2) weight of a strategy of density `pdf` against another of
/// density `other`.
pub(super) fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let (a, b) = (pdf * pdf, other * other);
    if a + b > 0.0 && (a + b).is_finite() {
        a / (a + b)
    } else if pdf.is_infinite() {
        1.0
    } else {
        0.0
    }
}
