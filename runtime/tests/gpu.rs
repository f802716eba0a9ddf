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
            near: None,
        };
        let baked = cssm_bake::bake(&scene, &options, &mut |_, _| {}).expect("bake");
        (scene, baked.file)
    })
}

/// `count` random sender/receiver pairs on the surface, area-uniform (seeded).
fn random_pairs(scene: &Scene, count: usize, seed: u64) -> Vec<QueryPair> {
    let sampler = SurfaceSampler::new(scene);
    let mut rng = SplitMix64(seed);
    (0..count)
        .map(|_| {
            let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
            let sender = sampler.point(r());
            let receiver = sampler.point(r());
            QueryPair::new(
                sender.triangle as u32,
                sender.bary,
                receiver.position,
                Some(receiver.normal),
            )
        })
        .collect()
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
