//! GPU visibility queries per second (issue: runtime core, "Speed"): CSSM queries in the access
//! pattern of a final gather and for fully random pairs, next to exact ray casting of the same
//! random pairs by a BVH traversal kernel on the same GPU, on every scene of the report: the
//! Cornell box, and from `--scenes` (when there) the Cornell heads, the church at the paper's
//! 3,700 faces and the full Sibenik cathedral.
//!
//! ```text
//! cargo bench --bench gpu_queries -- [--scenes DIR] [--atlas 128] [--cube 32]
//!     [--pairs 4194304] [--receivers 65536] [--senders 256] [--reps 5] [--csv FILE]
//!     [--only cornell-box,heads,church3700,sibenik] [--baked NAME=FILE.cssm]
//! ```
//!
//! `--baked NAME=FILE` takes scene NAME's bake from FILE instead of baking it here (the device
//! harness bakes the full Sibenik cathedral in a step of its own, which the queries step's time
//! limit did not leave room for).
//!
//! Each scene bakes at `--atlas`, or at the next power of two that holds its charts (the
//! Sibenik cathedral's 6,913 charts need 256); the row names the atlas used and how many
//! storage bindings its runs span. The pair and receiver counts are cut to what one storage
//! binding of the adapter holds (the row says so), so the harness runs on any device.
//!
//! Times come from GPU timestamp queries (best of `--reps`). They mean something only on a real
//! GPU: on lavapipe this checks that the harness runs. Run `../shared/tools/gpu-limit` in the
//! same device call to state each figure as a fraction of the memory ceiling of the pattern
//! (`reports/runtime.sh` does both).

use std::{
    io::Write,
    path::{Path, PathBuf},
};

use cssm::{bake, formats, report, runtime};
use runtime::{
    Gpu,
    load::CssmGpu,
    visibility::{QueryKernel, QueryPair, bvh::BvhKernel, gather::GatherKernel, gather::Receiver},
};

#[path = "common/mod.rs"]
mod common;

use common::{best_ms, parsed as arg};

/// The largest atlas a scene is tried at before its rows are skipped.
const LARGEST_ATLAS: u32 = 1024;

/// The scenes of the report that exist here: the built-in Cornell box, then from `scenes` the
/// Cornell heads (teapot and bunny), the church simplified to 3,700 faces and the full Sibenik
/// cathedral; a missing one is a row saying why.
fn scenes(scenes_dir: &Path, work: &Path) -> Vec<(&'static str, Result<PathBuf, String>)> {
    let cornell = cssm::builtin::cornell_box().expect("built-in scene");
    let sibenik = scenes_dir.join("sibenik");
    let missing = |p: &Path| format!("{} not found", p.display());
    let parts = ["teapot", "bunny"].map(|s| scenes_dir.join(s));
    let heads = match parts.iter().find(|p| !p.is_dir()) {
        Some(absent) => Err(missing(absent)),
        None => report::heads::build(&cornell, scenes_dir, &work.join("heads")).map(|h| h.dir),
    };
    let (church, full) = if sibenik.is_dir() {
        (
            report::church::build(&sibenik, &work.join("church3700")).map(|c| c.dir),
            Ok(sibenik),
        )
    } else {
        (Err(missing(&sibenik)), Err(missing(&sibenik)))
    };
    vec![
        ("cornell-box", Ok(cornell)),
        ("heads", heads),
        ("church3700", church),
        ("sibenik", full),
    ]
}

/// Bakes `scene` at `atlas`, doubling it while the charts do not fit: the file and its atlas.
fn bake_fitting(
    scene: &formats::Scene,
    atlas: u32,
    cube: u32,
) -> Result<(formats::CssmFile, u32), String> {
    let mut atlas = atlas;
    loop {
        let options = bake::BakeOptions {
            atlas_resolution: atlas,
            cube_resolution: cube,
            ..Default::default()
        };
        match bake::bake(scene, &options, &mut |_| {}) {
            Ok(baked) => return Ok((baked.file, atlas)),
            Err(bake::BakeError::Atlas(e))
                if e.contains("could not fit") && atlas < LARGEST_ATLAS =>
            {
                println!(
                    "({}: charts do not fit atlas {atlas}; trying {})",
                    scene.name,
                    2 * atlas
                );
                atlas *= 2;
            }
            Err(e) => return Err(e.to_string()),
        }
    }
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
    let asked_pairs = arg(&args, "--pairs", 1usize << 22);
    let asked_receivers = arg(&args, "--receivers", 1usize << 16);
    let senders = arg(&args, "--senders", 256u32);
    let reps = arg(&args, "--reps", 5u32);
    let only: Option<String> = args
        .iter()
        .position(|a| a == "--only")
        .and_then(|i| args.get(i + 1))
        .cloned();
    let baked: Option<(String, PathBuf)> = args
        .iter()
        .position(|a| a == "--baked")
        .and_then(|i| args.get(i + 1))
        .map(|v| match v.split_once('=') {
            Some((name, file)) => (name.to_string(), PathBuf::from(file)),
            None => panic!("--baked takes NAME=FILE, not {v}"),
        });
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
    // One storage binding holds the pairs (the largest item per query); so many and no more.
    let binding = cssm::runtime::load::storage_binding_bytes(&gpu.device.limits());
    let fits = |asked: usize, item: usize, what: &str| {
        let most = (binding / item as u64) as usize;
        if asked > most {
            println!(
                "({what}: {asked} asked, {most} fit one storage binding of {binding} bytes: {most})"
            );
        }
        asked.min(most)
    };
    let pairs = fits(asked_pairs, size_of::<QueryPair>(), "pairs");
    let receivers = fits(asked_receivers, size_of::<Receiver>(), "receivers");
    let work = tempfile::tempdir().expect("a temporary directory");
    let mut rows = vec![
        "scene,atlas,cube,maps,gpu_bytes,run_bindings,pattern,queries,ms,queries_per_s".to_string(),
    ];
    println!(
        "| scene | atlas | pattern | queries | GPU ms | queries/s |\n| --- | --- | --- | --- | --- | --- |"
    );
    for (name, dir) in scenes(&scenes_dir, work.path()) {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|n| n == name))
        {
            continue;
        }
        let skipped = |why: &str| println!("| {name} | | skipped: {why} | | | |");
        let dir = match dir {
            Ok(dir) => dir,
            Err(why) => {
                skipped(&why);
                continue;
            }
        };
        let scene = formats::Scene::load(&dir).expect("scene loads");
        let given = baked.as_ref().filter(|(n, _)| n == name);
        let bake = match given {
            Some((_, path)) => formats::cssm::read(path)
                .map(|file| {
                    let atlas = file.params.atlas_resolution;
                    (file, atlas)
                })
                .map_err(|e| format!("{}: {e}", path.display())),
            None => bake_fitting(&scene, atlas, cube),
        };
        let (file, atlas) = match bake {
            Ok(baked) => baked,
            Err(e) => {
                skipped(&e);
                continue;
            }
        };
        let cube = file.params.cube_resolution;
        let cssm = match CssmGpu::new(&gpu.device, &gpu.queue, &file, Default::default()) {
            Ok(cssm) => cssm,
            Err(e) => {
                skipped(&e.to_string());
                continue;
            }
        };
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
                "| {name} | {atlas} | {pattern} | {queries} | {ms:.3} | {:.3e} |",
                rate
            );
            rows.push(format!(
                "{name},{atlas},{cube},{},{},{},{pattern},{queries},{ms:.4},{rate:.4e}",
                file.runs.map_count, cssm.run_bytes, cssm.run_bindings
            ));
        }
    }
    if let Some(path) = csv {
        let mut f = std::fs::File::create(&path).expect("csv");
        writeln!(f, "{}", rows.join("\n")).expect("csv");
        println!("wrote {}", path.display());
    }
}
