//! Frame time of `vct` (Crassin et al. 2011, §10) per voxel resolution, against `direct` and
//! `rsm` measured in the same run on the same device, per pass from GPU timestamps; and the
//! memory of the node and brick pools against a dense mipmapped grid of the same resolution.
//!
//! ```text
//! cargo bench --bench vct_time -- [--size 1280x720] [--frames 5] [--scene DIR]
//!     [--resolutions 64,128,256] [--shadow-resolution 2048] [--out FILE.md]
//! ```
//!
//! Per resolution two rows: a static light (the octree built once, a frame is the G-buffer,
//! direct light, the cones, compose and tone mapping) and a light that moves every frame (the
//! paper's dynamic case: the RSM, voxelisation, octree build, injection, MIP-mapping and bricks
//! every frame). Wall-clock milliseconds per frame from submit to the GPU's idle (median) and
//! GPU milliseconds per pass of the last frame. On lavapipe only the ratios mean something;
//! absolute GPU times count only from a real GPU (`reports/runtime.sh`).

use cssm::runtime;
use runtime::{
    method::{OptionValue, OptionValues},
    vct::SparseVoxels,
};

#[path = "common/mod.rs"]
mod common;

use common::{Bench, arg, passes_cell, write_report};

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

fn main() {
    let bench = Bench::new((1280, 720));
    let resolutions: Vec<u32> = arg(&bench.args, "--resolutions")
        .unwrap_or_else(|| "64,128,256".into())
        .split(',')
        .map(|r| r.parse().expect("--resolutions N,N,..."))
        .collect();
    let renderer = |name: &str, values: &OptionValues| bench.renderer(name, values);
    let mut report = format!(
        "`vct` on {}, default options but the resolution.\n\n\
         | method | light | frame ms | GPU ms per pass, last frame |\n\
         | --- | --- | --- | --- |\n",
        bench.setting()
    );
    let light = bench.scene.lights.first();
    let mut baseline = Vec::new();
    for name in ["direct", "rsm"] {
        let mut r = renderer(name, &OptionValues::default());
        let (ms, passes) = bench.timed(&mut r, None);
        baseline.push(ms);
        let row = format!("| {name} | static | {ms:.1} | {} |\n", passes_cell(&passes));
        print!("{row}");
        report += &row;
    }
    let mut memory = String::from(
        "\n| resolution | fragments | node pool MiB | brick pool MiB | values MiB | dense grid MiB |\n\
         | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    let mut ratios = String::new();
    for &resolution in &resolutions {
        let mut values = OptionValues::default();
        values.set("resolution", OptionValue::Count(resolution));
        let mut r = renderer("vct", &values);
        let (still, passes) = bench.timed(&mut r, None);
        let row = format!(
            "| vct {resolution}³ | static | {still:.1} | {} |\n",
            passes_cell(&passes)
        );
        print!("{row}");
        report += &row;
        let (moving, passes) = bench.timed(&mut r, light);
        let row = format!(
            "| vct {resolution}³ | moving | {moving:.1} | {} |\n",
            passes_cell(&passes)
        );
        print!("{row}");
        report += &row;
        ratios += &format!(
            "vct {resolution}³: a static frame {:.2}x direct's, {:.2}x rsm's; a moving light's \
             frame {:.2}x direct's.\n",
            still / baseline[0],
            still / baseline[1],
            moving / baseline[0]
        );
        // The pools as the method sizes them (its own are inside the renderer).
        let cones = runtime::vct::trace::TraceParams::new(16, 7.5f32.to_radians(), 2.0);
        let voxels = SparseVoxels::new(
            r.context(),
            bench.scene.bounds(),
            resolution,
            true,
            false,
            &cones,
            runtime::common::converge::BouncePlan::exactly(0),
        )
        .expect("voxels");
        let (nodes, bricks, node_values) = voxels.svo.pool_bytes(&voxels.octree);
        // A dense grid: rgba16f leaves, and six rgba16f faces per voxel of the mip levels.
        let cube = (resolution as u64).pow(3);
        let dense = cube * 8 + cube / 7 * 8 * 6;
        memory += &format!(
            "| {resolution}³ | {} | {:.1} | {:.1} | {:.1} | {:.1} |\n",
            voxels.voxelizer.capacity,
            mib(nodes),
            mib(bricks),
            mib(node_values),
            mib(dense)
        );
    }
    let tail = format!(
        "\n{ratios}{memory}\nPools as allocated (room for half as many fragments and tiles again); \
         *fragments* is the fragment list's capacity.\n"
    );
    print!("{tail}");
    report += &tail;
    write_report(bench.out.as_deref(), &report);
}
