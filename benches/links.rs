//! The radiosity's cached links (issue 49, item 1; `runtime/src/radiosity/links.rs`): their
//! memory, what a moved light costs with them and without, how many cuts go stale, and how far
//! the links' answer is from the walk's as the light moves.
//!
//! ```text
//! cargo bench --bench links -- [--scene DIR] [--atlas 128] [--cube 32] [--bounces 2]
//!     [--moves 4] [--step 0.05] [--threshold 0.02] [--far]
//! ```
//!
//! One radiosity (`radiosity::atlas_radiosity_lights`, as a renderer keeps it) solved for the
//! scene's first light, then again for the same light (the links built for the first
//! solution, then multiplied), then `--moves` times with the light moved by `--step` of the
//! scene's diagonal along x each time; beside it the same solves with every bounce walking.
//! Per solve: wall-clock milliseconds (recorded, submitted, waited for, read back; on
//! lavapipe a CPU emulation, so only the ratio of the two columns says anything), the links,
//! the receivers the solve before found stale and the re-cuts that overflowed, and the
//! relative RMSE of the texels' irradiance against the walk's. With `--far`, `lightcuts`'
//! far field after each solve (its default near field, the emitters apart) with its own
//! links, or walking: its links, stale receivers and error against its walk beside.

use cssm::runtime;
use runtime::radiosity::{self, RadiosityOptions};

#[path = "common/mod.rs"]
mod common;

use common::{baked_scene, parsed};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let bounces = parsed(&args, "--bounces", 2u32);
    let moves = parsed(&args, "--moves", 4usize);
    let step = parsed(&args, "--step", 0.05f32);
    let threshold = parsed(&args, "--threshold", radiosity::DEFAULT_THRESHOLD);
    let (dir, scene, file) = baked_scene(&args);
    let far = args
        .iter()
        .any(|a| a == "--far")
        .then(|| radiosity::cpu::FarSplit {
            near_radius: runtime::lightcuts::near_radius(&file.hierarchy, 4.0),
            emitters_apart: true,
        });
    let gpu = runtime::Gpu::new_headless().unwrap_or_else(|e| panic!("{e}"));
    println!(
        "{}: atlas {}, cube {}, {} texels, {} nodes, {bounces} bounce(s), threshold \
         {threshold}, on {}",
        dir.display(),
        file.params.atlas_resolution,
        file.params.cube_resolution,
        file.texels.len(),
        file.hierarchy.nodes.len(),
        gpu.describe()
    );
    let Some(first) = scene.lights.first() else {
        println!("no spot light to move");
        return;
    };
    let (lo, hi) = scene.bounds();
    let diagonal = (hi - lo).length();
    let lights: Vec<Vec<_>> = (0..moves + 2)
        .map(|k| {
            let mut set = scene.lights.clone();
            set[0].position.x = first.position.x + k.saturating_sub(1) as f32 * step * diagonal;
            set
        })
        .collect();
    let options = RadiosityOptions {
        threshold,
        ..Default::default()
    };
    let solve = |links: bool| {
        radiosity::atlas_radiosity_lights(
            &gpu.device,
            &gpu.queue,
            &scene,
            &file,
            runtime::common::shadow_map::DEFAULT_RESOLUTION,
            bounces,
            (options, links, far),
            &lights,
        )
        .unwrap_or_else(|e| panic!("radiosity: {e}"))
    };
    let (cached, walked) = (solve(true), solve(false));
    println!(
        "\n| solve | light moved | cached ms | walk ms | links | stale before | overflowed \
         before | cached against walk |{}\n| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |{}",
        if far.is_some() {
            " far-field links | far stale before | far field against walk |"
        } else {
            ""
        },
        if far.is_some() {
            " ---: | ---: | ---: |"
        } else {
            ""
        },
    );
    for (k, (c, w)) in cached.iter().zip(&walked).enumerate() {
        let far_cells = match (&c.far, &w.far) {
            (Some(cf), Some(wf)) => format!(
                " {} | {} | {:.4}% |",
                cf.links.map_or("-".to_string(), |n| n.to_string()),
                cf.stale_before.0,
                100.0 * relative_rmse(&cf.irradiance, &wf.irradiance)
            ),
            _ => String::new(),
        };
        let links = c.links.map_or("-".to_string(), |n| {
            format!(
                "{n} ({:.0} a texel, {:.1} MB)",
                n as f64 / file.texels.len() as f64,
                // Slots (12 bytes a link, a quarter and 8 more a receiver) and the table.
                (12.0 * (1.25 * n as f64 + 8.0 * file.texels.len() as f64)
                    + 8.0 * file.texels.len() as f64)
                    / 1e6
            )
        });
        println!(
            "| {k} | {:.3} | {:.1} | {:.1} | {links} | {} | {} | {:.4}% |{far_cells}",
            k.saturating_sub(1) as f32 * step,
            c.wall_ms,
            w.wall_ms,
            c.stale_before.0,
            c.stale_before.1,
            100.0 * relative_rmse(&c.solved.irradiance, &w.solved.irradiance)
        );
    }
}

/// Relative RMSE of `a` against `b` (rgb).
fn relative_rmse(a: &[[f32; 4]], b: &[[f32; 4]]) -> f64 {
    let (mut err, mut norm) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().zip(b) {
        for c in 0..3 {
            err += f64::from(x[c] - y[c]).powi(2);
            norm += f64::from(y[c]).powi(2);
        }
    }
    (err / norm.max(1e-30)).sqrt()
}
