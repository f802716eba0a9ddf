//! The visibility kernels against the CPU reference query and exact ray casts: batch queries
//! over random pairs, the gather and segment kernels, runs over several bindings, and the
//! errors a bad file or shader gives.

use super::*;

pub(crate) fn random_pairs(scene: &Scene, count: usize, seed: u64) -> Vec<QueryPair> {
    cssm_runtime::visibility::random_pairs(scene, count, seed).0
}

/// GPU and CPU answers to the same pairs: (pairs compared, decisions that differ, largest
/// difference of the visible fraction).
fn compare(options: QueryOptions, count: usize, seed: u64) -> (usize, usize, f32) {
    compare_on(cornell(), options, count, seed)
}

/// [`compare`] on the baked `scene` and `file`.
fn compare_on(
    (scene, file): &(Scene, CssmFile),
    options: QueryOptions,
    count: usize,
    seed: u64,
) -> (usize, usize, f32) {
    let gpu = gpu();
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

/// The query on staggered pixel grids (`PixelGrid::Staggered`, in the default turned cube frame)
/// and on the paper's layout (centred grids, faces on the world's axes, `CubeFrame::World`):
/// each texel's lookups shift with its grid and turn with its frame on the GPU as on the CPU.
#[test]
fn gpu_matches_cpu_on_staggered_grids_and_in_either_frame() {
    use cssm_formats::cube::{CubeFrame, PixelGrid};
    for (pixel_grid, cube_frame) in [
        (PixelGrid::Staggered, CubeFrame::Turned),
        (PixelGrid::Centred, CubeFrame::World),
    ] {
        let file = baked(
            "cornell-box",
            BakeOptions {
                atlas_resolution: 64,
                cube_resolution: 16,
                pixel_grid,
                cube_frame,
                ..Default::default()
            },
        );
        assert_eq!(
            (file.1.pixel_grid, file.1.cube_frame),
            (pixel_grid, cube_frame)
        );
        let unfiltered = QueryOptions {
            pcf: false,
            sender_filter: false,
            both_ends: false,
            ..Default::default()
        };
        for (options, count) in [(QueryOptions::default(), 50_000), (unfiltered, 20_000)] {
            let (n, differ, worst) = compare_on(&file, options, count, 13);
            eprintln!(
                "{pixel_grid}, {cube_frame}: {differ} of {n} differ, largest difference {worst}"
            );
            assert!(differ as f64 <= 1e-4 * n as f64, "{differ} of {n} differ");
        }
    }
}

#[test]
fn gpu_matches_cpu_without_filtering() {
    let options = QueryOptions {
        pcf: false,
        sender_filter: false,
        both_ends: false,
        bias_near: 1.0,
        bias_relative: 0.001,
    };
    let (n, differ, worst) = compare(options, 20_000, 11);
    eprintln!("unfiltered: {differ} of {n} differ, largest difference {worst}");
    assert!(differ as f64 <= 1e-4 * n as f64, "{differ} of {n} differ");
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
    let glossy_dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-glossy");
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
    let bvh = cssm_raycast::SceneBvh::new(scene);
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

/// A `.cssm` whose runs exceed one storage binding loads with them spread over several, and
/// every pass that queries it answers exactly as with one binding: the query and gather
/// kernels on the same pairs, and the images of `lightmap` (the radiosity gather and the atlas
/// lookup; `hrc` has the same passes) and `lightcuts` (the final gather). The binding limit is
/// lowered on a device of its own so that the Cornell box's runs need three bindings (the
/// Sibenik cathedral at atlas 256 needs two at WebGPU's default 128 MiB).
#[test]
fn runs_spread_over_several_bindings_answer_as_one() {
    use cssm_runtime::{
        load::MAX_RUN_BINDINGS,
        radiosity::HierarchyGpu,
        visibility::gather::{GatherKernel, Receiver},
    };
    let whole = gpu();
    let (scene, file) = cornell();
    let options = QueryOptions::default();
    let one = CssmGpu::new(&whole.device, &whole.queue, file, options).unwrap();
    assert_eq!(one.run_bindings, 1);
    let hierarchy = HierarchyGpu::new(&whole.device, &file.hierarchy, &file.texels, &[]).unwrap();
    let run_bytes = 4 * file.runs.runs.len() as u64;
    // Every other buffer still fits one binding; the runs need three.
    let largest_other = [
        &one.texels,
        &one.grid,
        &one.triangle_uvs,
        &one.offsets,
        &hierarchy.nodes,
        &hierarchy.leaves,
        &hierarchy.pull_order,
    ]
    .iter()
    .map(|b| b.size())
    .max()
    .unwrap();
    let limit = largest_other.max(run_bytes.div_ceil(3)).next_multiple_of(4);
    eprintln!(
        "runs {run_bytes} bytes, largest other buffer {largest_other}, binding limit {limit}"
    );
    let lowered = |limit: u64| {
        let adapter = &whole.adapter;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("lowered binding limit"),
            required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
            required_limits: wgpu::Limits {
                max_storage_buffer_binding_size: limit,
                ..adapter.limits()
            },
            ..Default::default()
        }))
        .expect("a device with a lowered binding limit");
        Gpu::from_device(adapter.clone(), device, queue)
    };
    let split_gpu = lowered(limit);
    let split = CssmGpu::new(&split_gpu.device, &split_gpu.queue, file, options).unwrap();
    assert!(
        (2..=3).contains(&split.run_bindings),
        "{} bindings",
        split.run_bindings
    );
    assert_eq!(split.runs.len(), split.run_bindings as usize);
    assert!(split.runs.iter().all(|b| b.size() <= limit));

    // As many pairs as one binding of the lowered limit holds (at most 10,000).
    let fit = (limit / std::mem::size_of::<QueryPair>() as u64).min(10_000);
    let pairs = random_pairs(scene, fit as usize, 23);
    let answers = |gpu: &Gpu, cssm: &CssmGpu| {
        QueryKernel::new(gpu, cssm)
            .run(gpu, cssm, &pairs, None)
            .unwrap()
    };
    let (expected, got) = (answers(whole, &one), answers(&split_gpu, &split));
    assert!(expected.iter().any(|&v| v > 0.0) && expected.contains(&0.0));
    assert_eq!(got, expected, "the query over split runs differs");

    let receivers: Vec<Receiver> = pairs
        .iter()
        .take(2_000)
        .enumerate()
        .map(|(i, q)| Receiver {
            position: q.receiver,
            first_sender: (i as u32 / 64) * 37,
            normal: q.receiver_normal,
            _pad: 0,
        })
        .collect();
    let sums = |gpu: &Gpu, cssm: &CssmGpu| {
        GatherKernel::new(gpu, cssm)
            .run(gpu, cssm, &receivers, 64, None)
            .unwrap()
    };
    assert_eq!(sums(&split_gpu, &split), sums(whole, &one));

    let render_options = RenderOptions {
        width: 32,
        height: 24,
        ..Default::default()
    };
    for method in ["lightmap", "lightcuts"] {
        let expected = render(whole, scene, Some(file), method, &render_options).unwrap();
        let got = render(&split_gpu, scene, Some(file), method, &render_options)
            .unwrap_or_else(|e| panic!("{method} over split runs: {e}"));
        assert!(expected.display.iter().any(|&b| b > 0), "{method}: black");
        assert_eq!(
            got.display, expected.display,
            "{method} over split runs differs"
        );
    }

    // Runs beyond MAX_RUN_BINDINGS bindings: a clear error, not a validation error (the runs
    // are checked before the other tables).
    let tiny_limit = run_bytes
        .div_ceil(u64::from(MAX_RUN_BINDINGS) + 2)
        .next_multiple_of(4);
    let tiny = lowered(tiny_limit);
    let refused = CssmGpu::new(&tiny.device, &tiny.queue, file, options).err();
    let message = refused.map(|e| e.to_string()).unwrap_or_default();
    assert!(
        message.contains("more than 8 storage bindings"),
        "{message}"
    );
}
