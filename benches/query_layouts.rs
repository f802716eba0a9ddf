//! What each layout of the run data would cost the query (issue 48 item 2: "a query that costs
//! about one memory access"), by replay on the CPU, no GPU needed: the lean query's loads on a
//! scene's own queries with the depth lookups swapped for those of each layout, replayed as
//! warps (`runtime::work::warp`), priced by the cost model (`CostModel::H200`: **predictions**).
//!
//! ```text
//! cargo bench --bench query_layouts -- [--scene DIR] [--atlas 128] [--cube 32]
//!     [--pairs 65536] [--tile-size 640x480] [--tile-senders 32]
//! ```
//!
//! Layouts: `runs` (today's: per pixel a list of runs, a binary search a tap), `decoded` (every
//! map's depths, 2 bytes a pixel: a tap is one load), `quad runs` (per 2x2 footprint a merged
//! list whose runs hold the four depths, 16 bytes each: one search a footprint). Two patterns:
//! random pairs (the `cssm check` sampler, one thread each, 4,194,304 on the H200) and the
//! G-buffer's tiles asking spread senders (`cssm tiles` of `gpu_queries`, two-ended).

use cssm::runtime;
use runtime::{
    common::camera::View,
    visibility::tiles::{TILE_PIXELS, TileSenders, tile_pixels},
    work::cost::CostModel,
};

#[path = "common/mod.rs"]
mod common;

use common::{
    baked_scene, parsed,
    query_work::{self, Kernel, QuadRuns},
    size_arg,
};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let pairs = parsed(&args, "--pairs", 1usize << 16);
    let tile_senders = parsed(&args, "--tile-senders", 32u32);
    let (width, height) = size_arg(&args, "--tile-size", (640, 480));
    let (dir, scene, file) = baked_scene(&args);
    let n = file.params.cube_resolution;
    let texels = file.texels.len() as u32;
    let quads = QuadRuns::new(&file.runs, n);
    // The tables every layout keeps: texel records, the atlas grid, triangles' coordinates.
    let tables = runtime::work::cost::query_table_bytes(&file);
    let decoded_bytes = 2 * u64::from(file.runs.map_count) * u64::from(file.runs.pixel_count);
    let layouts = [
        ("runs", Kernel::Lean, file.runs.gpu_bytes()),
        ("decoded", Kernel::Decoded, decoded_bytes),
        ("quad runs", Kernel::QuadRuns(&quads), quads.bytes()),
    ];
    let (query_pairs, _) = runtime::visibility::random_pairs(&scene, pairs, 1);
    let (tile_list, _) = tile_pixels(&scene, &View::of_scene(&scene, width, height));
    let senders = TileSenders::spread(texels, tile_senders);
    let tile_step = (tile_list.len() / TILE_PIXELS / 64).max(1);
    let tile_threads = (tile_list.len() * tile_senders as usize) as u64;
    let model = CostModel::H200;
    println!(
        "{} at atlas {}, cube {n} ({} maps); H200 ms are the cost model's predictions\n",
        dir.display(),
        file.params.atlas_resolution,
        file.runs.map_count
    );
    println!(
        "| layout | GPU bytes | pattern | depth loads/query | loads/query | lane efficiency | sectors/warp load | H200 ms (model) |"
    );
    println!("| --- | ---: | --- | ---: | ---: | ---: | ---: | ---: |");
    for (name, kernel, bytes) in layouts {
        let data = bytes + tables;
        let random = query_work::random(&file, &query_pairs, pairs, kernel);
        let tiles = query_work::tiles(&file, &tile_list, senders, tile_step, kernel);
        for (pattern, counted, threads) in [
            ("random (4,194,304)", random, 1u64 << 22),
            ("tiles", tiles, tile_threads),
        ] {
            let q = counted.queries.max(1) as f64;
            println!(
                "| {name} | {:.1} MB | {pattern} | {:.1} | {:.1} | {:.2} | {:.2} | {:.3} |",
                bytes as f64 / 1e6,
                counted.depth_loads as f64 / q,
                counted.stats.lane_loads as f64 / q,
                counted.stats.lane_efficiency(),
                counted.stats.sectors_per_load(),
                counted.predicted_ms(&model, threads, data),
            );
        }
    }
}
