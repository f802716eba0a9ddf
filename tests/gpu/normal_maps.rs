//! Bump and normal maps (issue 22, item 7; the CSSM paper's Fig. 1, right): the G-buffer's
//! shading normal and the direct light on it against their CPU twins
//! (`direct::cpu::render_screen`), on a small scene written by the tests into a temporary
//! directory: a floor with a height map (`bump -bm`), a back wall with a tangent-space normal
//! map (`norm`) whose right half has mirrored UVs, under a spot light.

use std::path::Path;

use cssm_formats::Scene;
use cssm_runtime::common::{
    camera::View,
    compose::Component,
    readback::{read_texture, render_image},
};
use glam::Vec3;

use super::{relative_rmse, ssil};

/// Writes the scene into `dir`: `bumps.obj`, `bumps.mtl`, `height.png` (round bumps on a
/// grid), `normals.png` (a normal map of ridges along v) and `scene.toml`.
fn write_scene(dir: &Path) {
    // Floor y = 0 (facing +y), UVs repeated twice; back wall z = -1 (facing +z) in two halves,
    // the right one with u mirrored.
    let obj = "mtllib bumps.mtl\n\
        v -1 0 1\nv 1 0 1\nv 1 0 -1\nv -1 0 -1\n\
        v -1 0 -1\nv 0 0 -1\nv 0 2 -1\nv -1 2 -1\nv 1 0 -1\nv 1 2 -1\n\
        vt 0 0\nvt 2 0\nvt 2 2\nvt 0 2\n\
        vt 0 0\nvt 1 0\nvt 1 2\nvt 0 2\n\
        usemtl bumpy\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n\
        usemtl ridged\nf 5/5 6/6 7/7\nf 5/5 7/7 8/8\nf 6/6 9/5 10/8\nf 6/6 10/8 7/7\n";
    std::fs::write(dir.join("bumps.obj"), obj).unwrap();
    std::fs::write(
        dir.join("bumps.mtl"),
        "newmtl bumpy\nKd 0.7 0.7 0.7\nmap_Bump -bm 6 height.png\n\
         newmtl ridged\nKd 0.6 0.5 0.4\nNORM normals.png\n",
    )
    .unwrap();
    let height = image::GrayImage::from_fn(64, 64, |x, y| {
        let (u, v) = (x as f32 / 64.0, y as f32 / 64.0);
        let g = (u * 4.0 * std::f32::consts::TAU).sin() * (v * 4.0 * std::f32::consts::TAU).sin();
        image::Luma([(127.5 + 127.0 * g) as u8])
    });
    height.save(dir.join("height.png")).unwrap();
    let normals = image::RgbImage::from_fn(64, 64, |x, _| {
        let a = (x as f32 / 64.0 * 3.0 * std::f32::consts::TAU).sin() * 0.6;
        let n = Vec3::new(a.sin(), 0.0, a.cos()) * 0.5 + 0.5;
        image::Rgb((n * 255.0).round().to_array().map(|c| c as u8))
    });
    normals.save(dir.join("normals.png")).unwrap();
    std::fs::write(
        dir.join("scene.toml"),
        "name = \"normal-maps\"\nmesh = \"bumps.obj\"\n\n[camera]\n\
         position = [0.0, 1.2, 2.6]\ntarget = [0.0, 0.5, 0.0]\nup = [0.0, 1.0, 0.0]\n\
         fov_y_deg = 50.0\nresolution = [64, 48]\n\n[[lights]]\ntype = \"spot\"\n\
         position = [0.3, 1.6, 1.0]\ndirection = [-0.2, -1.0, -0.8]\ncutoff_deg = 70.0\n\
         intensity = [3.0, 3.0, 3.0]\n",
    )
    .unwrap();
}

/// The scene, loaded once from a directory that outlives it.
fn scene() -> &'static Scene {
    use std::sync::OnceLock;
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("normal-maps");
        std::fs::create_dir_all(&dir).unwrap();
        write_scene(&dir);
        let scene = Scene::load(&dir).expect("the scene loads");
        assert!(scene.materials.iter().all(|m| m.normal_map.is_some()));
        scene
    })
}

/// Pixels whose 3x3 neighbourhood sees one plane, and (for `lights`) whose 5x5 agrees on the
/// lights that reach them: where rasterisation and shadow maps agree with exact rays.
fn interior(
    scene: &Scene,
    reference: &[cssm_runtime::direct::cpu::CpuPixel],
    (w, h): (u32, u32),
    lights: bool,
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
                    if lights && other.lit != me.lit {
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

/// The G-buffer's normal is the CPU twin's normal-mapped shading normal, pixel by pixel (the
/// floor's height map, the wall's normal map, plain and mirrored), and the direct light on it
/// is the CPU reference's; the maps visibly change both.
#[test]
fn normal_mapped_gbuffer_and_direct_light_match_cpu_twins() {
    use cssm_runtime::direct::cpu;
    let scene = scene();
    let (w, h) = (96u32, 72u32);
    let mut renderer = ssil::renderer_of("direct", scene, (w, h), Component::Full);
    let frame = render_image(&mut renderer, 1).expect("render");
    let ctx = renderer.context();
    let bytes = read_texture(&ctx.device, &ctx.queue, &ctx.gbuffer.normal, 16).expect("read");
    let gpu_normals: Vec<Vec3> = bytemuck::cast_slice::<u8, f32>(&bytes)
        .chunks(4)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect();
    let (materials, textures) = cssm_runtime::load::cpu_materials(scene).expect("materials");
    assert!(materials.iter().all(|m| m.normal_texture >= 0));
    let bvh = cssm_raycast::SceneBvh::new(scene);
    let view = View::of_scene(scene, w, h);
    let reference = cpu::render_screen(scene, &view, &materials, &textures, &bvh);

    // The normals, wherever a pixel and its neighbours see one plane.
    let keep = interior(scene, &reference, (w, h), false);
    let (mut compared, mut tilted, mut worst) = (0, 0, 1.0f32);
    let mut per_material = [0usize; 2];
    for (i, (r, g)) in reference.iter().zip(&gpu_normals).enumerate() {
        if !keep[i] {
            continue;
        }
        compared += 1;
        worst = worst.min(r.normal.dot(*g));
        let [a, b, c] = scene.triangle(r.triangle as usize);
        let geometric = (b - a).cross(c - a).normalize();
        if r.normal.dot(geometric).abs() < 0.995 {
            tilted += 1;
            per_material[scene.triangle_materials[r.triangle as usize] as usize] += 1;
        }
        // Unit, never NaN, never below the side of the surface the eye sees.
        let facing = if geometric.dot(view.eye - a) < 0.0 {
            -geometric
        } else {
            geometric
        };
        assert!(
            g.is_finite() && (g.length() - 1.0).abs() < 1e-3,
            "pixel {i}: {g}"
        );
        let least = cssm_runtime::normal_map::MIN_SHADING_COS - 1e-4;
        assert!(g.dot(facing) >= least, "pixel {i}: {g} below {facing}");
    }
    eprintln!(
        "normal maps, {w}x{h}: {compared} pixels compared, {tilted} tilted ({per_material:?} \
         floor, wall), worst cosine GPU vs CPU {worst}"
    );
    assert!(
        compared as u32 > w * h / 3,
        "too few pixels compared: {compared}"
    );
    assert!(
        per_material.iter().all(|&n| n > compared / 10),
        "{per_material:?}"
    );
    assert!(
        worst > 0.995,
        "worst cosine between the GPU and CPU normals {worst}"
    );

    // The direct light, away from shadow and cone edges too.
    let keep = interior(scene, &reference, (w, h), true);
    let kept = keep.iter().filter(|&&k| k).count();
    let gpu_radiance: Vec<Vec3> = frame
        .radiance
        .iter()
        .map(|p| Vec3::new(p[0], p[1], p[2]))
        .collect();
    let cpu_radiance: Vec<Vec3> = reference.iter().map(|p| p.radiance).collect();
    let rmse = relative_rmse(&gpu_radiance, &cpu_radiance, &keep);
    // The same scene without its maps: the maps must show in the light.
    let flat_materials: Vec<_> = materials
        .iter()
        .map(|m| cssm_runtime::gpu_types::GpuMaterial {
            normal_texture: -1,
            ..*m
        })
        .collect();
    let flat = cpu::render_screen(scene, &view, &flat_materials, &textures, &bvh);
    let flat_radiance: Vec<Vec3> = flat.iter().map(|p| p.radiance).collect();
    let change = relative_rmse(&flat_radiance, &cpu_radiance, &keep);
    eprintln!(
        "normal-mapped direct light: relative RMSE {:.4}% over {kept} pixels; the maps change \
         it by {:.1}%",
        100.0 * rmse,
        100.0 * change
    );
    assert!(kept as u32 > w * h / 4, "too few pixels compared: {kept}");
    assert!(rmse < 0.02, "relative RMSE {rmse}");
    assert!(
        change > 0.05,
        "the maps change the direct light by {change} only"
    );
}

/// The final gather sees the detail too (lightcuts reads the G-buffer's shading normal): the
/// GPU gather against its CPU twin with normal-mapped receivers, with and without the maps,
/// and the maps change the gathered light. The walk (`gather=walk`): the atlas form's far field
/// is gathered at the texels' own normals, so the maps change its near field only.
#[test]
fn normal_mapped_final_gather_matches_cpu_twin() {
    let scene = scene();
    let options = cssm_bake::BakeOptions {
        atlas_resolution: 32,
        cube_resolution: 32,
        ..Default::default()
    };
    let file = cssm_bake::bake(scene, &options, &mut |_| {})
        .expect("the scene bakes")
        .file;
    let threshold = cssm_runtime::radiosity::DEFAULT_THRESHOLD;
    let (w, h) = (48, 36);
    let (rmse, mapped) = super::final_gather_vs_twin(scene, &file, w, h, threshold, false, "walk");
    // The same scene without its maps (the same files, so the same bake).
    let mut flat_scene = scene.clone();
    for m in &mut flat_scene.materials {
        m.normal_map = None;
    }
    let (flat_rmse, flat) =
        super::final_gather_vs_twin(&flat_scene, &file, w, h, threshold, false, "walk");
    let lit: Vec<bool> = flat.iter().map(|c| c.max_element() > 0.0).collect();
    let change = relative_rmse(&mapped, &flat, &lit);
    eprintln!(
        "normal-mapped final gather: GPU vs twin {:.4}% (without the maps {:.4}%); the maps \
         change it by {:.1}% over {} pixels",
        100.0 * rmse,
        100.0 * flat_rmse,
        100.0 * change,
        lit.iter().filter(|&&l| l).count()
    );
    assert!(lit.iter().filter(|&&l| l).count() as u32 > w * h / 3);
    assert!(rmse < 0.01 && flat_rmse < 0.01, "{rmse}, {flat_rmse}");
    assert!(
        change > 0.02,
        "the maps change the final gather by {change} only"
    );
}
