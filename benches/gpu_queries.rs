//! GPU visibility queries per second (issue: runtime core, "Speed"): CSSM queries in the access
//! pattern of a final gather and for fully random pairs, next to exact ray casting of the same
//! random pairs by a BVH traversal kernel on the same GPU, on the Cornell box and (when present)
//! the Sibenik cathedral.
//!
//! ```text
//! cargo bench --bench gpu_queries -- [--scenes DIR] [--atlas 128] [--cube 32]
//!     [--pairs 4194304] [--receivers 65536] [--senders 256] [--reps 5] [--csv FILE]
//! ```
//!
//! Times come from GPU timestamp queries (best of `--reps`). They mean something only on a real
//! GPU: on lavapipe this checks that the harness runs. Run `../shared/tools/gpu-limit` in the
//! same device call to state each figure as a fraction of the memory ceiling of the pattern
//! (`reports/runtime.sh` does both).

use std::{io::Write, path::PathBuf};

use cssm::{bake, formats, runtime};
use runtime::{
    Gpu,
    common::timestamps::PassTimer,
    load::CssmGpu,
    visibility::{QueryKernel, bvh::BvhKernel, gather::GatherKernel, gather::Receiver},
};

fn arg<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> T {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Best GPU milliseconds of `reps` runs of `work` (which records one timed pass).
fn best_ms(gpu: &Gpu, reps: u32, mut work: impl FnMut(&mut PassTimer)) -> Option<f64> {
    let mut timer = PassTimer::new(&gpu.device, &gpu.queue);
    let mut best: Option<f64> = None;
    for _ in 0..reps {
        work(&mut timer);
        let t = timer.read(&gpu.device, &gpu.queue).expect("timestamps");
        let ms: f64 = t.iter().map(|(_, ms)| ms).sum();
        if !t.is_empty() {
            best = Some(best.map_or(ms, |b: f64| b.min(ms)));
        }
    }
    best
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scenes_dir: PathBuf = arg(
        &args,
        "--scenes",
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"),
    );
    let atlas = arg(&args, "--atlas", 128u32);
    let cube = arg(&args, "--cube", 32u32);
    let pairs = arg(&args, "--pairs", 1usize << 22);
    let receivers = arg(&args, "--receivers", 1usize << 16);
    let senders = arg(&args, "--senders", 256u32);
    let reps = arg(&args, "--reps", 5u32);
    let csv: Option<PathBuf> = args
        .iter()
        .position(|a| a == "--csv")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from);

    let gpu = Gpu::new_headless().unwrap_or_else(|e| panic!("{e}"));
    println!("device: {}", gpu.describe());
    if !gpu.has_timestamps() {
        println!("this adapter has no timestamp queries: nothing to time");
        return;
    }
    let scenes = [
        (
            "cornell-box",
            cssm::builtin::cornell_box().expect("built-in scene"),
        ),
        ("sibenik", scenes_dir.join("sibenik")),
    ];
    let mut rows =
        vec!["scene,atlas,cube,maps,gpu_bytes,pattern,queries,ms,queries_per_s".to_string()];
    println!("| scene | pattern | queries | GPU ms | queries/s |\n| --- | --- | --- | --- | --- |");
    for (name, dir) in scenes {
        if !dir.is_dir() {
            println!("| {name} | skipped: {} not found | | | |", dir.display());
            continue;
        }
        let scene = formats::Scene::load(&dir).expect("scene loads");
        let options = bake::BakeOptions {
            atlas_resolution: atlas,
            cube_resolution: cube,
            ..Default::default()
        };
        let file = match bake::bake(&scene, &options, &mut |_, _| {}) {
            Ok(baked) => baked.file,
            Err(e) => {
                println!("| {name} | skipped: {e} | | | |");
                continue;
            }
        };
        let cssm =
            CssmGpu::new(&gpu.device, &gpu.queue, &file, Default::default()).expect("upload");
        let (query_pairs, segments) = runtime::visibility::random_pairs(&scene, pairs, 1);
        let query = QueryKernel::new(&gpu, &cssm);
        let bvh = BvhKernel::new(&gpu, &scene).expect("bvh");
        let gather = GatherKernel::new(&gpu, &cssm);
        let texels = file.texels.len() as u32;
        let receiver_list: Vec<Receiver> = query_pairs
            .iter()
            .take(receivers)
            .enumerate()
            .map(|(i, q)| Receiver {
                position: q.receiver,
                // 64 neighbouring receivers (one workgroup, a screen tile) share their senders.
                first_sender: ((i / 64) as u32).wrapping_mul(7919) % texels.max(1),
                normal: q.receiver_normal,
                _pad: 0,
            })
            .collect();
        let measured = [
            (
                "cssm random",
                pairs as u64,
                best_ms(&gpu, reps, |t| {
                    query
                        .run(&gpu, &cssm, &query_pairs, Some(t))
                        .expect("query");
                }),
            ),
            (
                "cssm gather",
                receiver_list.len() as u64 * senders as u64,
                best_ms(&gpu, reps, |t| {
                    gather
                        .run(&gpu, &cssm, &receiver_list, senders, Some(t))
                        .expect("gather");
                }),
            ),
            (
                "bvh random",
                pairs as u64,
                best_ms(&gpu, reps, |t| {
                    bvh.run(&gpu, &segments, Some(t)).expect("bvh");
                }),
            ),
        ];
        for (pattern, queries, ms) in measured {
            let ms = ms.unwrap_or(f64::NAN);
            let rate = queries as f64 / (ms * 1e-3);
            println!(
                "| {name} | {pattern} | {queries} | {ms:.3} | {:.3e} |",
                rate
            );
            rows.push(format!(
                "{name},{atlas},{cube},{},{},{pattern},{queries},{ms:.4},{rate:.4e}",
                file.runs.map_count, cssm.run_bytes
            ));
        }
    }
    if let Some(path) = csv {
        let mut f = std::fs::File::create(&path).expect("csv");
        writeln!(f, "{}", rows.join("\n")).expect("csv");
        println!("wrote {}", path.display());
    }
}
