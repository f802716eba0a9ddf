//! Bake speed against the paper's Table 3 (Cornell box, atlas 64x64, cube 6x64x64: 43 s on a
//! 2008 GPU), and the Sibenik cathedral at atlas 256, cube 32.
//!
//! `cargo bench --bench bake_speed [-- --scenes DIR]` (DIR defaults to ../shared/scenes, the
//! third-party meshes; rows whose scene is absent are reported as skipped). Prints a Markdown
//! table with rays per second and cube maps per second, and the machine it ran on. The whole
//! process time of one bake (start to file written) is what `cssm bake` prints; here the
//! in-process phases are timed separately.

use std::{path::PathBuf, time::Instant};

use cssm::{bake, formats};

fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    format!("{cpu}, {} threads", rayon_threads())
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scenes = args
        .iter()
        .position(|a| a == "--scenes")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"));
    let rows: Vec<(&str, PathBuf, u32, u32, Option<f64>)> = vec![
        (
            "Cornell box",
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box"),
            64,
            64,
            Some(43.0),
        ),
        ("Sibenik cathedral", scenes.join("sibenik"), 256, 32, None),
    ];
    println!("machine: {}", machine());
    println!();
    println!(
        "| scene | atlas | cube | maps | rays | load s | atlas s | maps s | total s | M rays/s | maps/s | paper s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, dir, atlas, cube, paper) in rows {
        if !dir.is_dir() {
            println!(
                "| {name} | {atlas} | {cube} | skipped: {} not found | | | | | | | | |",
                dir.display()
            );
            continue;
        }
        let t0 = Instant::now();
        let scene = formats::Scene::load(&dir).expect("scene loads");
        let load = t0.elapsed().as_secs_f64();
        let options = bake::BakeOptions {
            atlas_resolution: atlas,
            cube_resolution: cube,
            traversal: formats::Traversal::Spiral,
            ..Default::default()
        };
        let baked = bake::bake(&scene, &options, &mut |_| {}).expect("bake");
        let out = std::env::temp_dir().join(format!("cssm-bench-{}.cssm", std::process::id()));
        formats::cssm::write_atomic(&out, &baked.file).expect("write");
        let _ = std::fs::remove_file(&out);
        let total = t0.elapsed().as_secs_f64();
        let s = &baked.stats;
        let maps_s = s.maps_time.as_secs_f64();
        println!(
            "| {name} | {atlas} | {cube} | {} | {} | {load:.2} | {:.2} | {maps_s:.2} | {total:.2} | {:.1} | {:.0} | {} |",
            s.defined_texels,
            s.rays,
            s.atlas_time.as_secs_f64(),
            s.rays as f64 / maps_s / 1e6,
            s.defined_texels as f64 / maps_s,
            paper.map_or("-".to_string(), |p| format!("{p:.0}")),
        );
    }
}
