//! Tests of the path tracer: the direct light against `direct::cpu`, closed forms for a
//! sphere lit by a point light at its centre, convergence, determinism, the components'
//! additivity, the error's decrease with more paths and the bounce weights against their
//! density; `emitters.rs` holds the closed forms with emissive surfaces.

mod emitters;

use std::{
    collections::HashMap,
    path::Path,
    sync::{
        OnceLock,
        atomic::{AtomicU64, Ordering},
    },
};

use cssm_formats::{
    Scene,
    scene::{Camera, Material, SpotLight},
};
use cssm_raycast::{SceneBvh, SplitMix64};
use glam::Vec3;

use super::{
    Component, EmitterSampling, ReferenceOptions, render_reference, render_reference_converging,
    sampling::sample_bounce, tracer::Vertex,
};
use crate::{
    common::{camera::View, converge::Convergence},
    direct::cpu::{brdf, render_screen},
    gpu_types::GpuMaterial,
    load::{AlbedoTexture, cpu_materials},
};

/// A scene with what `render_reference` needs beside it.
struct Setup {
    scene: Scene,
    materials: Vec<GpuMaterial>,
    textures: Vec<AlbedoTexture>,
    bvh: SceneBvh,
}

impl Setup {
    fn new(scene: Scene) -> Self {
        let (materials, textures) = cpu_materials(&scene).expect("textures");
        let bvh = SceneBvh::new(&scene);
        Self {
            scene,
            materials,
            textures,
            bvh,
        }
    }

    fn render(&self, w: u32, h: u32, options: &ReferenceOptions) -> Vec<Vec3> {
        self.render_converging(w, h, options).0
    }

    fn render_converging(
        &self,
        w: u32,
        h: u32,
        options: &ReferenceOptions,
    ) -> (Vec<Vec3>, Option<Convergence>) {
        let view = View::of_scene(&self.scene, w, h);
        render_reference_converging(
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
        converge: 0.0,
        component,
        seed,
        clamp: None,
        emitters: EmitterSampling::Mis,
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

/// In the same sphere bounce `k` adds `rho^k` of the light `1 + rho + ... + rho^k`: 5.7% at
/// 5 bounces, 3.8% at 6 for rho 0.7, so a run converging at 5% keeps 6 bounces, the same
/// image as 6 bounces asked for, and one at 1% runs out of its 8 first.
#[test]
fn a_converging_image_keeps_the_bounces_its_light_needs() {
    let (rho, intensity) = (0.7f32, 3.0f32);
    let s = Setup::new(lit_sphere(4, rho, intensity));
    let at = |fraction| ReferenceOptions {
        converge: fraction,
        ..options(4, 8, Component::Full, 3)
    };
    let (image, convergence) = s.render_converging(16, 12, &at(0.05));
    let convergence = convergence.expect("a converging run says where it ended");
    assert_eq!(
        (convergence.bounces, convergence.converged),
        (6, true),
        "{convergence}"
    );
    assert!((convergence.added - 0.038).abs() < 0.002, "{convergence}");
    // The same paths' first six bounces, but a path of 8 draws more numbers than one of 6,
    // so the later paths differ: by the tessellation's 0.5% at most, where a bounce more
    // or fewer is 3-6%.
    let six = s.render(16, 12, &options(4, 6, Component::Full, 3));
    for (a, b) in image.iter().zip(&six) {
        assert!(
            (*a - *b).abs().max_element() <= 5e-3 * b.max_element(),
            "{a} {b}"
        );
    }
    let (_, longer) = s.render_converging(16, 12, &at(0.01));
    let longer = longer.unwrap();
    assert_eq!((longer.bounces, longer.converged), (8, false), "{longer}");
    // Exactly: no layers, no convergence.
    assert_eq!(
        s.render_converging(8, 6, &options(2, 3, Component::Full, 3))
            .1,
        None
    );
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
            ..Default::default()
        };
        let v = Vec3::new(view_angle.sin(), 0.0, view_angle.cos());
        let x = Vertex {
            p: Vec3::ZERO,
            n,
            ng: n,
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
            if let Some((wi, weight, _)) = sample_bounce(&x, &mut rng) {
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
