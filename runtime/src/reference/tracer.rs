//! The integrator: a pixel's radiance by path tracing (see the module docs of
//! [`crate::reference`]). At every vertex the spot lights' light by next-event estimation, the
//! emitters' light by light sampling and BSDF sampling weighed by MIS ([`EmitterSampling`]),
//! then a continuation drawn from the vertex's BRDF lobes, with no Russian roulette.

use cssm_formats::Scene;
use cssm_raycast::{SceneBvh, SplitMix64};
use glam::{DVec3, Vec3};

use super::{
    EmitterSampling, ReferenceOptions,
    emitters::{Emitters, power_heuristic},
    render::Layers,
    sampling::{bounce_pdf, pixel_rng, sample_bounce},
};
use crate::{
    common::camera::View,
    direct::cpu::{
        albedo_at, brdf, direct_radiance, emission_at, emitted_radiance, facing_normal,
        front_normal, shading_normal,
    },
    gpu_types::GpuMaterial,
    load::AlbedoTexture,
};

/// A surface point of a path.
#[derive(Clone, Copy)]
pub(super) struct Vertex<'a> {
    /// Position.
    pub(super) p: Vec3,
    /// Unit shading normal on the side the path arrives from (the geometric one tilted by the
    /// material's normal map): the cosines, the BRDF and the sampled lobes take it.
    pub(super) n: Vec3,
    /// Unit geometric normal on that side: ray origins are lifted along it, and a direction
    /// below it leaves no light (the surface itself is in the way).
    pub(super) ng: Vec3,
    /// Unit direction back along the path (towards the eye or the previous vertex).
    pub(super) v: Vec3,
    /// Kd times the albedo texture at `p`.
    pub(super) albedo: Vec3,
    pub(super) material: &'a GpuMaterial,
}

/// The scene as the paths see it.
pub(super) struct Tracer<'a> {
    pub(super) scene: &'a Scene,
    pub(super) materials: &'a [GpuMaterial],
    pub(super) textures: &'a [AlbedoTexture],
    pub(super) bvh: &'a SceneBvh,
    /// Offset of ray origins off the surface.
    pub(super) eps: f32,
    /// The emitting triangles.
    pub(super) emitters: Emitters,
    /// How paths gather the emitters' light.
    pub(super) sampling: EmitterSampling,
}

impl<'a> Tracer<'a> {
    /// The vertex at `p` on `triangle`, reached along a ray whose origin lies towards `towards`
    /// (decides the side of the normal), seen from the unit direction `v`.
    fn vertex(&self, triangle: u32, p: Vec3, towards: Vec3, v: Vec3) -> Vertex<'a> {
        let material = &self.materials[self.scene.triangle_materials[triangle as usize] as usize];
        let ng = facing_normal(self.scene, triangle, towards);
        Vertex {
            p,
            n: shading_normal(self.scene, material, self.textures, triangle, p, ng),
            ng,
            v,
            albedo: albedo_at(self.scene, material, self.textures, triangle, p),
            material,
        }
    }

    /// Radiance leaving `x` towards `x.v` straight from the lights (next-event estimation).
    fn direct(&self, x: &Vertex) -> Vec3 {
        direct_radiance(
            self.scene, self.bvh, self.eps, x.p, x.ng, x.n, x.v, x.albedo, x.material,
        )
        .0
    }

    /// The emitters' light reflected at `x` towards `x.v`, estimated from one point sampled on
    /// them (light sampling) with an exact shadow ray, weighted against BSDF sampling by the
    /// power heuristic under [`EmitterSampling::Mis`].
    fn emitter_light(&self, x: &Vertex, rng: &mut SplitMix64) -> Vec3 {
        let (t, y) = self.emitters.sample(self.scene, rng);
        let Some(pdf) = self.emitters.solid_angle_pdf(self.scene, t, x.p, y) else {
            return Vec3::ZERO;
        };
        let wi = (y - x.p).normalize();
        let cos_i = x.n.dot(wi);
        if cos_i <= 0.0 || x.ng.dot(wi) <= 0.0 || !pdf.is_finite() {
            return Vec3::ZERO;
        }
        let m = &self.materials[self.scene.triangle_materials[t as usize] as usize];
        let le = emission_at(self.scene, m, self.textures, t, y);
        if le == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let lifted = y + front_normal(self.scene, t) * self.eps;
        if !self.bvh.segment_clear(x.p + x.ng * self.eps, lifted) {
            return Vec3::ZERO;
        }
        let weight = match self.sampling {
            EmitterSampling::Mis => power_heuristic(pdf, bounce_pdf(x, wi)),
            _ => 1.0,
        };
        brdf(x.albedo, x.material, wi, x.n, x.v) * le * (cos_i * weight / pdf)
    }

    /// The radiance the emitter `t` sends back along a continuation from `x` in the direction
    /// `wi` (drawn with the density `pdf`) that met it at `y`: its emission when `x` lies in
    /// front of it, weighted against light sampling under [`EmitterSampling::Mis`].
    fn emitter_hit(&self, x: &Vertex, wi: Vec3, pdf: f32, t: u32, y: Vec3) -> Vec3 {
        let m = &self.materials[self.scene.triangle_materials[t as usize] as usize];
        let le = emitted_radiance(self.scene, m, self.textures, t, y, -wi);
        if le == Vec3::ZERO {
            return Vec3::ZERO;
        }
        let weight = match self.sampling {
            EmitterSampling::Mis => {
                let light = self.emitters.solid_angle_pdf(self.scene, t, x.p, y);
                power_heuristic(pdf, light.unwrap_or(0.0))
            }
            _ => 1.0,
        };
        le * weight
    }

    /// Radiance of pixel (`x`, `y`), and with `layers` not empty its light per bounce there.
    pub(super) fn pixel(
        &self,
        view: &View,
        x: u32,
        y: u32,
        options: &ReferenceOptions,
        layers: &mut Layers,
    ) -> Vec3 {
        layers.mean.fill(Vec3::ZERO);
        layers.sum.fill(DVec3::ZERO);
        let dir = view.primary_ray(x, y);
        let Some((t, triangle)) = self.bvh.closest_hit(view.eye, dir, 0.0, f32::INFINITY) else {
            return Vec3::ZERO;
        };
        // The same point and normal as `render_screen`, so the direct light is identical.
        let p = view.eye + dir * t;
        let first = self.vertex(triangle, p, view.eye - p, -dir);
        let mut radiance = Vec3::ZERO;
        if options.component.has_direct() {
            radiance += self.direct(&first);
            radiance += emitted_radiance(
                self.scene,
                first.material,
                self.textures,
                triangle,
                p,
                view.eye - p,
            );
        }
        if let Some(direct) = layers.mean.first_mut() {
            *direct = radiance;
        }
        if options.component.has_indirect() && options.bounces > 0 {
            let pixel = y as u64 * view.width as u64 + x as u64;
            let mut rng = pixel_rng(options.seed, pixel);
            let samples = options.samples_per_pixel.max(1);
            let mut sum = DVec3::ZERO;
            for _ in 0..samples {
                let mut l = self.indirect(&first, options.bounces, &mut rng, &mut layers.path);
                let mut scale = 1.0;
                if let Some(c) = options.clamp {
                    let largest = l.max_element();
                    if largest > c {
                        scale = c / largest;
                        l *= scale;
                    }
                }
                sum += l.as_dvec3();
                for (s, p) in layers.sum.iter_mut().zip(&layers.path) {
                    *s += (*p * scale).as_dvec3();
                }
            }
            radiance += (sum / samples as f64).as_vec3();
            for (m, s) in layers.mean.iter_mut().skip(1).zip(&layers.sum) {
                *m = (*s / samples as f64).as_vec3();
            }
        }
        radiance
    }

    /// One path from `first` of at most `bounces` bounces: the radiance it brings back to
    /// `first` along `first.v`, not counting the direct light at `first` (the spot lights'
    /// reflected once, and its own emission): the emitters' light reflected at vertices 0 to
    /// `bounces - 1` and the spot lights' at vertices 1 to `bounces`. With `per_bounce` not
    /// empty, the light of bounce `b + 1` goes to `per_bounce[b]` too.
    fn indirect(
        &self,
        first: &Vertex<'a>,
        bounces: u32,
        rng: &mut SplitMix64,
        per_bounce: &mut [Vec3],
    ) -> Vec3 {
        let emitters = !self.emitters.is_empty();
        let light_sampling = emitters && self.sampling != EmitterSampling::Bsdf;
        let bsdf_sampling = emitters && self.sampling != EmitterSampling::Light;
        let mut x = *first;
        let mut throughput = Vec3::ONE;
        let mut radiance = Vec3::ZERO;
        per_bounce.fill(Vec3::ZERO);
        for b in 0..bounces as usize {
            let mark = radiance;
            let goes_on = 'bounce: {
                // 1. The emitters' light reflected at x, by light sampling.
                if light_sampling {
                    radiance += throughput * self.emitter_light(&x, rng);
                }
                // 2. The continuation.
                let Some((wi, weight, pdf)) = sample_bounce(&x, rng) else {
                    break 'bounce false;
                };
                throughput *= weight;
                if throughput == Vec3::ZERO {
                    break 'bounce false;
                }
                // A direction the shading normal allows but the surface hides carries no light.
                if x.ng.dot(wi) <= 0.0 {
                    break 'bounce false;
                }
                let origin = x.p + x.ng * self.eps;
                let Some((t, triangle)) = self.bvh.closest_hit(origin, wi, 0.0, f32::INFINITY)
                else {
                    break 'bounce false;
                };
                let y = origin + wi * t;
                // 3. The emitters' light reflected at x, by BSDF sampling: the emitter met.
                if bsdf_sampling {
                    radiance += throughput * self.emitter_hit(&x, wi, pdf, triangle, y);
                }
                // 4. The spot lights' light reflected at the new vertex.
                x = self.vertex(triangle, y, -wi, -wi);
                radiance += throughput * self.direct(&x);
                true
            };
            if let Some(slot) = per_bounce.get_mut(b) {
                *slot = radiance - mark;
            }
            if !goes_on {
                break;
            }
        }
        radiance
    }
}
