//! The bake's depth cube maps on the GPU (`cssm bake --device gpu`, issue 25) against the CPU's
//! ray casts: the kernel's hits pixel by pixel, and whole files.

use cssm_bake::{BakeDevice, BakeOptions, cubemap::SecondLayer};
use cssm_formats::{Scene, cube};
use cssm_raycast::{SceneBvh, SplitMix64};
use cssm_runtime::visibility::depth_maps::{
    DepthMapKernel, DepthMapSettings, DepthMapTexel, decode,
};
use glam::Vec3;

use super::gpu;

/// Lavapipe rounds as the CPU does (LLVM, no fused multiply-adds nor approximate division), so
/// there the GPU's answers must equal the CPU's; a GPU may round a ray through an edge
/// otherwise, so elsewhere a few may differ.
fn exact_device() -> bool {
    gpu().describe().contains("llvmpipe")
}

/// Random triangles in the unit cube, and one triangle stacked five times over (every ray
/// through it meets five hits at one distance: more than the kernel's hit list keeps, so it
/// hands those pixels back to the CPU).
fn soup() -> Scene {
    let mut rng = SplitMix64(17);
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let point = |rng: &mut SplitMix64| {
        Vec3::new(
            rng.next_f64() as f32,
            rng.next_f64() as f32,
            rng.next_f64() as f32,
        ) * 2.0
            - 1.0
    };
    for _ in 0..300 {
        let base = positions.len() as u32;
        let centre = point(&mut rng);
        for _ in 0..3 {
            positions.push(centre + point(&mut rng) * 0.3);
        }
        triangles.push([base, base + 1, base + 2]);
    }
    let base = positions.len() as u32;
    positions.extend([
        Vec3::new(-2.0, -2.0, 1.5),
        Vec3::new(2.0, -2.0, 1.5),
        Vec3::new(0.0, 2.0, 1.5),
    ]);
    for _ in 0..5 {
        triangles.push([base, base + 1, base + 2]);
    }
    Scene::from_triangles(positions, triangles)
}

#[test]
fn depth_map_kernel_matches_cpu_ray_casts() {
    let gpu = gpu();
    let scene = soup();
    let bvh = SceneBvh::new(&scene);
    let (triangles, normals) = bvh.triangles_by_scene_index();
    let kernel = DepthMapKernel::new(gpu, &triangles, normals, bvh.box_padding()).expect("kernel");
    let mut rng = SplitMix64(3);
    // The first 16 on a staggered grid (each of its four offsets), the rest centred.
    let offset = |t: usize| {
        let grid = cube::PixelGrid::ALL[usize::from(t < 16)];
        grid.offset(t as u16 % 2, t as u16 / 2 % 2)
    };
    let texels: Vec<DepthMapTexel> = (0..24)
        .map(|t| {
            let mut v = || rng.next_f64() as f32 * 2.0 - 1.0;
            let centre = Vec3::new(v(), v(), v()) * 0.8;
            let normal = Vec3::new(v(), v(), v()).normalize_or(Vec3::Z);
            DepthMapTexel {
                centre: centre.to_array(),
                grid_u: offset(t).x,
                normal: normal.to_array(),
                grid_v: offset(t).y,
            }
        })
        .collect();
    let n = 16;
    let pixels = (6 * n * n) as usize;
    for every_hit_faces in [false, true] {
        let settings = DepthMapSettings {
            resolution: n,
            min_hit: 1e-4,
            separation: 1e-3,
            every_hit_faces,
        };
        let answers = kernel.run(gpu, &texels, settings).expect("kernel run");
        assert_eq!(answers.len(), texels.len() * pixels);
        let (mut cast, mut handed_back, mut differ, mut second_hits) = (0, 0, 0, 0);
        for (t, texel) in texels.iter().enumerate() {
            let normal = Vec3::from(texel.normal);
            let offset = offset(t);
            for pixel in 0..pixels {
                let (dir, depth_scale) = cube::cast_direction_at(n, pixel as u32, normal, offset);
                if cube::pixel_is_dont_care_at(n, pixel as u32, normal, offset)
                    || depth_scale < 1e-3
                {
                    continue;
                }
                cast += 1;
                let centre = Vec3::from(texel.centre);
                let Some(gpu_hit) = decode(answers[t * pixels + pixel]) else {
                    handed_back += 1;
                    continue;
                };
                let same = if every_hit_faces {
                    let cpu = bvh.dual_hit_beyond(centre, dir, 1e-4, 1e-3);
                    (cpu.first, cpu.second) == (gpu_hit.first, gpu_hit.second)
                } else {
                    bvh.front_dual_hit_beyond(centre, dir, 1e-4, 1e-3) == gpu_hit
                };
                differ += usize::from(!same);
                second_hits += usize::from(gpu_hit.second.is_finite());
            }
        }
        eprintln!(
            "depth-map kernel (every hit faces: {every_hit_faces}): {cast} rays, {differ} differ \
             from the CPU, {handed_back} handed back, {second_hits} with a second hit"
        );
        assert!(second_hits > cast / 20, "{second_hits} second hits");
        // The stacked triangle's rays come back to the CPU, and only a few others.
        assert!(
            handed_back > 0 && handed_back < cast / 4,
            "{handed_back} handed back"
        );
        if exact_device() {
            assert_eq!(differ, 0, "on lavapipe the kernel is the CPU's arithmetic");
        } else {
            assert!(differ * 1000 <= cast, "{differ} of {cast} differ");
        }
    }
}

/// Rays in a triangle's plane miss it on the GPU as on the CPU (`seen_edge_on` and its WGSL
/// twin): triangles and cube centres in the oblique plane `x + y + z = 0` (the third coordinate
/// rounded, as a turned scene's are), whose pixel rays with face coordinates summing to one run
/// in that plane, as turned cube maps cast horizontal rays along a box's top. Without the WGSL
/// test the GPU reports such "hits" at rounding-noise distances.
#[test]
fn depth_map_kernel_misses_triangles_in_the_rays_plane() {
    let gpu = gpu();
    let mut rng = SplitMix64(23);
    let mut coordinate = || ((rng.next_f64() * 2.0 - 1.0) * 300.0) as f32;
    let mut point = || {
        let (x, y) = (coordinate(), coordinate());
        Vec3::new(x, y, -x - y)
    };
    let positions: Vec<Vec3> = (0..900).map(|_| point()).collect();
    let triangles = (0..300).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    let centres: Vec<Vec3> = (0..128).map(|_| point()).collect();
    let scene = Scene::from_triangles(positions, triangles);
    let bvh = SceneBvh::new(&scene);
    let (triangles, normals) = bvh.triangles_by_scene_index();
    let kernel = DepthMapKernel::new(gpu, &triangles, normals, bvh.box_padding()).expect("kernel");
    // A normal off the plane, so that the in-plane pixels are cast as they are.
    let normal = Vec3::new(1.0, -2.0, 0.5).normalize();
    let texels: Vec<DepthMapTexel> = centres
        .iter()
        .map(|c| DepthMapTexel {
            centre: c.to_array(),
            grid_u: 0.0,
            normal: normal.to_array(),
            grid_v: 0.0,
        })
        .collect();
    let n = 16;
    let pixels = (6 * n * n) as usize;
    let settings = DepthMapSettings {
        resolution: n,
        min_hit: 1e-4,
        separation: 1e-3,
        every_hit_faces: true,
    };
    let answers = kernel.run(gpu, &texels, settings).expect("kernel run");
    let (mut in_plane, mut differ) = (0, 0);
    for (t, centre) in centres.iter().enumerate() {
        for pixel in 0..pixels {
            let (dir, depth_scale) = cube::cast_direction(n, pixel as u32, normal);
            if cube::pixel_is_dont_care(n, pixel as u32, normal) || depth_scale < 1e-3 {
                continue;
            }
            let Some(gpu_hit) = decode(answers[t * pixels + pixel]) else {
                continue;
            };
            let cpu = bvh.dual_hit_beyond(*centre, dir, 1e-4, 1e-3);
            differ += usize::from((cpu.first, cpu.second) != (gpu_hit.first, gpu_hit.second));
            if dir.x + dir.y + dir.z == 0.0 {
                in_plane += 1;
                assert!(
                    cpu.first.is_infinite() && gpu_hit.first.is_infinite(),
                    "a ray in the triangles' plane hit: CPU {}, GPU {} from {centre} along {dir}",
                    cpu.first,
                    gpu_hit.first
                );
            }
        }
    }
    assert!(in_plane > 200, "{in_plane} rays in the plane");
    if exact_device() {
        assert_eq!(differ, 0, "on lavapipe the kernel is the CPU's arithmetic");
    }
}

/// A bake on the GPU writes the CPU's file: the Cornell box with a rigid block (two
/// geometries, one kernel each), every second layer.
#[test]
fn gpu_bake_writes_the_cpu_file() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    for f in ["cornell-box.obj", "cornell-box.mtl"] {
        std::fs::copy(cornell.join(f), dir.path().join(f)).unwrap();
    }
    let block = format!(
        "mtllib cornell-box.mtl\nusemtl white\n{}",
        cssm::builtin::cube_obj([0.0; 3], 60.0, 0, false)
    );
    std::fs::write(dir.path().join("block.obj"), block).unwrap();
    std::fs::write(
        dir.path().join("scene.toml"),
        "name = \"cornell-block\"\nmesh = \"cornell-box.obj\"\n\n[[objects]]\nname = \"block\"\n\
         mesh = \"block.obj\"\ntranslation = [300.0, 0.0, 200.0]\nscale = 2.0\n",
    )
    .unwrap();
    let scene = Scene::load(dir.path()).expect("scene");
    // Every layer, on both pixel grids between them, with the faces on the world's axes; then
    // the default turned frame, where the box's quads' diagonals meet pixel rays exactly (edge
    // functions of exactly zero, which the CPU once recomputed in double precision and the
    // GPU cannot): lavapipe writes the CPU's file in either frame.
    let layers = SecondLayer::ALL
        .into_iter()
        .enumerate()
        .map(|(k, layer)| (layer, cube::PixelGrid::ALL[k % 2], cube::CubeFrame::World))
        .chain([(
            SecondLayer::Exchange,
            cube::PixelGrid::Centred,
            cube::CubeFrame::Turned,
        )]);
    for (second_layer, pixel_grid, cube_frame) in layers {
        let options = BakeOptions {
            atlas_resolution: 32,
            cube_resolution: 16,
            second_layer,
            pixel_grid,
            cube_frame,
            ..Default::default()
        };
        let bake = |device| {
            let options = BakeOptions {
                device,
                ..options.clone()
            };
            let baked = cssm_bake::bake(&scene, &options, &mut |_| {}).expect("bake");
            (
                baked.stats,
                cssm_formats::cssm::encode(&baked.file).expect("encode"),
            )
        };
        let (cpu_stats, cpu_file) = bake(BakeDevice::Cpu);
        let (gpu_stats, gpu_file) = bake(BakeDevice::Gpu);
        assert!(gpu_stats.gpu.is_some() && cpu_stats.gpu.is_none());
        assert_eq!(gpu_stats.rays, cpu_stats.rays);
        assert!(cpu_stats.csms == 1, "the block is a rigid object");
        if exact_device() {
            assert!(
                cpu_file == gpu_file,
                "{second_layer}, {cube_frame} frame: the files differ"
            );
        } else {
            let runs = |s: &cssm_bake::BakeStats| s.runs as f64;
            assert!(
                (runs(&gpu_stats) / runs(&cpu_stats) - 1.0).abs() < 0.005,
                "{second_layer}: {} runs on the GPU, {} on the CPU",
                gpu_stats.runs,
                cpu_stats.runs
            );
        }
    }
}

/// `cssm bake --device gpu` where no Vulkan driver loads: a clear error, exit 2, no file.
#[test]
fn gpu_bake_without_a_gpu_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cornell.cssm");
    let nowhere = dir.path().join("no-driver.json");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_cssm"))
        .args([
            "bake", "--atlas", "32", "--cube", "8", "--device", "gpu", "-o",
        ])
        .arg(&out)
        .env("VK_ICD_FILENAMES", &nowhere)
        .env("VK_DRIVER_FILES", &nowhere)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("GPU: no GPU adapter found"), "{stderr}");
    assert!(stderr.contains("mesa-vulkan-drivers"), "{stderr}");
    assert!(!out.exists());
}
