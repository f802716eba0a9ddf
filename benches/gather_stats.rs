//! The final gather's work counted by its CPU twin (`runtime::work::passes`, what `cssm render
//! --stats` prints) without rendering a frame: the radiosity's node radiance on the device
//! (lavapipe is fine), then the twin's walk over a sample of the gather's tiles, and the cost
//! model's H200 milliseconds (**predictions**).
//!
//! ```text
//! cargo bench --bench gather_stats -- [--scene DIR] [--atlas 128] [--cube 32]
//!     [--size 640x480] [--downsample 1] [--bounces 1] [--threshold 0.02] [--tiles 16]
//!     [--gather atlas|walk] [--near 4] [--emitters pixel|far]
//! ```
//!
//! `--gather` is `lightcuts`' option of that name (the default `atlas`: the far field looked up,
//! the near field within `--near` texel sizes gathered per pixel; `walk`: the whole hierarchy
//! per pixel). With `atlas` it also counts the far-field pass over the atlas's texels;
//! `--emitters` is the option of that name (`pixel`: every pixel gathers the emitters' light).

use cssm::runtime;
use runtime::{
    common::camera::View,
    lightcuts::cpu::TwinGather,
    radiosity,
    work::passes::{final_gather_stats, radiosity_gather_stats},
};

#[path = "common/mod.rs"]
mod common;

use common::{baked_scene, parsed, size_arg};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let downsample = parsed(&args, "--downsample", 1u32);
    let bounces = parsed(&args, "--bounces", 1u32);
    let threshold = parsed(&args, "--threshold", radiosity::DEFAULT_THRESHOLD);
    let tiles = parsed(&args, "--tiles", 16u32);
    let walk = match parsed(&args, "--gather", "atlas".to_string()).as_str() {
        "walk" => true,
        "atlas" => false,
        other => panic!("--gather {other}: atlas or walk"),
    };
    let near = parsed(&args, "--near", 4.0f32);
    let emitters_apart = match parsed(&args, "--emitters", "pixel".to_string()).as_str() {
        "pixel" => true,
        "far" => false,
        other => panic!("--emitters {other}: pixel or far"),
    };
    let (width, height) = size_arg(&args, "--size", (640, 480));
    let (dir, scene, file) = baked_scene(&args);
    let gpu = runtime::Gpu::new_headless().unwrap_or_else(|e| panic!("{e}"));
    // The renderer's exposure at 0 stops, and its default shadow maps.
    let exposure = 1.0;
    let solved = radiosity::atlas_radiosity(
        &gpu.device,
        &gpu.queue,
        &scene,
        &file,
        runtime::common::shadow_map::DEFAULT_RESOLUTION,
        bounces.saturating_sub(1),
        radiosity::RadiosityOptions {
            threshold,
            exposure,
        },
    )
    .unwrap_or_else(|e| panic!("radiosity: {e}"));
    let radiance: Vec<glam::Vec3> = solved
        .node_radiance
        .iter()
        .map(|r| glam::Vec3::new(r[0], r[1], r[2]))
        .collect();
    let view = View::of_scene(&scene, width, height);
    let near_radius = runtime::lightcuts::near_radius(&file.hierarchy, near);
    // The counts do not depend on the far field's values, only on where pixels look it up.
    let far = vec![glam::Vec3::ZERO; file.texels.len()];
    let lists = runtime::lightcuts::near_lists(&file, near);
    if let Some(lists) = &lists {
        let empty = lists.offsets.windows(2).filter(|w| w[0] == w[1]).count();
        println!(
            "near lists: {} leaves over {} texels ({:.1} a texel, {:.0}% empty), {:.2} MB",
            lists.leaves.len(),
            file.texels.len(),
            lists.leaves.len() as f64 / file.texels.len().max(1) as f64,
            100.0 * empty as f64 / file.texels.len().max(1) as f64,
            lists.bytes() as f64 / 1e6
        );
    }
    let form = if walk {
        TwinGather::Walk
    } else {
        let (materials, _) = runtime::load::cpu_materials(&scene).unwrap_or_else(|e| panic!("{e}"));
        let albedo: Vec<glam::Vec3> = radiosity::texel_albedo(&materials, &file)
            .iter()
            .map(|a| glam::Vec3::new(a[0], a[1], a[2]))
            .collect();
        let stats = radiosity_gather_stats(
            &file,
            &radiance,
            &albedo,
            (threshold, exposure),
            (
                radiosity::cpu::FarSplit {
                    near_radius,
                    emitters_apart,
                },
                &radiosity::emitting_materials(&scene),
            ),
            32,
        );
        println!(
            "{}: far field over the atlas {}, near field {near} texel sizes ({near_radius:.4} \
             units), {bounces} bounce(s), threshold {threshold}:\n{stats}",
            dir.display(),
            file.params.atlas_resolution,
        );
        TwinGather::Atlas {
            far: &far,
            near_radius,
            lists: lists.as_ref(),
            emitters_apart,
        }
    };
    let stats = final_gather_stats(
        &scene, &file, &view, &radiance, form, downsample, threshold, exposure, tiles,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    println!(
        "{}: final gather ({}) at {width}x{height}, downsample {downsample}, {bounces} \
         bounce(s), threshold {threshold}, atlas {}, cube {}:\n{stats}",
        dir.display(),
        if walk { "walk" } else { "atlas" },
        file.params.atlas_resolution,
        file.params.cube_resolution
    );
}
