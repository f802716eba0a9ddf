//! The two renderers of the bake's depth cube maps side by side (issue 25): the BVH (one
//! traversal per pixel, the baseline) and the rasteriser (triangle by triangle), on the same
//! texels of scenes of growing triangle count: the Cornell box (36), the Cornell box with every
//! triangle split in 4, 16, 64 and 256, and the third-party teapot (6,320) and bunny (69,451) where
//! `--scenes DIR` (default ../shared/scenes) has them. Where the raster/BVH ratio crosses 1 is
//! where `--cube-renderer auto` switches (`cubemap::CubeRenderer::resolve`).
//!
//! `cargo bench --bench cube_renderer [-- --scenes DIR --cube N --threads T --max-triangles M
//! --no-bake]`. Each row renders
//! the same texels (random surface points, fixed seed) with both renderers on `T` threads (default
//! 1: per-core speed, least disturbed by other work on the machine), best of three runs each,
//! and checks that the maps are identical. Then one whole Cornell-box bake (atlas 64, cube 64,
//! every thread) with each renderer, in process. Prints Markdown tables and the machine.

use std::{path::PathBuf, time::Instant};

use cssm::{
    bake::{
        self,
        cubemap::{self, CubeRenderer, Renderer},
        raycast::{SceneBvh, SplitMix64, SurfaceSampler},
    },
    formats::{self, Scene, Texel, cube::DepthQuantizer},
};
use glam::Vec3;
use rayon::prelude::*;

fn machine(threads: usize) -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{cpu}, {cores} hardware threads, {threads} used per row")
}

/// `scene` with every triangle split into four at its edges' midpoints, `levels` times (shared
/// edges stay shared: a midpoint is computed the same way from either side).
fn subdivide(scene: &Scene, levels: u32) -> Scene {
    let mut positions = scene.positions.clone();
    let mut triangles = scene.triangles.clone();
    for _ in 0..levels {
        let mut next = Vec::with_capacity(triangles.len() * 4);
        let mut mids = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            *mids.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (positions[a.min(b) as usize], positions[a.max(b) as usize]);
                positions.push((p + q) * 0.5);
                positions.len() as u32 - 1
            })
        };
        for [a, b, c] in triangles {
            let (ab, bc, ca) = (
                mid(a, b, &mut positions),
                mid(b, c, &mut positions),
                mid(c, a, &mut positions),
            );
            next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        triangles = next;
    }
    Scene::from_triangles(positions, triangles)
}

/// `count` texels at random points of the surface (fixed seed).
fn texels(scene: &Scene, count: usize) -> Vec<Texel> {
    let sampler = SurfaceSampler::new(scene);
    let mut rng = SplitMix64(25);
    (0..count)
        .map(|_| {
            let p = sampler.point([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
            Texel {
                position: p.position.to_array(),
                normal: p.normal.to_array(),
                area: 1.0,
                material: 0,
                chart: 0,
                object: 0,
                x: 0,
                y: 0,
            }
        })
        .collect()
}

/// Best of three: seconds to render every texel's map, the rays cast, and the maps.
fn time_renderer(
    renderer: &Renderer,
    texels: &[Texel],
    n: u32,
    near: f32,
    quantizer: &DepthQuantizer,
) -> (f64, u64, Vec<cubemap::Interval>) {
    let pixels = (6 * n * n) as usize;
    let mut maps = vec![cubemap::DONT_CARE; texels.len() * pixels];
    let mut best = f64::INFINITY;
    let mut rays = 0;
    for _ in 0..3 {
        let t0 = Instant::now();
        rays = maps
            .par_chunks_mut(pixels)
            .zip(texels.par_iter())
            .map(|(out, texel)| {
                renderer.render(
                    texel,
                    n,
                    near,
                    quantizer,
                    cubemap::SecondLayer::Exchange,
                    out,
                )
            })
            .sum();
        best = best.min(t0.elapsed().as_secs_f64());
    }
    (best, rays, maps)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let flag = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let shared = flag("--scenes")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"));
    let n: u32 = flag("--cube").and_then(|s| s.parse().ok()).unwrap_or(64);
    let threads: usize = flag("--threads").and_then(|s| s.parse().ok()).unwrap_or(1);
    let max_triangles: usize = flag("--max-triangles")
        .and_then(|s| s.parse().ok())
        .unwrap_or(usize::MAX);
    let whole_bake = !args.iter().any(|a| a == "--no-bake");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("thread pool");

    let cornell_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    let cornell = Scene::load(&cornell_dir).expect("the Cornell box loads");
    let mut rows: Vec<(String, Option<Scene>)> =
        vec![("Cornell box".into(), Some(cornell.clone()))];
    for levels in 1..=4 {
        rows.push((
            format!("Cornell box, split x{}", 4u32.pow(levels)),
            Some(subdivide(&cornell, levels)),
        ));
    }
    for (name, dir) in [("teapot", "teapot"), ("bunny", "bunny")] {
        let path = shared.join(dir);
        rows.push((
            name.into(),
            path.is_dir()
                .then(|| Scene::load(&path).expect("scene loads")),
        ));
    }

    println!("machine: {}", machine(threads));
    println!();
    println!("Depth cube maps of random surface texels, cube 6x{n}x{n}, exchange layer:");
    println!();
    println!(
        "| scene | triangles | texels | BVH M rays/s | raster M rays/s | raster / BVH | auto picks | maps identical |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (name, scene) in &rows {
        let Some(scene) = scene else {
            println!(
                "| {name} | skipped: not found under {} | | | | | | |",
                shared.display()
            );
            continue;
        };
        let triangles = scene.triangles.len();
        if triangles > max_triangles {
            continue;
        }
        // Fewer texels for the big scenes, where the rasteriser clips every triangle per face.
        let count = (400_000 / triangles.max(1)).clamp(8, 400);
        let texels = texels(scene, count);
        let far = scene.diameter();
        let near = bake::DEFAULT_NEAR_FRACTION * far;
        let quantizer = DepthQuantizer::new(near, far);
        let bvh = SceneBvh::new(scene);
        let by_bvh = Renderer::new(&bvh, CubeRenderer::Bvh, Default::default());
        let by_raster = Renderer::new(&bvh, CubeRenderer::Raster, Default::default());
        let ((bvh_s, rays, bvh_maps), (raster_s, raster_rays, raster_maps)) = pool.install(|| {
            (
                time_renderer(&by_bvh, &texels, n, near, &quantizer),
                time_renderer(&by_raster, &texels, n, near, &quantizer),
            )
        });
        assert_eq!(rays, raster_rays);
        let identical = bvh_maps == raster_maps;
        println!(
            "| {name} | {triangles} | {count} | {:.2} | {:.2} | {:.2} | {} | {} |",
            rays as f64 / bvh_s / 1e6,
            rays as f64 / raster_s / 1e6,
            bvh_s / raster_s,
            CubeRenderer::Auto.resolve(triangles, n),
            if identical { "yes" } else { "NO" },
        );
    }

    if !whole_bake {
        return;
    }
    println!();
    println!(
        "Whole bake in process (Cornell box, atlas 64, cube 64, every thread, default options):"
    );
    println!();
    println!("| renderer | maps s | total s | M rays/s | file bytes |");
    println!("|---|---|---|---|---|");
    let mut files = Vec::new();
    for renderer in [CubeRenderer::Bvh, CubeRenderer::Raster] {
        let mut best: Option<(f64, f64, u64, Vec<u8>)> = None;
        for _ in 0..3 {
            let t0 = Instant::now();
            let options = bake::BakeOptions {
                atlas_resolution: 64,
                cube_resolution: 64,
                cube_renderer: renderer,
                ..Default::default()
            };
            let baked = bake::bake(&cornell, &options, &mut |_| {}).expect("bake");
            let bytes = formats::cssm::encode(&baked.file).expect("encode");
            let total = t0.elapsed().as_secs_f64();
            let maps = baked.stats.maps_time.as_secs_f64();
            if best.as_ref().is_none_or(|b| total < b.1) {
                best = Some((maps, total, baked.stats.rays, bytes));
            }
        }
        let (maps, total, rays, bytes) = best.expect("three runs");
        println!(
            "| {renderer} | {maps:.2} | {total:.2} | {:.1} | {} |",
            rays as f64 / maps / 1e6,
            bytes.len()
        );
        files.push(bytes);
    }
    println!();
    println!(
        "files identical: {}",
        if files[0] == files[1] { "yes" } else { "NO" }
    );
}
