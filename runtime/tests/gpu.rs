//! GPU tests of the runtime against its CPU references. They run on any Vulkan device; on a
//! machine without a GPU that is Mesa's lavapipe (`apt-get install mesa-vulkan-drivers`, which
//! `.ci/run` does). They never skip: without a device they fail and say how to get one.

use std::sync::OnceLock;

use cssm_bake::{BakeOptions, check::SplitMix64, check::SurfaceSampler};
use cssm_formats::{
    CssmFile, Scene, Traversal, visibility::QueryOptions, visibility::VisibilityQuery,
};
use cssm_runtime::{
    Gpu,
    load::CssmGpu,
    visibility::{QueryKernel, QueryPair},
};

fn gpu() -> &'static Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| match Gpu::new_headless() {
        Ok(gpu) => {
            eprintln!("GPU tests on {}", gpu.describe());
            gpu
        }
        Err(e) => panic!("GPU tests need a Vulkan device: {e}"),
    })
}

fn cornell() -> &'static (Scene, CssmFile) {
    static CORNELL: OnceLock<(Scene, CssmFile)> = OnceLock::new();
    CORNELL.get_or_init(|| {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box");
        let scene = Scene::load(&dir).expect("built-in Cornell box loads");
        let options = BakeOptions {
            atlas_resolution: 64,
            cube_resolution: 32,
            traversal: Traversal::Spiral,
            ..Default::default()
        };
        let baked = cssm_bake::bake(&scene, &options, &mut |_, _| {}).expect("bake");
        (scene, baked.file)
    })
}

fn random_pairs(scene: &Scene, count: usize, seed: u64) -> Vec<QueryPair> {
    cssm_runtime::visibility::random_pairs(scene, count, seed).0
}

/// GPU and CPU answers to the same pairs: (pairs compared, decisions that differ, largest
/// difference of the visible fraction).
fn compare(options: QueryOptions, count: usize, seed: u64) -> (usize, usize, f32) {
    let gpu = gpu();
    let (scene, file) = cornell();
    let pairs = random_pairs(scene, count, seed);
    let cssm = CssmGpu::new(&gpu.device, &gpu.queue, file, options).expect("upload");
    let kernel = QueryKernel::new(gpu, &cssm);
    let answers = kernel.run(gpu, &cssm, &pairs, None).expect("GPU queries");
    let query = VisibilityQuery::new(file, options);
    let (mut differ, mut worst) = (0, 0.0f32);
    for (pair, &gpu_answer) in pairs.iter().zip(&answers) {
        let n = glam::Vec3::from(pair.receiver_normal);
        let cpu = query.visibility_from_surface(
            pair.sender_triangle as usize,
            pair.sender_bary,
            pair.receiver.into(),
            Some(n),
        );
        match cpu {
            None => assert_eq!(gpu_answer, -1.0, "GPU found a texel where the CPU did not"),
            Some(cpu) => {
                if (cpu >= 0.5) != (gpu_answer >= 0.5) {
                    differ += 1;
                }
                worst = worst.max((cpu - gpu_answer).abs());
            }
        }
    }
    (pairs.len(), differ, worst)
}

#[test]
fn gpu_matches_cpu_reference() {
    let (n, differ, worst) = compare(QueryOptions::default(), 100_000, 7);
    eprintln!(
        "GPU vs CPU visibility: {differ} of {n} decisions differ, largest fraction difference {worst}"
    );
    assert!(
        differ as f64 <= 1e-4 * n as f64,
        "{differ} of {n} decisions differ (allowed: 0.01%)"
    );
}

#[test]
fn gpu_matches_cpu_without_filtering() {
    let options = QueryOptions {
        pcf: false,
        sender_filter: false,
        bias_near: 1.0,
        bias_relative: 0.001,
    };
    let (n, differ, worst) = compare(options, 20_000, 11);
    eprintln!("unfiltered: {differ} of {n} differ, largest difference {worst}");
    assert!(differ as f64 <= 1e-4 * n as f64, "{differ} of {n} differ");
}

/// Relative RMSE of `gpu` against `cpu` over the pixels `keep` marks.
fn relative_rmse(gpu: &[glam::Vec3], cpu: &[glam::Vec3], keep: &[bool]) -> f64 {
    let (mut err, mut norm) = (0.0f64, 0.0f64);
    for ((g, c), &k) in gpu.iter().zip(cpu).zip(keep) {
        if k {
            err += (*g - *c).length_squared() as f64;
            norm += c.length_squared() as f64;
        }
    }
    (err / norm.max(1e-30)).sqrt()
}

#[test]
fn direct_light_matches_cpu_reference() {
    use cssm_runtime::{
        common::camera::View,
        direct::cpu,
        frame::{self, Method, RenderOptions},
        load::load_albedo_textures,
    };
    let gpu = gpu();
    let (scene, _) = cornell();
    let (w, h) = (160u32, 120u32);
    let options = RenderOptions {
        width: w,
        height: h,
        ..Default::default()
    };
    let frame = frame::render(gpu, scene, Method::Direct, &options).expect("render");
    let (textures, index) = load_albedo_textures(scene).expect("textures");
    let materials: Vec<_> = scene
        .materials
        .iter()
        .zip(index)
        .map(|(m, texture)| cssm_runtime::gpu_types::GpuMaterial {
            kd: m.kd,
            ns: m.ns,
            ks: m.ks,
            texture,
        })
        .collect();
    let bvh = cssm_bake::raycast::SceneBvh::new(scene);
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
        let _ = frame.save_png(&out);
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
    let gpu = gpu();
    let (scene, file) = cornell();
    let gpu_texels =
        cssm_runtime::frame::render_atlas_direct(gpu, scene, file, 2048).expect("atlas pass");
    let bvh = cssm_bake::raycast::SceneBvh::new(scene);
    let cpu_texels = cssm_runtime::direct::cpu::render_atlas(scene, file, &bvh);
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

#[test]
fn corrupt_or_mismatched_files_give_errors() {
    use cssm_runtime::{RuntimeError, load::read_cssm};
    let (scene, file) = cornell();
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("cornell.cssm");
    cssm_formats::cssm::write_atomic(&path, file).unwrap();
    assert!(read_cssm(&path, scene).is_ok());
    // A flipped byte in the payload: the checksum catches it.
    let mut bytes = std::fs::read(&path).unwrap();
    let last = bytes.len() - 10;
    bytes[last] ^= 0x5a;
    let corrupt = tmp.path().join("corrupt.cssm");
    std::fs::write(&corrupt, &bytes).unwrap();
    let err = read_cssm(&corrupt, scene).unwrap_err();
    assert!(matches!(err, RuntimeError::Cssm(_)), "{err}");
    assert!(err.to_string().contains("corrupt.cssm"), "{err}");
    // Truncated.
    std::fs::write(&corrupt, &bytes[..bytes.len() / 2]).unwrap();
    assert!(matches!(
        read_cssm(&corrupt, scene),
        Err(RuntimeError::Cssm(_))
    ));
    // Another scene: the glossy Cornell box has the same triangles but other files.
    let glossy_dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-glossy");
    let glossy = Scene::load(&glossy_dir).unwrap();
    let err = read_cssm(&path, &glossy).unwrap_err();
    assert!(matches!(err, RuntimeError::SceneMismatch { .. }), "{err}");
    assert!(err.to_string().contains("re-bake"), "{err}");
    // The device is still usable after all that: a query still runs.
    let gpu = gpu();
    let cssm = CssmGpu::new(&gpu.device, &gpu.queue, file, QueryOptions::default()).unwrap();
    let kernel = QueryKernel::new(gpu, &cssm);
    let pairs = random_pairs(scene, 100, 3);
    assert_eq!(kernel.run(gpu, &cssm, &pairs, None).unwrap().len(), 100);
}

#[test]
fn a_shader_error_is_an_error_not_a_panic() {
    // A device of its own: the error must not reach the tests sharing the common one.
    let gpu = &Gpu::new_headless().expect("a Vulkan device");
    let _module = gpu
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("broken"),
            source: wgpu::ShaderSource::Wgsl("fn main( {".into()),
        });
    let err = gpu.wait().unwrap_err();
    assert!(err.to_string().contains("broken"), "{err}");
    assert!(gpu.wait().is_ok(), "the error is reported once");
}

#[test]
fn bvh_kernel_matches_cpu_ray_casts() {
    use cssm_runtime::visibility::bvh::BvhKernel;
    let gpu = gpu();
    let (scene, _) = cornell();
    // The segments of the accuracy check's ground truth (`cssm_bake::check::exact_visible`).
    let (_, segments) = cssm_runtime::visibility::random_pairs(scene, 50_000, 5);
    let kernel = BvhKernel::new(gpu, scene).expect("bvh");
    let gpu_clear = kernel.run(gpu, &segments, None).expect("GPU traversal");
    let bvh = cssm_bake::raycast::SceneBvh::new(scene);
    let differ = segments
        .iter()
        .zip(&gpu_clear)
        .filter(|(s, g)| bvh.segment_clear(s.a.into(), s.b.into()) != **g)
        .count();
    let clear = gpu_clear.iter().filter(|&&c| c).count();
    eprintln!(
        "BVH kernel vs CPU ray casts: {differ} of {} differ ({clear} clear)",
        segments.len()
    );
    assert!(
        clear > 1000 && clear < segments.len() - 1000,
        "{clear} clear"
    );
    assert!(
        differ as f64 <= 1e-4 * segments.len() as f64,
        "{differ} differ"
    );
}

#[test]
fn gather_kernel_matches_cpu() {
    use cssm_runtime::visibility::gather::{GatherKernel, Receiver, gather_cpu};
    let gpu = gpu();
    let (scene, file) = cornell();
    let sampler = SurfaceSampler::new(scene);
    let mut rng = SplitMix64(9);
    let receivers: Vec<Receiver> = (0..2_000)
        .map(|i| {
            let p = sampler.point([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
            Receiver {
                position: p.position.to_array(),
                first_sender: (i / 64) * 37,
                normal: p.normal.to_array(),
                _pad: 0,
            }
        })
        .collect();
    let cssm = CssmGpu::new(&gpu.device, &gpu.queue, file, QueryOptions::default()).unwrap();
    let gpu_sums = GatherKernel::new(gpu, &cssm)
        .run(gpu, &cssm, &receivers, 64, None)
        .unwrap();
    let cpu_sums = gather_cpu(
        &VisibilityQuery::new(file, QueryOptions::default()),
        &receivers,
        64,
    );
    let worst = gpu_sums
        .iter()
        .zip(&cpu_sums)
        .map(|(g, c)| (g - c).abs())
        .fold(0.0f32, f32::max);
    let total: f32 = cpu_sums.iter().sum();
    eprintln!("gather: largest difference {worst} (sums total {total})");
    assert!(total > 1000.0, "the gather sees something");
    // Each sum has 64 terms of at most 1; allow one flipped PCF tap and float order.
    assert!(worst <= 1.0, "largest difference {worst}");
}
