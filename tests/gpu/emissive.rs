//! Emissive surfaces as light sources (MTL `Ke`, glTF emissive; §4.7: any direct light may be
//! the radiosity's source). Every GPU piece that emission changed against its CPU twin on a
//! small room lit by a lamp panel, written by the tests into a temporary directory: the
//! G-buffer's emission and the direct light (`direct::cpu::render_screen`), the atlas's source
//! radiance (`direct::cpu::render_atlas`) and the radiosity over it (`radiosity::cpu`), the
//! light SSIL's pixels send (`ssil::cpu::sender_radiance`) and the VPLs of `vf`
//! (`vf::light::vpl_cpu`); then every method of the table on the room lit by its emitters
//! alone, every method's energy in a closed sphere that emits, and `cssm bake` + `cssm render`
//! on the room.
//!
//! The room (2 x 2 x 2, open towards the camera): a lamp under the ceiling facing down, a
//! panel standing in the room that emits towards the back wall (the camera sees its dark
//! back: emission is one-sided), a sign on the back wall whose emission is a texture
//! (`map_Ke`), a block on the floor; with or without a spot light.

use std::{fmt::Write as _, path::Path};

use cssm_bake::BakeOptions;
use cssm_formats::{CssmFile, Scene};
use cssm_runtime::{
    METHODS,
    common::{
        compose::Component,
        readback::{read_texture, render_image},
    },
    method::Energy,
};
use glam::{Vec3, Vec4};

use super::{RenderOptions, gpu, materials, methods, relative_rmse, render, ssil, vf as vf_tests};

/// The lamp's emitted radiance (Kd 0.78, as McGuire's Cornell box's light).
const LAMP: [f32; 3] = [10.0, 8.0, 6.0];
/// The standing panel's, emitted towards the back wall.
const PANEL: [f32; 3] = [2.0, 3.0, 4.0];

/// The corners, in order around it, of the axis-aligned rectangle from `lo` to `hi` (equal in
/// the coordinate across it).
fn rect(lo: [f32; 3], hi: [f32; 3]) -> [Vec3; 4] {
    let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
    let flat = (0..3).find(|&k| lo[k] == hi[k]).expect("a flat rectangle");
    let (u, v) = ((flat + 1) % 3, (flat + 2) % 3);
    let corner = |a: bool, b: bool| {
        let mut c = lo;
        c[u] = if a { hi[u] } else { lo[u] };
        c[v] = if b { hi[v] } else { lo[v] };
        c
    };
    [
        corner(false, false),
        corner(true, false),
        corner(true, true),
        corner(false, true),
    ]
}

/// The OBJ of the room: each rectangle its four corners with texture coordinates, its material,
/// and two triangles wound so that their normal (the front, the side that emits) points along
/// the rectangle's.
fn room_obj() -> String {
    let (x, y, z) = (Vec3::X, Vec3::Y, Vec3::Z);
    // (material, lower corner, upper corner, normal of the front side)
    let mut rects = vec![
        ("white", [-1., 0., -1.], [1., 0., 1.], y),
        ("white", [-1., 2., -1.], [1., 2., 1.], -y),
        ("white", [-1., 0., -1.], [1., 2., -1.], z),
        ("red", [-1., 0., -1.], [-1., 2., 1.], x),
        ("green", [1., 0., -1.], [1., 2., 1.], -x),
        ("lamp", [-0.3, 1.98, -0.3], [0.3, 1.98, 0.3], -y),
        ("panel", [-0.9, 0.2, -0.5], [-0.4, 0.9, -0.5], -z),
        ("sign", [0.2, 0.8, -0.99], [0.8, 1.4, -0.99], z),
    ];
    // A block on the floor: its top and four sides, facing out.
    let ([x0, y0, z0], [x1, y1, z1]) = ([0.1, 0.0, -0.2], [0.6, 0.6, 0.3]);
    rects.extend([
        ("white", [x0, y1, z0], [x1, y1, z1], y),
        ("white", [x0, y0, z1], [x1, y1, z1], z),
        ("white", [x0, y0, z0], [x1, y1, z0], -z),
        ("white", [x0, y0, z0], [x0, y1, z1], -x),
        ("white", [x1, y0, z0], [x1, y1, z1], x),
    ]);
    let mut obj = String::from("mtllib room.mtl\n");
    let uvs = [[0.0f32, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    for (k, (material, lo, hi, normal)) in rects.iter().enumerate() {
        let corners = rect(*lo, *hi);
        for (c, uv) in corners.iter().zip(uvs) {
            writeln!(obj, "v {} {} {}\nvt {} {}", c.x, c.y, c.z, uv[0], uv[1]).unwrap();
        }
        let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
        let order = if n.dot(*normal) > 0.0 {
            [0, 1, 2, 3]
        } else {
            [0, 3, 2, 1]
        };
        let v = order.map(|i| 4 * k + 1 + i);
        writeln!(obj, "usemtl {material}").unwrap();
        writeln!(obj, "f {0}/{0} {1}/{1} {2}/{2}", v[0], v[1], v[2]).unwrap();
        writeln!(obj, "f {0}/{0} {1}/{1} {2}/{2}", v[0], v[2], v[3]).unwrap();
    }
    obj
}

/// Writes the room into `dir`: `room.obj`, `room.mtl`, `sign.png` (the sign's emission, a 4x4
/// checker of white and blue) and `scene.toml` (the camera, and a spot light when `spot`).
pub(super) fn write_room(dir: &Path, spot: bool) {
    std::fs::write(dir.join("room.obj"), room_obj()).unwrap();
    let [l0, l1, l2] = LAMP;
    let [p0, p1, p2] = PANEL;
    std::fs::write(
        dir.join("room.mtl"),
        format!(
            "newmtl white\nKd 0.7 0.7 0.7\nnewmtl red\nKd 0.6 0.06 0.05\n\
             newmtl green\nKd 0.14 0.45 0.09\nnewmtl lamp\nKd 0.78 0.78 0.78\nKe {l0} {l1} {l2}\n\
             newmtl panel\nKd 0.5 0.5 0.5\nKe {p0} {p1} {p2}\n\
             newmtl sign\nKd 0.5 0.5 0.5\nKe 1.5 1.5 1.5\nmap_Ke sign.png\n"
        ),
    )
    .unwrap();
    let checker = image::RgbImage::from_fn(4, 4, |x, y| {
        if (x + y) % 2 == 0 {
            image::Rgb([255, 255, 255])
        } else {
            image::Rgb([40, 90, 255])
        }
    });
    checker.save(dir.join("sign.png")).unwrap();
    let light = if spot {
        "\n[[lights]]\ntype = \"spot\"\nposition = [0.0, 1.9, 0.6]\ndirection = [0.0, -1.0, -0.3]\n\
         cutoff_deg = 60.0\nintensity = [2.0, 2.0, 2.0]\n"
    } else {
        ""
    };
    std::fs::write(
        dir.join("scene.toml"),
        format!(
            "name = \"emissive-room\"\nmesh = \"room.obj\"\n\n[camera]\n\
             position = [0.0, 1.0, 3.4]\ntarget = [0.0, 0.9, 0.0]\nup = [0.0, 1.0, 0.0]\n\
             fov_y_deg = 45.0\nresolution = [64, 48]\n{light}"
        ),
    )
    .unwrap();
}

/// The room (with the spot light when `spot`) and its bake (atlas 64, cube 16), made once.
pub(super) fn room(spot: bool) -> &'static (Scene, CssmFile) {
    use std::sync::OnceLock;
    static ROOMS: [OnceLock<(Scene, CssmFile)>; 2] = [OnceLock::new(), OnceLock::new()];
    ROOMS[usize::from(spot)].get_or_init(|| {
        // A directory that outlives the scene, whose sign texture the renderers read.
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("emissive-room-{spot}"));
        std::fs::create_dir_all(&dir).unwrap();
        write_room(&dir, spot);
        let scene = Scene::load(&dir).expect("the room loads");
        assert_eq!(scene.lights.len(), usize::from(spot));
        let options = BakeOptions {
            atlas_resolution: 64,
            cube_resolution: 16,
            ..Default::default()
        };
        let file = cssm_bake::bake(&scene, &options, &mut |_| {})
            .expect("the room bakes")
            .file;
        (scene, file)
    })
}

/// The index of the material called `name`.
fn material_index(scene: &Scene, name: &str) -> u32 {
    scene
        .materials
        .iter()
        .position(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material {name}")) as u32
}

/// A half float's value.
fn half(bits: u16) -> f32 {
    let sign = if bits >> 15 == 1 { -1.0 } else { 1.0 };
    let exponent = i32::from((bits >> 10) & 0x1f);
    let mantissa = f32::from(bits & 0x3ff);
    sign * match exponent {
        0 => mantissa * 2f32.powi(-24),
        31 => f32::INFINITY,
        e => (1.0 + mantissa / 1024.0) * 2f32.powi(e - 15),
    }
}

/// The G-buffer's emission target of `ctx`, one `Vec4` per pixel.
fn gbuffer_emission(ctx: &cssm_runtime::frame::FrameContext) -> Vec<Vec4> {
    let bytes = read_texture(&ctx.device, &ctx.queue, &ctx.gbuffer.emission, 8).expect("read");
    bytemuck::cast_slice::<u8, u16>(&bytes)
        .chunks(4)
        .map(|c| Vec4::new(half(c[0]), half(c[1]), half(c[2]), half(c[3])))
        .collect()
}

/// Pixels away from silhouettes and creases (every pixel of the 3x3 around sees the same
/// plane) and, with lights, from shadow and cone edges (the 5x5 around agree on the lights
/// that reach them): where shadow maps and rasterisation agree with exact rays.
fn interior_pixels(
    scene: &Scene,
    reference: &[cssm_runtime::direct::cpu::CpuPixel],
    w: u32,
    h: u32,
) -> Vec<bool> {
    let plane = |t: u32| {
        let [a, b, c] = scene.triangle(t as usize);
        let n = (b - a).cross(c - a).normalize_or_zero();
        (n, n.dot(a))
    };
    (0..(w * h) as i64)
        .map(|i| {
            let (x, y) = (i % w as i64, i / w as i64);
            let me = reference[i as usize];
            if me.triangle == u32::MAX {
                return false;
            }
            let (n, d) = plane(me.triangle);
            for dy in -2..=2i64 {
                for dx in -2..=2i64 {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let other = reference[(ny * w as i64 + nx) as usize];
                    if other.lit != me.lit {
                        return false;
                    }
                    if dx.abs() <= 1 && dy.abs() <= 1 {
                        if other.triangle == u32::MAX {
                            return false;
                        }
                        let (m, e) = plane(other.triangle);
                        if m.dot(n) < 0.999 || (e - d).abs() > 1e-4 {
                            return false;
                        }
                    }
                }
            }
            true
        })
        .collect()
}

/// The G-buffer's emission is what the surface seen emits towards the eye (the lamp and the
/// sign from their fronts, nothing from the panel's back), and the direct light adds it to the
/// lights' reflected light: the GPU against `direct::cpu::render_screen`, with and without a
/// spot light, away from edges.
#[test]
fn direct_light_with_emitters_matches_cpu_twin() {
    use cssm_runtime::{common::camera::View, direct::cpu};
    for spot in [false, true] {
        let (scene, _) = room(spot);
        let (w, h) = (64u32, 48u32);
        let mut renderer = ssil::renderer_of("direct", scene, (w, h), Component::Full);
        let frame = render_image(&mut renderer, 1).expect("render");
        let emission = gbuffer_emission(renderer.context());
        let (materials, textures) = cssm_runtime::load::cpu_materials(scene).expect("materials");
        let bvh = cssm_raycast::SceneBvh::new(scene);
        let view = View::of_scene(scene, w, h);
        let reference = cpu::render_screen(scene, &view, &materials, &textures, &bvh);
        let keep = interior_pixels(scene, &reference, w, h);
        let kept = keep.iter().filter(|&&k| k).count();
        let gpu_radiance: Vec<Vec3> = frame
            .radiance
            .iter()
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect();
        let cpu_radiance: Vec<Vec3> = reference.iter().map(|p| p.radiance).collect();
        let rmse = relative_rmse(&gpu_radiance, &cpu_radiance, &keep);
        // What each kind of emitter looks like in the G-buffer, pixel by pixel.
        let (lamp, panel, sign) = (
            material_index(scene, "lamp"),
            material_index(scene, "panel"),
            material_index(scene, "sign"),
        );
        let mut seen = [0usize; 3];
        for (i, (r, e)) in reference.iter().zip(&emission).enumerate() {
            if !keep[i] {
                continue;
            }
            let m = scene.triangle_materials[r.triangle as usize];
            let emitted = e.truncate();
            if m == lamp {
                seen[0] += 1;
                assert!(
                    e.w == 1.0 && (emitted - Vec3::from(LAMP)).abs().max_element() < 1e-2,
                    "pixel {i}: {e}"
                );
            } else if m == panel {
                seen[1] += 1;
                assert!(*e == Vec4::ZERO, "pixel {i} sees the panel's back: {e}");
                if !spot {
                    assert_eq!(
                        cpu_radiance[i],
                        Vec3::ZERO,
                        "pixel {i} sees the panel's back"
                    );
                }
            } else if m == sign {
                seen[2] += 1;
                assert!(e.w == 1.0 && emitted.max_element() > 0.05, "pixel {i}: {e}");
            } else {
                assert!(emitted == Vec3::ZERO, "pixel {i}: {e}");
            }
        }
        eprintln!(
            "direct light with emitters (spot: {spot}), {w}x{h}: relative RMSE {:.4}% over \
             {kept} pixels; lamp, panel, sign pixels {seen:?}",
            100.0 * rmse
        );
        assert!(seen.iter().all(|&n| n >= 4), "{seen:?}");
        assert!(kept as u32 > w * h / 3, "too few pixels compared: {kept}");
        assert!(rmse < 0.02, "relative RMSE {rmse}");
    }
}

/// Every atlas texel sends its emission from its front (the winding's side, the side its cube
/// map looks into) on top of its reflected direct light: the GPU's source radiance against
/// `direct::cpu::render_atlas` (exactly without lights, away from shadow edges with one), and
/// the radiosity iterations over it against their CPU twin.
#[test]
fn atlas_emission_and_radiosity_match_cpu_twins() {
    use cssm_formats::visibility::{QueryOptions, VisibilityQuery};
    use cssm_runtime::radiosity::{RadiosityOptions, cpu as radiosity_cpu, texel_albedo};
    let (scene, file) = room(false);
    let options = RadiosityOptions::default();
    let solved = super::solve_atlas(scene, file, 2, options).expect("radiosity");
    let bvh = cssm_raycast::SceneBvh::new(scene);
    let exact =
        cssm_runtime::direct::cpu::render_atlas(scene, &materials(scene), &file.texels, &bvh);
    let direct = super::vec3s(&solved.direct);
    let mut emitting = [0usize; 3];
    for (i, (g, c)) in direct.iter().zip(&exact).enumerate() {
        assert!(
            (*g - *c).abs().max_element() <= 1e-5 * c.max_element().max(1e-6),
            "texel {i}: GPU {g}, CPU {c}"
        );
        let m = scene.materials[file.texels[i].material as usize]
            .name
            .as_str();
        match m {
            "lamp" => emitting[0] += usize::from(*c == Vec3::from(LAMP)),
            "panel" => emitting[1] += usize::from(*c == Vec3::from(PANEL)),
            // The sign's texels emit its texture's mean.
            "sign" => emitting[2] += usize::from(c.z > c.x && c.x > 0.0),
            _ => assert_eq!(*c, Vec3::ZERO, "texel {i} of {m}"),
        }
    }
    assert!(emitting.iter().all(|&n| n > 0), "{emitting:?}");
    let albedo = super::vec3s(&texel_albedo(&materials(scene), file));
    let query = VisibilityQuery::new(file, QueryOptions::default());
    let traversal = radiosity_cpu::Traversal {
        threshold: options.threshold,
        exposure: options.exposure,
    };
    let twin = radiosity_cpu::radiosity(&query, &direct, &albedo, &traversal, 2);
    let all = vec![true; direct.len()];
    let irradiance = super::vec3s(&solved.irradiance);
    let rmse = relative_rmse(&irradiance, &twin.texel_irradiance, &all);
    let lit = irradiance.iter().filter(|e| e.max_element() > 0.0).count();
    eprintln!(
        "radiosity from emitters, {} texels: GPU vs twin relative RMSE {:.5}%, {lit} lit",
        direct.len(),
        100.0 * rmse
    );
    assert!(rmse < 1e-3, "{rmse}");
    assert!(
        lit * 10 > direct.len() * 9,
        "{lit} of {} texels lit",
        direct.len()
    );

    // With a spot light too: the shadow map against exact rays, away from its edges.
    let (scene, file) = room(true);
    let gpu_texels = cssm_runtime::radiosity::render_atlas_direct(
        &gpu().device,
        &gpu().queue,
        scene,
        file,
        1024,
    )
    .expect("atlas pass");
    let exact = cssm_runtime::direct::cpu::render_atlas(
        scene,
        &materials(scene),
        &file.texels,
        &bvh_of(scene),
    );
    let rmse = relative_rmse(&super::vec3s(&gpu_texels), &exact, &vec![true; exact.len()]);
    eprintln!(
        "atlas source with a spot light: relative RMSE {:.4}%",
        100.0 * rmse
    );
    assert!(rmse < 0.02, "{rmse}");
}

fn bvh_of(scene: &Scene) -> cssm_raycast::SceneBvh {
    cssm_raycast::SceneBvh::new(scene)
}

/// The light SSIL's pixels send is their diffuse direct light plus their emission (none from
/// the panel's back): the GPU against `ssil::cpu::sender_radiance` over the same G-buffer,
/// exactly without lights, with the spot light's shadow map against exact rays with one.
#[test]
fn ssil_sends_emitted_light_as_its_twin() {
    for spot in [false, true] {
        let (scene, _) = room(spot);
        let renderer = ssil::context_renderer(scene, (48, 36));
        let ctx = renderer.context();
        let gi = ssil::run(ctx, scene, &ssil::test_options(), 1);
        let sender = ssil::read4(ctx, gi.sender());
        let [position, normal, albedo] = [
            &ctx.gbuffer.position,
            &ctx.gbuffer.normal,
            &ctx.gbuffer.albedo,
        ]
        .map(|t| ssil::texture4(ctx, t));
        let emission = gbuffer_emission(ctx);
        let bvh = bvh_of(scene);
        let twin: Vec<Vec3> = (0..sender.len())
            .map(|i| {
                cssm_runtime::ssil::cpu::sender_radiance(
                    scene,
                    &bvh,
                    [position[i], normal[i], albedo[i], emission[i]],
                )
            })
            .collect();
        let gpu_sent: Vec<Vec3> = sender.iter().map(|s| s.truncate()).collect();
        let emitting = emission.iter().filter(|e| e.max_element() > 0.0).count();
        assert!(emitting > 20, "{emitting} emitting pixels");
        if spot {
            let rmse = relative_rmse(&gpu_sent, &twin, &vec![true; twin.len()]);
            eprintln!(
                "ssil sender with a spot light: relative RMSE {:.4}%",
                100.0 * rmse
            );
            assert!(rmse < 0.03, "{rmse}");
        } else {
            for (i, (g, c)) in gpu_sent.iter().zip(&twin).enumerate() {
                assert!(
                    (*g - *c).abs().max_element() <= 1e-5 * c.max_element().max(1e-3),
                    "pixel {i}: sent {g}, twin {c}"
                );
            }
        }
    }
}

/// `vf`'s VPLs send an emitter's exitance `pi Le` from its front on top of their reflected
/// light: the GPU against `vf::light::vpl_cpu`, every VPL without lights, all but those on the
/// spot light's shadow edges with one.
#[test]
fn vpls_carry_emission_as_their_twin() {
    use cssm_runtime::vf::light::{Vpl, vpl_cpu};
    for spot in [false, true] {
        let (scene, _) = room(spot);
        let lit = vf_tests::lit_proxies_in(scene, 4096, 6, (16, 12));
        let [p, n, f] = [&lit.light.position, &lit.light.normal, &lit.light.flux]
            .map(vf_tests::read::<[f32; 4]>);
        let gpu_vpls: Vec<Vpl> = (0..p.len())
            .map(|i| Vpl {
                position: p[i].into(),
                normal: n[i].into(),
                flux: f[i].into(),
            })
            .collect();
        let (materials, textures) = cssm_runtime::load::cpu_materials(scene).expect("materials");
        let motion = vec![glam::Mat4::IDENTITY; scene.objects.len()];
        let cpu_vpls = vpl_cpu(
            scene,
            &bvh_of(scene),
            &materials,
            &textures,
            &lit.proxies,
            &motion,
        );
        let emitters: Vec<u32> = ["lamp", "panel", "sign"]
            .map(|m| material_index(scene, m))
            .to_vec();
        let (mut emitting, mut off) = (0, 0);
        for (i, (g, c)) in gpu_vpls.iter().zip(&cpu_vpls).enumerate() {
            let proxy = &lit.proxies[i];
            if emitters.contains(&proxy.material) {
                emitting += 1;
                // An emitter sends from its front.
                assert!(
                    c.normal.truncate().dot(glam::Vec3::from(proxy.normal)) > 0.99,
                    "VPL {i} on an emitter sends from its back"
                );
            }
            let near =
                (g.flux - c.flux).abs().max_element() <= 1e-3 * c.flux.max_element().max(1e-6);
            if !near || g.normal != c.normal {
                off += 1;
                assert!(spot, "VPL {i}: GPU {g:?}, CPU {c:?}");
            }
        }
        eprintln!("VPLs with emitters (spot: {spot}): {emitting} on emitters, {off} differ");
        assert!(emitting > 10, "{emitting} VPLs on emitters");
        assert!(
            off * 10 <= cpu_vpls.len(),
            "{off} of {} VPLs differ",
            cpu_vpls.len()
        );
    }
}

/// The sphere of `methods::every_method_conserves_energy_in_a_closed_sphere`, lit by its own
/// emission instead, and its bake, made once.
fn emissive_sphere() -> &'static (Scene, f32, CssmFile) {
    static SPHERE: std::sync::OnceLock<(Scene, f32, CssmFile)> = std::sync::OnceLock::new();
    SPHERE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let area = methods::write_sphere(dir.path(), Some(SPHERE_LE));
        let scene = Scene::load(dir.path()).expect("sphere loads");
        assert!(scene.lights.is_empty());
        let options = BakeOptions {
            atlas_resolution: 32,
            cube_resolution: 16,
            ..Default::default()
        };
        let file = cssm_bake::bake(&scene, &options, &mut |_| {})
            .expect("sphere bakes")
            .file;
        (scene, area, file)
    })
}

/// The emissive sphere's radiance.
const SPHERE_LE: f32 = 0.8;

/// In a closed sphere whose wall emits `Le` inwards, the `k`-th bounce's irradiance is
/// `pi Le rho^(k-1)` everywhere, so each pixel's indirect radiance is `Le (rho + ... +
/// rho^B)`; every method is held to what its [`cssm_runtime::method::Checks::emissive`] says,
/// and every pixel's direct light is `Le`.
#[test]
fn every_method_conserves_energy_in_an_emissive_sphere() {
    let (scene, _, file) = emissive_sphere();
    let rho = methods::RHO;
    let options = RenderOptions {
        width: 32,
        height: 24,
        bounces: methods::BOUNCES,
        component: Component::Indirect,
        samples: 16,
        shadow_resolution: 512,
        ..Default::default()
    };
    let mut failures = Vec::new();
    for method in METHODS {
        let image = methods::image_of(method, scene, file, &options);
        let computed = if method.option("bounces").is_some() {
            methods::BOUNCES
        } else {
            1
        };
        let expected: f32 = (1..=computed).map(|k| SPHERE_LE * rho.powi(k as i32)).sum();
        // The whole wall emits, the part on screen too: a screen-space method must see it.
        failures.extend(super::energy_failure(
            method.name,
            method.checks.emissive,
            &image,
            expected,
            true,
        ));
    }
    // The direct light: the wall's emission, everywhere.
    let direct = render(
        gpu(),
        scene,
        Some(file),
        "direct",
        &RenderOptions {
            component: Component::Direct,
            ..options.clone()
        },
    )
    .expect("direct");
    for p in &direct.radiance {
        if (Vec3::new(p[0], p[1], p[2]) - Vec3::splat(SPHERE_LE))
            .abs()
            .max_element()
            > 1e-3
        {
            failures.push(format!("direct: {p:?} where the wall emits {SPHERE_LE}"));
            break;
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Every method of the table renders the room lit by its emitters alone (no light at all)
/// without an error and without a pixel that is not finite; the methods whose indirect light
/// carries emitted light light most of the room indirectly, the others (`vct`, `rsm`) none.
#[test]
fn every_method_renders_a_scene_lit_by_emitters_alone() {
    let (scene, file) = room(false);
    assert!(scene.lights.is_empty());
    let mut failures = Vec::new();
    for method in METHODS {
        for component in [Component::Full, Component::Indirect] {
            let options = RenderOptions {
                width: 40,
                height: 30,
                bounces: 1,
                samples: 4,
                shadow_resolution: 256,
                component,
                ..Default::default()
            };
            let image = methods::image_of(method, scene, file, &options);
            let values: Vec<Vec3> = image
                .radiance
                .iter()
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect();
            if values
                .iter()
                .any(|v| !v.is_finite() || v.min_element() < 0.0)
            {
                failures.push(format!(
                    "{} ({component}): a pixel is not finite or negative",
                    method.name
                ));
                continue;
            }
            let lit = values.iter().filter(|v| v.max_element() > 0.0).count();
            eprintln!(
                "{} ({component}): {lit} of {} pixels lit",
                method.name,
                values.len()
            );
            let indirect = component == Component::Indirect;
            match (indirect, method.checks.emissive) {
                (true, Energy::NoIndirect) if lit > 0 => failures.push(format!(
                    "{}: indirect light from emitters it ignores",
                    method.name
                )),
                (true, Energy::NoIndirect) => {}
                (true, _) if lit * 2 < values.len() => failures.push(format!(
                    "{}: only {lit} pixels lit indirectly by the emitters",
                    method.name
                )),
                // The lamp and the sign are seen directly: 37 pixels of 1,200.
                (false, _) if lit < 30 => {
                    failures.push(format!("{}: only {lit} pixels lit", method.name))
                }
                _ => {}
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The command line on the room lit by its emitters alone: `cssm bake` writes its `.cssm`,
/// `cssm render` draws the indirect light with it (hrc and lightcuts), not black.
#[test]
fn the_command_line_bakes_and_renders_a_scene_lit_by_emitters() {
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("room");
    std::fs::create_dir(&scene_dir).unwrap();
    write_room(&scene_dir, false);
    let cssm_path = dir.path().join("room.cssm");
    let run = |args: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_cssm"))
            .args(args)
            .output()
            .expect("run cssm");
        assert!(
            out.status.success(),
            "cssm {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let scene = scene_dir.to_str().unwrap();
    let baked = run(&[
        "bake",
        scene,
        "-o",
        cssm_path.to_str().unwrap(),
        "--atlas",
        "32",
        "--cube",
        "8",
    ]);
    assert!(
        baked.contains("emissive"),
        "the bake says the scene is lit by its emitters: {baked}"
    );
    for method in ["hrc", "lightcuts"] {
        let png = dir.path().join(format!("{method}.png"));
        run(&[
            "render",
            scene,
            "--cssm",
            cssm_path.to_str().unwrap(),
            "--method",
            method,
            "--size",
            "32x24",
            "--component",
            "indirect",
            "--out",
            png.to_str().unwrap(),
        ]);
        let image = image::open(&png).expect("the PNG reads").to_rgb8();
        let lit = image
            .pixels()
            .filter(|p| p.0.iter().any(|&c| c > 0))
            .count();
        assert!(lit * 2 > image.pixels().len(), "{method}: {lit} pixels lit");
    }
}

/// What a new user meets (issue 52): `cssm render` with no options on a room lit by its
/// emitters alone bakes a `.cssm`, runs the radiosity until a bounce adds at most 1% of the
/// light, and meters the exposure: the image is neither dark nor washed out, and the ceiling,
/// which only light reflected off the walls reaches (the lamp faces down), is lit. With the
/// direct light alone (the default until then) every surface but the emitters is black.
#[test]
fn a_room_lit_by_emitters_renders_lit_and_converged_with_no_options() {
    let dir = tempfile::tempdir().unwrap();
    write_room(dir.path(), false);
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("room-default.png");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_cssm"))
        .args(["render", dir.path().to_str().unwrap(), "--size", "64x48"])
        .arg("--out")
        .arg(&out)
        .output()
        .expect("run cssm");
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{said}");
    assert!(
        said.contains("with lightmap") && said.contains("exposure: automatic"),
        "{said}"
    );
    assert!(
        said.contains("bounces: automatic, ") && said.contains("bounces, the last adding"),
        "{said}"
    );
    let image = image::open(&out).expect("the PNG reads").to_luma8();
    let mean = |rows: std::ops::Range<u32>, columns: std::ops::Range<u32>| {
        let (mut sum, mut n) = (0.0, 0.0);
        for y in rows {
            for x in columns.clone() {
                sum += f64::from(image.get_pixel(x, y).0[0]);
                n += 1.0;
            }
        }
        sum / n
    };
    let all = mean(0..48, 0..64);
    assert!((40.0..170.0).contains(&all), "mean {all}");
    let ceiling = mean(0..4, 16..48);
    assert!(ceiling > 0.3 * all, "ceiling {ceiling}, image {all}");
}
