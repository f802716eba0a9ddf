//! The CPU path tracer: ground truth for the global-illumination methods.
//!
//! [`render_reference`] renders the scene's light transport by Monte Carlo path tracing on the
//! CPU, with exact ray casts (`cssm_raycast::SceneBvh`) for every visibility, so the
//! images of the GPU methods (direct light, and the CSSM-based indirect bounces of the paper,
//! Ritschel et al. 2008, §4) can be compared with it pixel by pixel.
//!
//! # What it simulates
//!
//! The scene model of the direct light (`direct/light.wgsl`, [`crate::direct::cpu`]), extended
//! to interreflections:
//!
//! - **Lights**: the scene's spot lights, points of constant radiant intensity inside their cone
//!   and none outside, falling off with `1 / d^2`. Nothing else emits, and no path can hit a
//!   point light, so all light reaches a path by next-event estimation (NEE): at every vertex,
//!   one exact shadow ray per light, from the point lifted by `1e-4` of the scene diameter along
//!   its normal, as in `direct::cpu`.
//! - **Surfaces**: two-sided, with the geometric (flat) normal flipped towards the incoming ray;
//!   BRDF `albedo / pi + Ks (Ns + 2) / (2 pi) max(0, reflect(-l, n) . v)^Ns` (Lambert plus
//!   normalised Phong) at *every* vertex, `albedo` being Kd times the material's albedo texture
//!   sampled as the G-buffer pass does.
//! - **Camera**: one primary ray per pixel through the pixel centre, as the rasteriser samples
//!   (no anti-aliasing: the comparison is pixel by pixel), traced once per pixel; the direct
//!   light at the first vertex is therefore exact (no noise) and equals
//!   [`crate::direct::cpu::render_screen`].
//! - **Paths**: from the first vertex, [`ReferenceOptions::samples_per_pixel`] paths of at most
//!   [`ReferenceOptions::bounces`] indirect bounces each. A bounce picks the diffuse lobe or the
//!   glossy lobe with probabilities proportional to the mean albedo and the mean Ks, samples a
//!   cosine-weighted direction (diffuse) or a direction of the Phong lobe `cos^Ns` around the
//!   mirror direction (glossy), and weights the path by `BRDF cos / pdf` with the pdf of the
//!   mixture of both lobes; a direction below the surface or a ray that leaves the scene ends
//!   the path. There is no Russian roulette: the estimate of the light transport truncated after
//!   `bounces` bounces (the Neumann series up to that term) is unbiased, unless
//!   [`ReferenceOptions::clamp`] is set.
//!
//! Not simulated: area lights, emissive materials, transmission, participating media, normal
//! maps, depth of field and motion.
//!
//! # Determinism and cost
//!
//! Pixel `i` draws its random numbers from its own SplitMix64 stream, started from `seed` and
//! `i`, so an image depends on the options only, never on the number of rayon threads. Rows are
//! rendered in parallel into one preallocated image; a path allocates nothing. A pixel costs one
//! primary ray and one shadow ray per light, plus, per path and bounce, one continuation ray and
//! one shadow ray per light.

use std::sync::atomic::{AtomicU64, Ordering};

use cssm_formats::Scene;
use cssm_raycast::{SceneBvh, SplitMix64};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::{
    RuntimeError,
    common::camera::View,
    direct::cpu::{albedo_at, brdf, direct_radiance, facing_normal, ray_epsilon},
    gpu_types::GpuMaterial,
    load::AlbedoTexture,
    method::{self, Backend, Checks, Energy, CpuSetup, MethodEntry, OptionKind, OptionSpec},
};

/// `--method reference`: this path tracer, on the CPU, the ground truth of every other method.
pub const METHOD: MethodEntry = MethodEntry {
    name: "reference",
    summary: "CPU path tracer with exact ray casts (obvhs, rayon): ground truth",
    needs_cssm: false,
    options: &[
        method::BOUNCES,
        OptionSpec {
            name: "samples",
            help: "paths per pixel",
            kind: OptionKind::Count {
                default: 256,
                min: 1,
                max: 1 << 20,
            },
        },
    ],
    passes: &[],
    backend: Backend::Cpu(render_method),
    checks: Checks {
        energy: Energy::Within(0.02),
        golden_flip: 0.005,
    },
};

/// [`METHOD`]'s entry point: the scene's materials and textures as the GPU sees them, a BVH,
/// then [`render_reference`].
fn render_method(setup: &CpuSetup) -> Result<Vec<[f32; 4]>, RuntimeError> {
    crate::frame::check_size(setup.view.width, setup.view.height)?;
    let (materials, textures) = crate::load::cpu_materials(setup.scene)?;
    let bvh = SceneBvh::new(setup.scene);
    let options = ReferenceOptions {
        samples_per_pixel: setup.options.count("samples"),
        bounces: setup.options.count("bounces"),
        component: setup.component,
        ..Default::default()
    };
    let image = render_reference(
        setup.scene,
        setup.view,
        &materials,
        &textures,
        &bvh,
        &options,
        setup.progress,
    );
    Ok(image.iter().map(|c| [c.x, c.y, c.z, 1.0]).collect())
}

pub use crate::common::compose::Component;

/// Options of [`render_reference`].
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceOptions {
    /// Paths per pixel (0 counts as 1). The noise of the indirect light falls as one over its
    /// square root; the direct light at the first vertex is exact whatever the count.
    pub samples_per_pixel: u32,
    /// Indirect bounces of a path at most: 0 = direct light only, 1 = one bounce of indirect
    /// light, and so on.
    pub bounces: u32,
    /// Which light paths the image holds.
    pub component: Component,
    /// Seed of the random numbers; the same options give the same image.
    pub seed: u64,
    /// `Some(c)` (with `c > 0`): each path's indirect radiance is scaled down so that its
    /// largest channel is at most `c`, which removes fireflies at the price of a bias (darker).
    /// `None` (the default): unbiased.
    pub clamp: Option<f32>,
}

impl Default for ReferenceOptions {
    /// 256 paths per pixel, 3 bounces, the full light, seed 0, no clamping.
    fn default() -> Self {
        Self {
            samples_per_pixel: 256,
            bounces: 3,
            component: Component::Full,
            seed: 0,
            clamp: None,
        }
    }
}

/// Linear radiance per pixel of `view` (row-major, row 0 at the top, the pixel centres and
/// conventions of [`crate::direct::cpu::render_screen`]; background black), by path tracing
/// (see the module docs). `materials` and `textures` are the scene's as the GPU sees them
/// ([`crate::load::SceneGpu::cpu_materials`] and `cpu_textures`, or built from
/// [`crate::load::load_albedo_textures`]); `bvh` is `SceneBvh::new(scene)`.
///
/// `progress(done, total)` is called from the worker threads after each row with the number of
/// pixels finished so far and the number in all.
pub fn render_reference(
    scene: &Scene,
    view: &View,
    materials: &[GpuMaterial],
    textures: &[AlbedoTexture],
    bvh: &SceneBvh,
    options: &ReferenceOptions,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Vec<Vec3> {
    let (w, h) = (view.width as usize, view.height as usize);
    let total = (w * h) as u64;
    let mut image = vec![Vec3::ZERO; w * h];
    if image.is_empty() {
        return image;
    }
    let tracer = Tracer {
        scene,
        materials,
        textures,
        bvh,
        eps: ray_epsilon(scene),
    };
    let done = AtomicU64::new(0);
    image.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            *out = tracer.pixel(view, x as u32, y as u32, options);
        }
        let finished = done.fetch_add(w as u64, Ordering::Relaxed) + w as u64;
        progress(finished, total);
    });
    image
}

/// A surface point of a path.
#[derive(Clone, Copy)]
struct Vertex<'a> {
    /// Position.
    p: Vec3,
    /// Unit normal on the side the path arrives from.
    n: Vec3,
    /// Unit direction back along the path (towards the eye or the previous vertex).
    v: Vec3,
    /// Kd times the albedo texture at `p`.
    albedo: Vec3,
    material: &'a GpuMaterial,
}

/// The scene as the paths see it.
struct Tracer<'a> {
    scene: &'a Scene,
    materials: &'a [GpuMaterial],
    textures: &'a [AlbedoTexture],
    bvh: &'a SceneBvh,
    /// Offset of ray origins off the surface.
    eps: f32,
}

impl<'a> Tracer<'a> {
    /// The vertex at `p` on `triangle`, reached along a ray whose origin lies towards `towards`
    /// (decides the side of the normal), seen from the unit direction `v`.
    fn vertex(&self, triangle: u32, p: Vec3, towards: Vec3, v: Vec3) -> Vertex<'a> {
        let material = &self.materials[self.scene.triangle_materials[triangle as usize] as usize];
        Vertex {
            p,
            n: facing_normal(self.scene, triangle, towards),
            v,
            albedo: albedo_at(self.scene, material, self.textures, triangle, p),
            material,
        }
    }

    /// Radiance leaving `x` towards `x.v` straight from the lights (next-event estimation).
    fn direct(&self, x: &Vertex) -> Vec3 {
        direct_radiance(
            self.scene, self.bvh, self.eps, x.p, x.n, x.v, x.albedo, x.material,
        )
        .0
    }

    /// Radiance of pixel (`x`, `y`).
    fn pixel(&self, view: &View, x: u32, y: u32, options: &ReferenceOptions) -> Vec3 {
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
        }
        if options.component.has_indirect() && options.bounces > 0 {
            let pixel = y as u64 * view.width as u64 + x as u64;
            let mut rng = pixel_rng(options.seed, pixel);
            let samples = options.samples_per_pixel.max(1);
            let mut sum = DVec3::ZERO;
            for _ in 0..samples {
                let mut l = self.indirect(&first, options.bounces, &mut rng);
                if let Some(c) = options.clamp {
                    let largest = l.max_element();
                    if largest > c {
                        l *= c / largest;
                    }
                }
                sum += l.as_dvec3();
            }
            radiance += (sum / samples as f64).as_vec3();
        }
        radiance
    }

    /// One path from `first` of at most `bounces` bounces: the radiance it brings back to
    /// `first` along `first.v` from the lights, not counting their direct light at `first`.
    fn indirect(&self, first: &Vertex<'a>, bounces: u32, rng: &mut SplitMix64) -> Vec3 {
        let mut x = *first;
        let mut throughput = Vec3::ONE;
        let mut radiance = Vec3::ZERO;
        for _ in 0..bounces {
            let Some((wi, weight)) = sample_bounce(&x, rng) else {
                break;
            };
            throughput *= weight;
            if throughput == Vec3::ZERO {
                break;
            }
            let origin = x.p + x.n * self.eps;
            let Some((t, triangle)) = self.bvh.closest_hit(origin, wi, 0.0, f32::INFINITY) else {
                break;
            };
            x = self.vertex(triangle, origin + wi * t, -wi, -wi);
            radiance += throughput * self.direct(&x);
        }
        radiance
    }
}

/// The random stream of pixel `pixel`: SplitMix64 started at `mix(seed) ^ mix(pixel)`, `mix`
/// being SplitMix64's output function (so neighbouring pixels' streams are unrelated, not
/// shifted copies of each other).
fn pixel_rng(seed: u64, pixel: u64) -> SplitMix64 {
    let mix = |v: u64| SplitMix64(v).next_u64();
    SplitMix64(mix(seed) ^ mix(pixel ^ 0x5851_F42D_4C95_7F2D))
}

/// Uniform in `[0, 1)` with 24 random bits (every value exact in `f32`, never 1).
fn uniform(rng: &mut SplitMix64) -> f32 {
    (rng.next_u64() >> 40) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Mean of the three channels.
fn mean(c: Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

/// Unit vector at polar angle `acos(cos_theta)` and azimuth `2 pi u` around the unit `axis`.
fn around(axis: Vec3, cos_theta: f32, u: f32) -> Vec3 {
    let (t, b) = axis.any_orthonormal_pair();
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (s, c) = (std::f32::consts::TAU * u).sin_cos();
    (t * (c * sin_theta) + b * (s * sin_theta) + axis * cos_theta).normalize()
}

/// Draws the direction `wi` a path continues in from `x` (towards the next vertex) from the
/// mixture of a cosine-weighted hemisphere (diffuse lobe) and the normalised Phong lobe around
/// the mirror direction of `x.v` (glossy lobe), chosen in proportion to the mean albedo and the
/// mean Ks; returns `wi` and `BRDF(wi, x.v) cos / pdf(wi)`, pdf being the mixture's. `None`
/// ends the path: a black material, or a direction below the surface (the glossy lobe reaches
/// below the horizon at grazing angles; those samples carry no light).
fn sample_bounce(x: &Vertex, rng: &mut SplitMix64) -> Option<(Vec3, Vec3)> {
    use std::f32::consts::PI;
    let ns = x.material.ns;
    let diffuse_weight = mean(x.albedo).max(0.0);
    let glossy_weight = mean(Vec3::from(x.material.ks)).max(0.0);
    if diffuse_weight + glossy_weight <= 0.0 {
        return None;
    }
    let p_diffuse = diffuse_weight / (diffuse_weight + glossy_weight);
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
    let mut pdf = p_diffuse * cos_i / PI;
    if p_diffuse < 1.0 {
        pdf += (1.0 - p_diffuse) * ((ns + 1.0) / (2.0 * PI) * wi.dot(mirror).max(0.0).powf(ns));
    }
    if pdf.is_nan() || pdf <= 0.0 {
        return None;
    }
    let f = brdf(x.albedo, x.material, wi, x.n, x.v);
    Some((wi, f * (cos_i / pdf)))
}

#[cfg(test)]
mod tests {
    use std::{collections::HashMap, path::Path, sync::OnceLock};

    use cssm_formats::scene::{Camera, Material, SpotLight};

    use super::*;
    use crate::{direct::cpu::render_screen, load::load_albedo_textures};

    /// A scene with what `render_reference` needs beside it.
    struct Setup {
        scene: Scene,
        materials: Vec<GpuMaterial>,
        textures: Vec<AlbedoTexture>,
        bvh: SceneBvh,
    }

    impl Setup {
        fn new(scene: Scene) -> Self {
            let (textures, index) = load_albedo_textures(&scene).expect("textures");
            let materials = scene
                .materials
                .iter()
                .zip(index)
                .map(|(m, texture)| GpuMaterial {
                    kd: m.kd,
                    ns: m.ns,
                    ks: m.ks,
                    texture,
                })
                .collect();
            let bvh = SceneBvh::new(&scene);
            Self {
                scene,
                materials,
                textures,
                bvh,
            }
        }

        fn render(&self, w: u32, h: u32, options: &ReferenceOptions) -> Vec<Vec3> {
            let view = View::of_scene(&self.scene, w, h);
            render_reference(
                &self.scene,
                &view,
                &self.materials,
                &self.textures,
                &self.bvh,
                options,
                &|_, _| {},
            )
        }
    }

    fn built_in(name: &str) -> Setup {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../scenes")
            .join(name);
        Setup::new(Scene::load(&dir).expect("built-in scene loads"))
    }

    fn cornell() -> &'static Setup {
        static S: OnceLock<Setup> = OnceLock::new();
        S.get_or_init(|| built_in("cornell-box"))
    }

    fn cornell_glossy() -> &'static Setup {
        static S: OnceLock<Setup> = OnceLock::new();
        S.get_or_init(|| built_in("cornell-glossy"))
    }

    fn options(spp: u32, bounces: u32, component: Component, seed: u64) -> ReferenceOptions {
        ReferenceOptions {
            samples_per_pixel: spp,
            bounces,
            component,
            seed,
            clamp: None,
        }
    }

    /// Root mean square of the channel differences.
    fn rms_difference(a: &[Vec3], b: &[Vec3]) -> f64 {
        let sum: f64 = a
            .iter()
            .zip(b)
            .map(|(x, y)| (*x - *y).length_squared() as f64)
            .sum();
        (sum / (3 * a.len()) as f64).sqrt()
    }

    #[test]
    fn component_names_round_trip() {
        for c in Component::ALL {
            assert_eq!(c.name().parse::<Component>(), Ok(c));
            assert_eq!(c.to_string(), c.name());
        }
        assert_eq!(Component::default(), Component::Full);
        assert!(
            "everything"
                .parse::<Component>()
                .unwrap_err()
                .contains("direct")
        );
    }

    #[test]
    fn direct_component_is_the_direct_light_reference() {
        let s = cornell();
        let (w, h) = (40, 30);
        let view = View::of_scene(&s.scene, w, h);
        let expected = render_screen(&s.scene, &view, &s.materials, &s.textures, &s.bvh);
        let calls = AtomicU64::new(0);
        let last = AtomicU64::new(0);
        let image = render_reference(
            &s.scene,
            &view,
            &s.materials,
            &s.textures,
            &s.bvh,
            &options(1, 0, Component::Direct, 1),
            &|done, total| {
                assert_eq!(total, (w * h) as u64);
                calls.fetch_add(1, Ordering::Relaxed);
                last.fetch_max(done, Ordering::Relaxed);
            },
        );
        assert_eq!(calls.into_inner(), h as u64, "one progress call per row");
        assert_eq!(last.into_inner(), (w * h) as u64);
        assert_eq!(image.len(), expected.len());
        let lit = expected.iter().filter(|p| p.lit != 0).count();
        assert!(lit > (w * h / 4) as usize, "only {lit} lit pixels");
        for (i, (got, want)) in image.iter().zip(&expected).enumerate() {
            let tolerance = 1e-6 * want.radiance.max_element().max(1e-30);
            assert!(
                (*got - want.radiance).abs().max_element() <= tolerance,
                "pixel {i}: {got} against {}",
                want.radiance
            );
        }
        // The direct light is exact, so more paths or bounces do not change it.
        let more = s.render(w, h, &options(4, 3, Component::Direct, 9));
        assert_eq!(more, image);
    }

    /// A sphere of radius 1 around the origin, an icosahedron subdivided `levels` times with its
    /// vertices pushed onto the sphere, of uniform Lambertian albedo `rho`, with an isotropic
    /// point light of intensity `intensity` at the centre: two spot lights of cutoff 90 degrees
    /// back to back (the scene model allows cutoffs in (0, 180) only). The camera sits at the
    /// centre too.
    fn lit_sphere(levels: u32, rho: f32, intensity: f32) -> Scene {
        let t = (1.0 + 5f32.sqrt()) / 2.0;
        let mut positions: Vec<Vec3> = [
            [-1.0, t, 0.0],
            [1.0, t, 0.0],
            [-1.0, -t, 0.0],
            [1.0, -t, 0.0],
            [0.0, -1.0, t],
            [0.0, 1.0, t],
            [0.0, -1.0, -t],
            [0.0, 1.0, -t],
            [t, 0.0, -1.0],
            [t, 0.0, 1.0],
            [-t, 0.0, -1.0],
            [-t, 0.0, 1.0],
        ]
        .iter()
        .map(|&p| Vec3::from(p).normalize())
        .collect();
        let mut triangles: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut midpoints = HashMap::new();
            let mut midpoint = |a: u32, b: u32| {
                *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let m = (positions[a as usize] + positions[b as usize]).normalize();
                    positions.push(m);
                    positions.len() as u32 - 1
                })
            };
            triangles = triangles
                .iter()
                .flat_map(|&[a, b, c]| {
                    let (ab, bc, ca) = (midpoint(a, b), midpoint(b, c), midpoint(c, a));
                    [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
                })
                .collect();
        }
        let spot = |direction: Vec3| SpotLight {
            position: Vec3::ZERO,
            direction,
            cutoff_deg: 90.0,
            intensity: [intensity; 3],
        };
        Scene {
            name: "lit-sphere".into(),
            path: std::path::PathBuf::from("/nonexistent"),
            triangle_materials: vec![0; triangles.len()],
            objects: vec![cssm_formats::SceneObject::whole_static(triangles.len())],
            positions,
            texcoords: Vec::new(),
            triangles,
            materials: vec![Material {
                kd: [rho; 3],
                ..Material::grey("grey")
            }],
            camera: Camera {
                position: Vec3::ZERO,
                target: Vec3::new(0.3, 0.2, 1.0),
                up: Vec3::Y,
                fov_y_deg: 70.0,
                resolution: [16, 12],
            },
            lights: vec![spot(Vec3::Y), spot(-Vec3::Y)],
            content_hash: [0; 32],
            files: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// The closed form. In a sphere of radius `R` with an isotropic point light of intensity
    /// `I` at its centre, the direct irradiance is `I / R^2` everywhere, and an enclosure of
    /// uniform radiance `L` gives the irradiance `pi L` at every point of it, so with albedo
    /// `rho` every bounce is uniform too and the radiance after `B` bounces is
    /// `rho / pi * I / R^2 * (1 + rho + ... + rho^B)`.
    ///
    /// The test sphere is a polyhedron: a point of a face whose plane lies at `r_f <= R` from the
    /// centre, at `d` in `[r_f, R]` from it, receives `I r_f / d^3`, between `I r_min / R^3` and
    /// `I / r_min^2` (`r_min` the smallest `r_f`). The uniform-radiance argument holds for any
    /// closed enclosure and the diffuse bounce weight is exactly `rho`, so every path, not just
    /// the mean, lies between those bounds times `(1 + rho + ... + rho^B)`: checked pixel by
    /// pixel, with bounds tight enough (0.5%) that a missing or extra bounce fails.
    #[test]
    fn sphere_with_a_central_point_light_matches_the_closed_form() {
        let (rho, intensity) = (0.7f32, 3.0f32);
        let s = Setup::new(lit_sphere(4, rho, intensity));
        let r_min = (0..s.scene.triangles.len())
            .map(|t| {
                let [a, b, c] = s.scene.triangle(t);
                (b - a).cross(c - a).normalize().dot(a).abs()
            })
            .fold(f32::INFINITY, f32::min);
        let r_max = s
            .scene
            .positions
            .iter()
            .map(|p| p.length())
            .fold(0.0f32, f32::max);
        let l_min = rho / std::f32::consts::PI * intensity * r_min / r_max.powi(3);
        let l_max = rho / std::f32::consts::PI * intensity / (r_min * r_min);
        assert!(l_max / l_min < 1.005, "tessellation too coarse: {r_min}");
        for bounces in [0, 1, 4] {
            let sum: f32 = (0..=bounces).map(|k| rho.powi(k as i32)).sum();
            for component in Component::ALL {
                let factor = match component {
                    Component::Direct => 1.0,
                    Component::Indirect => sum - 1.0,
                    Component::Full => sum,
                };
                let image = s.render(16, 12, &options(8, bounces, component, 3));
                let (lo, hi) = (factor * l_min * 0.9999, factor * l_max * 1.0001);
                for (i, p) in image.iter().enumerate() {
                    for c in p.to_array() {
                        assert!(
                            c >= lo && c <= hi,
                            "{component}, {bounces} bounces, pixel {i}: {c} outside [{lo}, {hi}]"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn same_options_same_image_whatever_the_threads() {
        let s = cornell_glossy();
        let o = options(4, 3, Component::Full, 5);
        let a = s.render(24, 18, &o);
        let b = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("thread pool")
            .install(|| s.render(24, 18, &o));
        assert!(a == b, "one thread and many differ");
        assert!(a.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
        let c = s.render(24, 18, &ReferenceOptions { seed: 6, ..o });
        let differ = a.iter().zip(&c).filter(|(x, y)| x != y).count();
        assert!(
            differ > a.len() / 2,
            "another seed changed only {differ} pixels"
        );
    }

    #[test]
    fn full_is_direct_plus_indirect() {
        let s = cornell_glossy();
        let (w, h) = (24, 18);
        let black = s.render(w, h, &options(4, 0, Component::Indirect, 2));
        assert!(black.iter().all(|&p| p == Vec3::ZERO));
        let direct = s.render(w, h, &options(4, 2, Component::Direct, 2));
        assert_eq!(s.render(w, h, &options(4, 0, Component::Full, 2)), direct);
        let indirect = s.render(w, h, &options(4, 2, Component::Indirect, 2));
        let full = s.render(w, h, &options(4, 2, Component::Full, 2));
        assert!(indirect.iter().filter(|p| p.max_element() > 0.0).count() > (w * h / 2) as usize);
        for ((f, d), i) in full.iter().zip(&direct).zip(&indirect) {
            assert!((*f - (*d + *i)).abs().max_element() <= 1e-6 * f.max_element());
        }
        // Clamping only ever darkens.
        let clamped = s.render(
            w,
            h,
            &ReferenceOptions {
                clamp: Some(0.05),
                ..options(4, 2, Component::Indirect, 2)
            },
        );
        assert!(
            clamped
                .iter()
                .zip(&indirect)
                .all(|(c, i)| c.cmple(*i + 1e-6).all())
        );
        assert!(clamped != indirect);
    }

    /// The error against a 512-path image shrinks like one over the square root of the path
    /// count (an independent seed for the reference): the estimator is consistent. On the
    /// glossy Cornell box, so both lobes are sampled.
    #[test]
    fn error_shrinks_with_more_paths() {
        let s = cornell_glossy();
        let (w, h) = (16, 12);
        let reference = s.render(w, h, &options(512, 2, Component::Indirect, 100));
        let error = |spp| {
            rms_difference(
                &s.render(w, h, &options(spp, 2, Component::Indirect, 7)),
                &reference,
            )
        };
        let (e4, e64) = (error(4), error(64));
        eprintln!("RMS error against 512 paths: {e4:.4} with 4, {e64:.4} with 64");
        // Expected ratio sqrt((1/64 + 1/512) / (1/4 + 1/512)) = 0.26.
        assert!(e64 < 0.45 * e4, "4 paths: {e4}, 64 paths: {e64}");
    }

    /// The mean of `BRDF cos / pdf` over drawn directions is the directional albedo
    /// `integral of BRDF cos` over the hemisphere, here by a midpoint rule in (theta, phi): the
    /// sampling weights match the sampling density, for both lobes and their mixture.
    #[test]
    fn bounce_weights_match_the_sampling_density() {
        let n = Vec3::Z;
        for (kd, ks, ns, view_angle) in [
            (0.5f32, 0.0f32, 1.0f32, 0.3f32),
            (0.0, 0.6, 20.0, 0.4),
            (0.3, 0.5, 50.0, 1.2),
            (0.2, 0.7, 5.0, 1.45),
        ] {
            let material = GpuMaterial {
                kd: [kd; 3],
                ns,
                ks: [ks; 3],
                texture: -1,
            };
            let v = Vec3::new(view_angle.sin(), 0.0, view_angle.cos());
            let x = Vertex {
                p: Vec3::ZERO,
                n,
                v,
                albedo: Vec3::splat(kd),
                material: &material,
            };
            let (steps_t, steps_p) = (2000, 2000);
            let (dt, dp) = (
                std::f64::consts::FRAC_PI_2 / steps_t as f64,
                std::f64::consts::TAU / steps_p as f64,
            );
            let mut exact = 0.0f64;
            for i in 0..steps_t {
                let theta = (i as f64 + 0.5) * dt;
                for j in 0..steps_p {
                    let phi = (j as f64 + 0.5) * dp;
                    let l = Vec3::new(
                        (theta.sin() * phi.cos()) as f32,
                        (theta.sin() * phi.sin()) as f32,
                        theta.cos() as f32,
                    );
                    let f = brdf(x.albedo, &material, l, n, v).x as f64;
                    exact += f * theta.cos() * theta.sin() * dt * dp;
                }
            }
            let mut rng = SplitMix64(42);
            let count = 400_000;
            let mut sum = 0.0f64;
            for _ in 0..count {
                if let Some((wi, weight)) = sample_bounce(&x, &mut rng) {
                    assert!((wi.length() - 1.0).abs() < 1e-5 && wi.dot(n) > 0.0);
                    sum += weight.x as f64;
                }
            }
            let estimate = sum / count as f64;
            eprintln!("kd {kd} ks {ks} ns {ns}: {estimate:.5} sampled, {exact:.5} integrated");
            assert!(
                (estimate - exact).abs() < 0.005 * exact,
                "kd {kd} ks {ks} ns {ns}: {estimate} sampled, {exact} integrated"
            );
        }
    }
}
