//! The final gather's work counted by its CPU twin (`runtime::work::passes`, what `cssm render
//! --stats` prints) without rendering a frame: the radiosity's node radiance on the device
//! (lavapipe is fine), then the twin's walk over a sample of the gather's tiles, and the cost
//! model's H200 milliseconds (**predictions**).
//!
//! ```text
//! cargo bench --bench gather_stats -- [--scene DIR] [--atlas 128] [--cube 32]
//!     [--size 640x480] [--downsample 1] [--bounces 1] [--threshold 0.02] [--tiles 16]
//! ```

use cssm::runtime;
use runtime::{common::camera::View, radiosity, work::passes::final_gather_stats};

#[path = "common/mod.rs"]
mod common;

use common::{baked_scene, parsed, size_arg};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let downsample = parsed(&args, "--downsample", 1u32);
    let bounces = parsed(&args, "--bounces", 1u32);
    let threshold = parsed(&args, "--threshold", radiosity::DEFAULT_THRESHOLD);
    let tiles = parsed(&args, "--tiles", 16u32);
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
    let stats = final_gather_stats(
        &scene, &file, &view, &radiance, downsample, threshold, exposure, tiles,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    println!(
        "{}: final gather at {width}x{height}, downsample {downsample}, {bounces} bounce(s), \
         threshold {threshold}, atlas {}, cube {}:\n{stats}",
        dir.display(),
        file.params.atlas_resolution,
        file.params.cube_resolution
    );
}
