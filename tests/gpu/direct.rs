//! Direct light on screen and into the atlas texels against its CPU reference.

use super::*;

#[test]
fn direct_light_matches_cpu_reference() {
    use cssm_runtime::{common::camera::View, direct::cpu, load::cpu_materials};
    let gpu = gpu();
    let (scene, _) = cornell();
    let (w, h) = (160u32, 120u32);
    let options = RenderOptions {
        width: w,
        height: h,
        ..Default::default()
    };
    let frame = render(gpu, scene, None, "direct", &options).expect("render");
    let (materials, textures) = cpu_materials(scene).expect("textures");
    let bvh = cssm_raycast::SceneBvh::new(scene);
    let view = View::of_scene(scene, w, h);
    let reference = cpu::render_screen(scene, &view, &materials, &textures, &bvh);
    // Away from edges: no shadow or cone edge within 2 pixels, no silhouette or crease within 1.
    let normal_of = |t: u32| {
        if t == u32::MAX {
            glam::Vec3::ZERO
        } else {
            let [a, b, c] = scene.triangle(t as usize);
            (b - a).cross(c - a).normalize_or_zero()
        }
    };
    let keep: Vec<bool> = (0..(w * h) as i64)
        .map(|i| {
            let (x, y) = (i % w as i64, i / w as i64);
            let me = reference[i as usize];
            if me.triangle == u32::MAX {
                return false;
            }
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
                    if dx.abs() <= 1
                        && dy.abs() <= 1
                        && normal_of(other.triangle).dot(normal_of(me.triangle)).abs() < 0.999
                    {
                        return false;
                    }
                }
            }
            true
        })
        .collect();
    let kept = keep.iter().filter(|&&k| k).count();
    let gpu_radiance: Vec<glam::Vec3> = frame
        .radiance
        .iter()
        .map(|p| glam::Vec3::new(p[0], p[1], p[2]))
        .collect();
    let cpu_radiance: Vec<glam::Vec3> = reference.iter().map(|p| p.radiance).collect();
    let rmse = relative_rmse(&gpu_radiance, &cpu_radiance, &keep);
    let lit_kept = keep
        .iter()
        .zip(&reference)
        .filter(|(k, p)| **k && p.lit != 0)
        .count();
    eprintln!(
        "direct light, {w}x{h}: relative RMSE {:.4}% over {kept} of {} pixels ({lit_kept} lit)",
        100.0 * rmse,
        w * h
    );
    if rmse >= 0.05 {
        let out = std::env::temp_dir().join("cssm-direct-actual.png");
        save_png(&frame, &out);
        eprintln!("GPU image written to {}", out.display());
    }
    assert!(kept as u32 > w * h / 2, "too few pixels compared: {kept}");
    assert!(
        lit_kept > kept / 4,
        "too few lit pixels compared: {lit_kept}"
    );
    assert!(rmse < 0.05, "relative RMSE {rmse} (allowed 5%)");
    // The tone-mapped image is the CPU tone mapping of the GPU radiance, to one step.
    for (p, d) in frame.radiance.iter().zip(frame.display.chunks(4)) {
        let expect = cssm_runtime::common::tonemap::tonemap([p[0], p[1], p[2]], options.exposure);
        for c in 0..3 {
            assert!(
                (expect[c] as i32 - d[c] as i32).abs() <= 1,
                "tone mapping: {:?} -> GPU {:?}, CPU {:?}",
                p,
                &d[..3],
                expect
            );
        }
    }
}

#[test]
fn atlas_direct_light_matches_cpu_reference() {
    let (scene, file) = cornell();
    atlas_direct_light_vs_cpu(scene, file);
    // A glossy floor: its texels reflect Kd + Ks in the bounces (`bounce_albedo`).
    let (scene, file) = baked(
        "cornell-glossy",
        BakeOptions {
            atlas_resolution: 32,
            cube_resolution: 8,
            ..Default::default()
        },
    );
    assert!(scene.materials.iter().any(|m| m.ks[0] > 0.0));
    atlas_direct_light_vs_cpu(&scene, &file);
}

fn atlas_direct_light_vs_cpu(scene: &Scene, file: &CssmFile) {
    let gpu = gpu();
    let gpu_texels =
        cssm_runtime::radiosity::render_atlas_direct(&gpu.device, &gpu.queue, scene, file, 2048)
            .expect("atlas pass");
    let bvh = cssm_raycast::SceneBvh::new(scene);
    let cpu_texels =
        cssm_runtime::direct::cpu::render_atlas(scene, &materials(scene), &file.texels, &bvh);
    assert_eq!(gpu_texels.len(), cpu_texels.len());
    // Away from shadow and cone edges: texels whose atlas neighbours in the same chart agree
    // with them on lit or not.
    let r = file.params.atlas_resolution as usize;
    let mut grid = vec![u32::MAX; r * r];
    for (i, t) in file.texels.iter().enumerate() {
        grid[t.y as usize * r + t.x as usize] = i as u32;
    }
    let lit = |i: usize| cpu_texels[i].length_squared() > 0.0;
    let keep: Vec<bool> = file
        .texels
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let (x, y) = (t.x as i64, t.y as i64);
            for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx >= r as i64 || ny >= r as i64 {
                    continue;
                }
                let n = grid[ny as usize * r + nx as usize];
                if n != u32::MAX
                    && file.texels[n as usize].chart == t.chart
                    && lit(n as usize) != lit(i)
                {
                    return false;
                }
            }
            true
        })
        .collect();
    let g: Vec<glam::Vec3> = gpu_texels
        .iter()
        .map(|p| glam::Vec3::new(p[0], p[1], p[2]))
        .collect();
    let rmse = relative_rmse(&g, &cpu_texels, &keep);
    let kept = keep.iter().filter(|&&k| k).count();
    eprintln!(
        "atlas direct light: relative RMSE {:.4}% over {kept} of {} texels",
        100.0 * rmse,
        keep.len()
    );
    assert!(kept > keep.len() / 2, "too few texels compared");
    assert!(rmse < 0.05, "relative RMSE {rmse}");
}
