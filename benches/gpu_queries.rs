//! GPU visibility queries per second (issue: runtime core, "Speed"): CSSM queries in the access
//! pattern of a final gather and for fully random pairs, next to exact ray casting of the same
//! random pairs by a BVH traversal kernel on the same GPU, on every scene of the report: the
//! Cornell box, and from `--scenes` (when there) the Cornell heads, the church at the paper's
//! 3,700 faces and the full Sibenik cathedral.
//!
//! ```text
//! cargo bench --bench gpu_queries -- [--scenes DIR] [--atlas 128] [--cube 32]
//!     [--pairs 4194304] [--receivers 65536] [--senders 256] [--reps 5] [--csv FILE]
//!     [--only cornell-box,heads,church3700,sibenik] [--baked NAME=FILE.cssm] [--h200 FILE]
//!     [--tile-sizes 640x480[,1280x720...]] [--tile-senders 32]
//! ```
//!
//! `cssm tiles` is the access pattern of the final gather, one query a thread (issue 48 item 4):
//! the scene's default view's G-buffer at each of `--tile-sizes` in 8x8 tiles, each tile a workgroup per
//! sender (`--tile-senders` texels spread over the scene), each thread the two-ended query
//! between its pixel and the sender (`visibility/tiles.wgsl`).
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
//! The CSSM rows come in both forms of the query's search (`CSSM_SEARCH_LOOP`): `loop`, what
//! every driver but llvmpipe runs, and `unrolled`, what llvmpipe runs (`shaders::CssmShape`).
//! Beside each, the work of one query as its CPU twin counts it on a sample of the same queries
//! (`cssm_formats::visibility::QueryWork`, which the kernel's own counters match query for
//! query in `tests/gpu/query.rs`): taps, search steps and texel loads per query, bytes read;
//! the warp replay of the sample (`runtime::work::warp`: lane efficiency, distinct 32-byte
//! sectors per warp load) and the H200 milliseconds the cost model predicts for the row's
//! launch (`runtime::work::cost::CostModel::H200`; a prediction, whatever the device).
//!
//! `--h200 FILE` (the table an earlier H200 run printed: reports/h200-2026-12-04/
//! runtime-queries.txt) adds the cost model's check: for each scene and pattern, the H200's
//! measurement of the query before the lean rewrite beside the model's prediction for that
//! kernel (its loads replayed, `Kernel::Before`) and for today's, at the H200 run's sizes.
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
    common::camera::View,
    load::CssmGpu,
    visibility::{
        QueryKernel, QueryPair,
        bvh::BvhKernel,
        gather::GatherKernel,
        gather::Receiver,
        tiles::{TILE_PIXELS, TileKernel, TileSenders, tile_pixels},
    },
};

#[path = "common/mod.rs"]
mod common;

use common::{
    best_ms, parsed as arg,
    query_work::{self, Kernel},
};
use runtime::work::cost::CostModel;

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

/// Queries the CPU twin counts and replays per row: enough for stable means, quick on the CPU.
const COUNTED_QUERIES: usize = 1 << 16;

/// The H200's figures of the query before the lean rewrite (`--h200 FILE`, the benchmark's
/// markdown table from the device: reports/h200-2026-12-04/runtime-queries.txt), by scene and
/// pattern: GPU ms.
fn h200_rows(path: &Path) -> Vec<(String, String, f64)> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .filter_map(|line| {
            let cells: Vec<&str> = line.split('|').map(str::trim).collect();
            // | scene | atlas | pattern | queries | GPU ms | queries/s |
            let ms: f64 = cells.get(5)?.parse().ok()?;
            Some((cells[1].to_string(), cells[3].to_string(), ms))
        })
        .collect()
}

/// One row of the table: pattern, queries, the CPU twin's counts (CSSM rows), threads
/// launched, GPU ms.
type Row = (String, u64, Option<query_work::Counted>, u64, Option<f64>);

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
    // The tile kernel's G-buffer sizes: several, to see its time against its launch's size.
    let tile_sizes: Vec<(u32, u32)> = common::arg(&args, "--tile-sizes")
        .unwrap_or_else(|| "640x480".into())
        .split(',')
        .map(|size| {
            size.split_once('x')
                .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
                .unwrap_or_else(|| panic!("--tile-sizes takes WIDTHxHEIGHT,..., not {size}"))
        })
        .collect();
    let tile_senders = arg(&args, "--tile-senders", 32u32);
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
    let h200: Option<PathBuf> = args
        .iter()
        .position(|a| a == "--h200")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from);
    let mut model_check = vec![
        "| scene | pattern | H200 ms measured (before the lean query) | predicted, same kernel | predicted, lean query |".to_string(),
        "| --- | --- | ---: | ---: | ---: |".to_string(),
    ];
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
        "scene,atlas,cube,maps,gpu_bytes,run_bindings,search_steps,pattern,queries,ms,queries_per_s,\
         taps_per_query,steps_per_tap,texel_loads_per_query,bytes_per_query,lane_efficiency,\
         sectors_per_load,predicted_h200_ms"
            .to_string(),
    ];
    println!(
        "| scene | atlas | pattern | queries | GPU ms | queries/s | taps/query | steps/tap | texels/query | bytes/query | lane efficiency | sectors/load | H200 ms (model) |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
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
        let mut cssm = match CssmGpu::new(&gpu.device, &gpu.queue, &file, Default::default()) {
            Ok(cssm) => cssm,
            Err(e) => {
                skipped(&e.to_string());
                continue;
            }
        };
        let (query_pairs, segments) = runtime::visibility::random_pairs(&scene, pairs, 1);
        let bvh = BvhKernel::new(&gpu, &scene).expect("bvh");
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
        // The data the queries read: run data, texel records, grid, triangles' coordinates.
        let data_bytes = cssm.run_bytes + runtime::work::cost::query_table_bytes(&file);
        let sample_receivers = (COUNTED_QUERIES / senders.max(1) as usize).max(32);
        let random = query_work::random(&file, &query_pairs, COUNTED_QUERIES, Kernel::Lean);
        let gathered = query_work::gather(
            &file,
            &receiver_list,
            senders,
            sample_receivers,
            Kernel::Lean,
        );
        let model = CostModel::H200;
        if let Some(path) = &h200 {
            let before_random =
                query_work::random(&file, &query_pairs, COUNTED_QUERIES, Kernel::Before);
            let before_gather = query_work::gather(
                &file,
                &receiver_list,
                senders,
                sample_receivers,
                Kernel::Before,
            );
            // The H200 ran 4,194,304 pairs and 65,536 receivers x 256 senders.
            for (pattern, before, lean, threads) in [
                ("cssm random", before_random, random, 1u64 << 22),
                ("cssm gather", before_gather, gathered, 1u64 << 16),
            ] {
                let scale = if pattern == "cssm gather" {
                    256.0 / senders as f64
                } else {
                    1.0
                };
                let measured = h200_rows(path)
                    .into_iter()
                    .find(|(s, p, _)| s == name && p == pattern)
                    .map_or("-".to_string(), |(_, _, ms)| format!("{ms:.3}"));
                model_check.push(format!(
                    "| {name} | {pattern} | {measured} | {:.3} | {:.3} |",
                    scale * before.predicted_ms(&model, threads, data_bytes),
                    scale * lean.predicted_ms(&model, threads, data_bytes)
                ));
            }
        }
        let mut measured: Vec<Row> = Vec::new();
        // The G-buffer's tiles at each size and the senders they ask; the CPU replays every
        // step-th tile (about 64 of them). A size whose answers exceed one storage binding of
        // the adapter is skipped.
        let tile_queries = TileSenders::spread(texels, tile_senders);
        let tile_runs: Vec<_> = tile_sizes
            .iter()
            .filter_map(|&(w, h)| {
                let (list, tiles_x) = tile_pixels(&scene, &View::of_scene(&scene, w, h));
                let threads = (list.len() * tile_senders as usize) as u64;
                if 4 * threads > binding {
                    println!("(tiles {w}x{h}: {threads} answers exceed one storage binding)");
                    return None;
                }
                let seen = list.iter().filter(|p| p.triangle != u32::MAX).count() as u64;
                let step = (list.len() / TILE_PIXELS / 64).max(1);
                let counted = query_work::tiles(&file, &list, tile_queries, step, Kernel::Lean);
                Some((format!("{w}x{h}"), list, tiles_x, threads, seen, counted))
            })
            .collect();
        // Both forms of the search: llvmpipe's loop limit is far off for these kernels (at
        // most 16 taps x 16 steps a random query, 4 x 16 a gather's sender).
        for (form, search_loop) in [("loop", true), ("unrolled", false)] {
            cssm.search_loop = search_loop;
            let query = QueryKernel::new(&gpu, &cssm);
            let gather = GatherKernel::new(&gpu, &cssm);
            measured.push((
                format!("cssm random ({form})"),
                pairs as u64,
                Some(random),
                pairs as u64,
                best_ms(&gpu, reps, |t| {
                    query
                        .run(&gpu, &cssm, &query_pairs, Some(t))
                        .expect("query");
                }),
            ));
            let tile_kernel = TileKernel::new(&gpu, &cssm, false);
            for (size, list, tiles_x, threads, seen, counted) in &tile_runs {
                measured.push((
                    format!("cssm tiles {size} ({form})"),
                    seen * tile_senders as u64,
                    Some(*counted),
                    *threads,
                    best_ms(&gpu, reps, |t| {
                        tile_kernel
                            .run(&gpu, &cssm, list, *tiles_x, tile_queries, Some(t))
                            .expect("tiles");
                    }),
                ));
            }
            measured.push((
                format!("cssm gather ({form})"),
                receiver_list.len() as u64 * senders as u64,
                Some(gathered),
                receiver_list.len() as u64,
                best_ms(&gpu, reps, |t| {
                    gather
                        .run(&gpu, &cssm, &receiver_list, senders, Some(t))
                        .expect("gather");
                }),
            ));
        }
        measured.push((
            "bvh random".to_string(),
            pairs as u64,
            None,
            pairs as u64,
            best_ms(&gpu, reps, |t| {
                bvh.run(&gpu, &segments, Some(t)).expect("bvh");
            }),
        ));
        for (pattern, queries, counted, threads, ms) in measured {
            let ms = ms.unwrap_or(f64::NAN);
            let rate = queries as f64 / (ms * 1e-3);
            let per = |value: u64, over: usize| value as f64 / over.max(1) as f64;
            let [
                taps,
                steps,
                texel_loads,
                bytes,
                efficiency,
                sectors,
                predicted,
            ] = match counted {
                Some(c) => {
                    let w = c.work;
                    [
                        per(w.taps, c.queries),
                        per(w.search_steps, w.taps as usize),
                        per(w.texel_loads, c.queries),
                        per(w.bytes(), c.queries),
                        c.stats.lane_efficiency(),
                        c.stats.sectors_per_load(),
                        c.predicted_ms(&model, threads, data_bytes),
                    ]
                }
                None => [f64::NAN; 7],
            };
            println!(
                "| {name} | {atlas} | {pattern} | {queries} | {ms:.3} | {rate:.3e} | {taps:.2} | {steps:.2} | {texel_loads:.2} | {bytes:.0} | {efficiency:.2} | {sectors:.2} | {predicted:.3} |"
            );
            rows.push(format!(
                "{name},{atlas},{cube},{},{},{},{},{pattern},{queries},{ms:.4},{rate:.4e},\
                 {taps:.4},{steps:.4},{texel_loads:.4},{bytes:.1},{efficiency:.4},{sectors:.3},\
                 {predicted:.4}",
                file.runs.map_count, cssm.run_bytes, cssm.run_bindings, cssm.search_steps
            ));
        }
    }
    if h200.is_some() {
        println!(
            "\nThe cost model ({}) against the H200's measurements of the query before the lean \
             rewrite, at this run's sizes scaled to the H200 run's (4,194,304 pairs, 65,536 \
             receivers x 256 senders); predictions, not measurements:\n{}",
            CostModel::H200.device,
            model_check.join("\n")
        );
    }
    if let Some(path) = csv {
        let mut f = std::fs::File::create(&path).expect("csv");
        writeln!(f, "{}", rows.join("\n")).expect("csv");
        println!("wrote {}", path.display());
    }
}
