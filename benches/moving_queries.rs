//! GPU query throughput with moving rigid objects (issue 21, "Speed"; §3.3): random surface
//! pairs answered by `moving_visibility_between` (each end's own maps in its baked frame, then
//! the coherent shadow map of every rigid object the pair does not lie on) with one, two and four
//! moving objects, against the static single-CSSM query over the same geometry baked as one
//! static scene, all measured in one run. The baseline is the static query between two surface
//! points as the renderer asks it (both ends' maps); the sender's end alone
//! (`visibility/query.wgsl`, what `gpu_queries` times) is the row beside it.
//!
//! ```text
//! cargo bench --bench moving_queries -- [--atlas 64] [--cube 16] [--pairs 4194304]
//!     [--objects 1,2,4] [--reps 5] [--csv FILE]
//! ```
//!
//! The scene: the built-in Cornell box with four 60 mm blocks in the air, of which the first K
//! are rigid `[[objects]]` (each with its own CSSM and CSM) and the rest part of the static mesh,
//! so every row queries the same geometry. Times come from GPU timestamp queries (best of
//! `--reps`); they mean something only on a real GPU (on lavapipe this checks that the harness
//! runs; the ratios there are a CPU's).

use std::{io::Write, path::Path};

use cssm::{bake, formats, raycast, runtime};
use formats::{Scene, scene::SceneObject, visibility::QueryOptions};
use runtime::{
    Gpu,
    load::CssmGpu,
    visibility::{
        QueryKernel,
        moving::{MovingEnd, MovingGpu, MovingPair, MovingQueryKernel},
    },
};

#[path = "common/mod.rs"]
mod common;

use common::{best_ms, parsed as arg};

/// Where the four blocks stand (corner, mm), clear of the box's own blocks and of each other.
const BLOCKS: [[f32; 3]; 4] = [
    [100.0, 400.0, 100.0],
    [400.0, 400.0, 400.0],
    [100.0, 200.0, 420.0],
    [420.0, 200.0, 100.0],
];

/// The Cornell box with the four blocks, the first `rigid` of them `[[objects]]`, in `dir`.
fn scene_with(dir: &Path, rigid: usize) -> Scene {
    let box_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    std::fs::copy(box_dir.join("cornell-box.mtl"), dir.join("cornell-box.mtl"))
        .expect("copy the box's materials");
    let mut static_obj =
        std::fs::read_to_string(box_dir.join("cornell-box.obj")).expect("read the box");
    let mut vertices = static_obj.lines().filter(|l| l.starts_with("v ")).count();
    static_obj += "\nusemtl white\n";
    let mut toml = String::from(
        "name = \"blocks\"\nmesh = \"static.obj\"\n\n[[lights]]\ntype = \"spot\"\n\
         position = [278.0, 540.0, 279.5]\ndirection = [0.0, -1.0, 0.0]\ncutoff_deg = 60.0\n\
         intensity = [500000.0, 500000.0, 500000.0]\n",
    );
    for (i, at) in BLOCKS.iter().enumerate() {
        if i < rigid {
            let name = format!("block{i}");
            let obj = format!(
                "mtllib cornell-box.mtl\nusemtl white\n{}",
                cssm::builtin::cube_obj(*at, 60.0, 0, false)
            );
            std::fs::write(dir.join(format!("{name}.obj")), obj).expect("write a block");
            toml += &format!("\n[[objects]]\nname = \"{name}\"\nmesh = \"{name}.obj\"\n");
        } else {
            static_obj += &cssm::builtin::cube_obj(*at, 60.0, vertices, false);
            vertices += 8;
        }
    }
    std::fs::write(dir.join("static.obj"), static_obj).expect("write the static mesh");
    std::fs::write(dir.join("scene.toml"), toml).expect("write scene.toml");
    Scene::load(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
}

/// `count` random pairs of surface points of `scene` where it was loaded, each end with its
/// object (seed 1).
fn moving_pairs(scene: &Scene, count: usize) -> Vec<MovingPair> {
    let sampler = raycast::SurfaceSampler::new(scene);
    let mut rng = raycast::SplitMix64(1);
    let end = |s: raycast::SurfacePoint| {
        MovingEnd::new(
            s.triangle as u32,
            s.bary,
            s.position,
            s.normal,
            scene.object_of(s.triangle) as u32,
        )
    };
    (0..count)
        .map(|_| {
            let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
            MovingPair {
                a: end(sampler.point(r())),
                b: end(sampler.point(r())),
            }
        })
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let atlas = arg(&args, "--atlas", 64u32);
    let cube = arg(&args, "--cube", 16u32);
    let asked_pairs = arg(&args, "--pairs", 1usize << 22);
    let reps = arg(&args, "--reps", 5u32);
    let objects: Vec<usize> = arg(&args, "--objects", "1,2,4".to_string())
        .split(',')
        .map(|k| k.parse().expect("--objects: counts such as 1,2,4"))
        .filter(|&k| k <= BLOCKS.len())
        .collect();
    let csv = args
        .iter()
        .position(|a| a == "--csv")
        .and_then(|i| args.get(i + 1))
        .map(std::path::PathBuf::from);

    let gpu = Gpu::new_headless().unwrap_or_else(|e| panic!("{e}"));
    println!("device: {}", gpu.describe());
    if !gpu.has_timestamps() {
        println!("this adapter has no timestamp queries: nothing to time");
        return;
    }
    let binding = runtime::load::storage_binding_bytes(&gpu.device.limits());
    let most = (binding / size_of::<MovingPair>() as u64) as usize;
    let pairs = asked_pairs.min(most);
    if pairs < asked_pairs {
        println!("(pairs: {asked_pairs} asked, {most} fit one storage binding of {binding} bytes)");
    }
    let options = bake::BakeOptions {
        atlas_resolution: atlas,
        cube_resolution: cube,
        ..Default::default()
    };
    let work = tempfile::tempdir().expect("a temporary directory");
    let mut rows = vec!["rigid_objects,atlas,cube,queries,ms,queries_per_s,ratio".to_string()];
    println!(
        "| moving objects | query | pairs | GPU ms | queries/s | against static |\n\
         | --- | --- | --- | --- | --- | --- |"
    );

    // The baseline: the same geometry, every block static, one CSSM (the static query).
    let dir = work.path().join("static");
    std::fs::create_dir_all(&dir).expect("a scene folder");
    let mut scene = scene_with(&dir, 0);
    scene.objects = vec![SceneObject::whole_static(scene.triangles.len())];
    let file = bake::bake(&scene, &options, &mut |_| {})
        .expect("bake the static scene")
        .file;
    let cssm = CssmGpu::new(&gpu.device, &gpu.queue, &file, QueryOptions::default())
        .expect("upload the static CSSM");
    let (query_pairs, _) = runtime::visibility::random_pairs(&scene, pairs, 1);
    let query = QueryKernel::new(&gpu, &cssm);
    let one_end = best_ms(&gpu, reps, |t| {
        let _: Vec<_> = query
            .run(&gpu, &cssm, &query_pairs, Some(t))
            .expect("static query");
    })
    .unwrap_or(f64::NAN);
    // The baseline: the renderer's static query between two surface points (both ends' maps,
    // `cssm_visibility_between`), which is what the moving objects' kernel composes to without
    // CSMs; the same pairs as the rows below.
    let scene_gpu = runtime::load::SceneGpu::new(&gpu.device, &gpu.queue, &scene, Some(&file))
        .expect("upload the scene");
    let static_moving =
        MovingGpu::new(&gpu.device, &file, &scene, &scene_gpu.motion).expect("no CSMs to upload");
    let static_kernel = MovingQueryKernel::new(&gpu, &cssm, &static_moving);
    let static_pairs = moving_pairs(&scene, pairs);
    let baseline = best_ms(&gpu, reps, |t| {
        let _: Vec<_> = static_kernel
            .run(&gpu, &cssm, &static_moving, &static_pairs, Some(t))
            .expect("static query between two points");
    })
    .unwrap_or(f64::NAN);
    let rate = |ms: f64| pairs as f64 / (ms * 1e-3);
    for (label, ms) in [
        ("static CSSM, sender's end only", one_end),
        ("static CSSM, both ends (baseline)", baseline),
    ] {
        println!(
            "| 0 | {label} | {pairs} | {ms:.3} | {:.3e} | {:.2} |",
            rate(ms),
            baseline / ms
        );
        rows.push(format!(
            "0,{atlas},{cube},{pairs},{ms:.4},{:.4e},{:.4}",
            rate(ms),
            baseline / ms
        ));
    }

    for &k in &objects {
        let dir = work.path().join(format!("moving{k}"));
        std::fs::create_dir_all(&dir).expect("a scene folder");
        let scene = scene_with(&dir, k);
        let file = bake::bake(&scene, &options, &mut |_| {})
            .expect("bake the scene with moving objects")
            .file;
        let cssm = CssmGpu::new(&gpu.device, &gpu.queue, &file, QueryOptions::default())
            .expect("upload the CSSM");
        let scene_gpu = runtime::load::SceneGpu::new(&gpu.device, &gpu.queue, &scene, Some(&file))
            .expect("upload the scene");
        let moving =
            MovingGpu::new(&gpu.device, &file, &scene, &scene_gpu.motion).expect("upload the CSMs");
        let kernel = MovingQueryKernel::new(&gpu, &cssm, &moving);
        let moving_pairs = moving_pairs(&scene, pairs);
        let ms = best_ms(&gpu, reps, |t| {
            let _: Vec<_> = kernel
                .run(&gpu, &cssm, &moving, &moving_pairs, Some(t))
                .expect("moving query");
        })
        .unwrap_or(f64::NAN);
        println!(
            "| {k} | own CSSMs + {k} CSM(s) | {pairs} | {ms:.3} | {:.3e} | {:.2} |",
            rate(ms),
            baseline / ms
        );
        rows.push(format!(
            "{k},{atlas},{cube},{pairs},{ms:.4},{:.4e},{:.4}",
            rate(ms),
            baseline / ms
        ));
    }
    println!("(against static: the static query's time over this row's; below 1 is slower)");
    if let Some(path) = csv {
        let mut f = std::fs::File::create(&path).expect("csv");
        writeln!(f, "{}", rows.join("\n")).expect("csv");
        println!("wrote {}", path.display());
    }
}
