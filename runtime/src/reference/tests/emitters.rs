//! Tests of the emitters (area lights): an emissive sphere and a square lamp over a floor
//! against their closed forms, under light sampling, BSDF sampling and MIS, and determinism
//! and additivity with emitters in the scene.

use cssm_formats::{
    Scene,
    scene::{Camera, Material},
};
use glam::Vec3;

use super::{Setup, lit_sphere, options};
use crate::common::camera::View;
use crate::reference::{Component, EmitterSampling, ReferenceOptions, sampling::mean};

/// [`lit_sphere`]'s polyhedron lit by its own emission instead: no lights, every triangle
/// of albedo `rho` emitting `le` from the side its winding faces, inwards when `inwards`.
fn emissive_sphere(levels: u32, rho: f32, le: f32, inwards: bool) -> Scene {
    let mut scene = lit_sphere(levels, rho, 0.0);
    scene.lights.clear();
    scene.materials[0].emission = [le; 3];
    for tri in &mut scene.triangles {
        let [a, b, c] = tri.map(|v| scene.positions[v as usize]);
        let faces_in = (b - a).cross(c - a).dot(a) < 0.0;
        if faces_in != inwards {
            tri.swap(1, 2);
        }
    }
    scene
}

/// Inside a closed enclosure every point of which emits `Le` inwards, the irradiance is
/// `pi Le` everywhere (the uniform-radiance argument of
/// [`sphere_with_a_central_point_light_matches_the_closed_form`] holds for any closed
/// enclosure), so with albedo `rho` the radiance is `Le` seen directly and
/// `Le (rho + ... + rho^B)` after `B` bounces as indirect light. BSDF sampling alone gets it
/// path by path (every continuation meets an emitter, every bounce weighs `rho`); light
/// sampling and MIS get it on average. Wound outwards, nothing emits into the sphere and the
/// image is black.
#[test]
fn emissive_sphere_matches_the_closed_form() {
    let (rho, le) = (0.6f32, 1.5f32);
    let s = Setup::new(emissive_sphere(3, rho, le, true));
    for bounces in [0u32, 1, 3] {
        let expected: f32 = (1..=bounces).map(|k| le * rho.powi(k as i32)).sum();
        for sampling in [
            EmitterSampling::Mis,
            EmitterSampling::Light,
            EmitterSampling::Bsdf,
        ] {
            let with = |component, spp| ReferenceOptions {
                emitters: sampling,
                ..options(spp, bounces, component, 11)
            };
            let direct = s.render(16, 12, &with(Component::Direct, 1));
            for p in &direct {
                assert!((*p - Vec3::splat(le)).abs().max_element() < 1e-6, "{p}");
            }
            let image = s.render(16, 12, &with(Component::Indirect, 64));
            let mean = image.iter().map(|p| mean(*p) as f64).sum::<f64>() / image.len() as f64;
            eprintln!("{sampling:?}, {bounces} bounces: mean {mean:.5}, closed form {expected:.5}");
            if bounces == 0 {
                assert!(image.iter().all(|&p| p == Vec3::ZERO));
                continue;
            }
            assert!(
                (mean / expected as f64 - 1.0).abs() < 0.01,
                "{sampling:?}, {bounces} bounces: mean {mean}, closed form {expected}"
            );
            if sampling == EmitterSampling::Bsdf {
                for (i, p) in image.iter().enumerate() {
                    assert!(
                        (*p - Vec3::splat(expected)).abs().max_element() < 1e-3 * expected,
                        "pixel {i}: {p} against {expected}"
                    );
                }
            }
        }
    }
    let outwards = Setup::new(emissive_sphere(3, rho, le, false));
    for sampling in [EmitterSampling::Mis, EmitterSampling::Bsdf] {
        let o = ReferenceOptions {
            emitters: sampling,
            ..options(16, 3, Component::Full, 4)
        };
        let image = outwards.render(16, 12, &o);
        assert!(image.iter().all(|&p| p == Vec3::ZERO), "{sampling:?}");
    }
}

/// A floor of albedo `rho` (`y = 0`, facing up, 4 x 4) under a black square emitter of side
/// 0.5 at height 0.5 emitting `le` (downwards, or upwards when `facing_up`), no lights, the
/// camera above and to the side.
fn lamp_over_floor(rho: f32, le: [f32; 3], facing_up: bool) -> Scene {
    let (f, r, h) = (2.0f32, 0.25f32, 0.5f32);
    let positions = vec![
        Vec3::new(-f, 0.0, f),
        Vec3::new(f, 0.0, f),
        Vec3::new(f, 0.0, -f),
        Vec3::new(-f, 0.0, -f),
        Vec3::new(-r, h, r),
        Vec3::new(r, h, r),
        Vec3::new(r, h, -r),
        Vec3::new(-r, h, -r),
    ];
    // The floor's winding faces +y; the lamp's faces -y unless `facing_up`.
    let lamp = if facing_up {
        [[4, 5, 6], [4, 6, 7]]
    } else {
        [[4, 6, 5], [4, 7, 6]]
    };
    let triangles = vec![[0, 1, 2], [0, 2, 3], lamp[0], lamp[1]];
    Scene {
        name: "lamp-over-floor".into(),
        path: std::path::PathBuf::from("/nonexistent"),
        triangle_materials: vec![0, 0, 1, 1],
        objects: vec![cssm_formats::SceneObject::whole_static(triangles.len())],
        positions,
        texcoords: Vec::new(),
        triangles,
        materials: vec![
            Material {
                kd: [rho; 3],
                ..Material::grey("floor")
            },
            Material {
                kd: [0.0; 3],
                emission: le,
                ..Material::grey("lamp")
            },
        ],
        camera: Camera {
            position: Vec3::new(0.0, 2.5, 2.5),
            target: Vec3::new(0.0, 0.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 60.0,
            resolution: [32, 24],
        },
        lights: Vec::new(),
        content_hash: [0; 32],
        files: Vec::new(),
        warnings: Vec::new(),
    }
}

/// Irradiance at `p` (unit normal `n`) from a polygon of uniform radiance `le` wholly
/// above `p`'s horizon and unoccluded: Lambert's formula, `E = le / 2 |sum_i theta_i
/// n . (u_i x u_(i+1)) / |u_i x u_(i+1)||` over the edges, `u_i` the unit directions to the
/// corners and `theta_i` the angle between consecutive ones.
fn polygon_irradiance(p: Vec3, n: Vec3, corners: &[Vec3], le: f32) -> f32 {
    let u: Vec<glam::DVec3> = corners
        .iter()
        .map(|c| (*c - p).as_dvec3().normalize())
        .collect();
    let mut sum = 0.0f64;
    for i in 0..u.len() {
        let (a, b) = (u[i], u[(i + 1) % u.len()]);
        let theta = a.dot(b).clamp(-1.0, 1.0).acos();
        sum += theta * n.as_dvec3().dot(a.cross(b).normalize());
    }
    (le as f64 / 2.0 * sum.abs()) as f32
}

/// One bounce of a square emitter's light on a floor is `rho / pi E` with `E` by Lambert's
/// formula, pixel by pixel: the path tracer gets it with light sampling, BSDF sampling and
/// MIS alike (each unbiased: their means agree within the noise), MIS with less noise than
/// BSDF sampling alone. The lamp's back, which the camera sees, is dark; wound the other
/// way the lamp lights nothing below it.
#[test]
fn square_lamp_over_a_floor_matches_lamberts_formula() {
    let (rho, le) = (0.6f32, 3.0f32);
    let s = Setup::new(lamp_over_floor(rho, [le; 3], false));
    let (w, h) = (32, 24);
    let view = View::of_scene(&s.scene, w, h);
    let corners = [0.25f32, -0.25].map(|x| [0.25f32, -0.25].map(|z| Vec3::new(x, 0.5, z)));
    let corners = [corners[0][0], corners[0][1], corners[1][1], corners[1][0]];
    // The exact value at every pixel that sees the floor.
    let exact: Vec<Option<f32>> = (0..w * h)
        .map(|i| {
            let dir = view.primary_ray(i % w, i / w);
            let (t, triangle) = s.bvh.closest_hit(view.eye, dir, 0.0, f32::INFINITY)?;
            (triangle < 2).then(|| {
                let p = view.eye + dir * t;
                rho / std::f32::consts::PI * polygon_irradiance(p, Vec3::Y, &corners, le)
            })
        })
        .collect();
    let floor = exact.iter().filter(|e| e.is_some()).count();
    assert!(floor > (w * h / 2) as usize, "{floor} floor pixels");
    let mut errors = Vec::new();
    for sampling in [
        EmitterSampling::Mis,
        EmitterSampling::Light,
        EmitterSampling::Bsdf,
    ] {
        let o = ReferenceOptions {
            emitters: sampling,
            ..options(128, 1, Component::Indirect, 21)
        };
        let image = s.render(w, h, &o);
        let (mut err, mut norm, mut sum, mut sum_exact) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for (p, e) in image.iter().zip(&exact) {
            match e {
                Some(e) => {
                    let e = *e as f64;
                    err += (mean(*p) as f64 - e).powi(2);
                    norm += e * e;
                    sum += mean(*p) as f64;
                    sum_exact += e;
                }
                None => assert_eq!(*p, Vec3::ZERO, "the lamp reflects nothing"),
            }
        }
        let rmse = (err / norm).sqrt();
        // The pixels' errors are noise, independent from pixel to pixel: the standard
        // error of the sum is the root of their summed squares.
        let (bias, standard_error) = (sum / sum_exact - 1.0, err.sqrt() / sum_exact);
        eprintln!(
            "{sampling:?}: relative RMSE {rmse:.4}, mean off by {bias:+.4} (standard error \
             {standard_error:.4})"
        );
        assert!(
            bias.abs() < 4.0 * standard_error + 1e-3,
            "{sampling:?}: mean off by {bias}, standard error {standard_error}"
        );
        errors.push(rmse);
    }
    assert!(errors[0] < 0.05, "MIS: relative RMSE {}", errors[0]);
    assert!(
        errors[0] < errors[2],
        "MIS {} no better than BSDF sampling {}",
        errors[0],
        errors[2]
    );
    // The camera sees the lamp's back: its direct light is nothing.
    let direct = s.render(w, h, &options(1, 1, Component::Direct, 1));
    assert!(direct.iter().all(|&p| p == Vec3::ZERO));
    // Wound upwards, the lamp lights the floor not at all, and the camera sees its front.
    let up = Setup::new(lamp_over_floor(rho, [le; 3], true));
    let indirect = up.render(w, h, &options(16, 2, Component::Indirect, 3));
    assert!(indirect.iter().all(|&p| p == Vec3::ZERO));
    let direct = up.render(w, h, &options(1, 1, Component::Direct, 1));
    assert!(direct.iter().filter(|&&p| p == Vec3::splat(le)).count() > 4);
}

/// With emitters too, an image depends on the options only (not the thread count) and the
/// full light is the direct plus the indirect.
#[test]
fn emitters_keep_images_deterministic_and_components_additive() {
    let s = Setup::new(lamp_over_floor(0.5, [4.0, 2.0, 1.0], false));
    let o = options(8, 2, Component::Full, 5);
    let a = s.render(24, 18, &o);
    let b = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("thread pool")
        .install(|| s.render(24, 18, &o));
    assert!(a == b, "one thread and many differ");
    assert!(a.iter().any(|p| p.max_element() > 0.0));
    assert!(a.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
    let direct = s.render(24, 18, &options(8, 2, Component::Direct, 5));
    let indirect = s.render(24, 18, &options(8, 2, Component::Indirect, 5));
    for ((f, d), i) in a.iter().zip(&direct).zip(&indirect) {
        assert!((*f - (*d + *i)).abs().max_element() <= 1e-6 * f.max_element().max(1e-6));
    }
}
