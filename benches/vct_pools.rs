//! The memory of `vct`'s sparse voxel octree (Crassin et al. 2011, §10): its node and brick
//! pools per voxel resolution, as the method sizes them on the scene, against a dense
//! mipmapped grid of the same resolution. Its frame time is `method_time --method vct`'s.
//!
//! ```text
//! cargo bench --bench vct_pools -- [--scene DIR] [--resolutions 64,128,256] [--out FILE.md]
//! ```

use cssm::runtime::{
    self,
    vct::{SparseVoxels, VctOptions},
};

#[path = "common/mod.rs"]
mod common;

use common::{Bench, arg, write_report};

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

fn main() {
    let bench = Bench::new((64, 64));
    let resolutions: Vec<u32> = arg(&bench.args, "--resolutions")
        .unwrap_or_else(|| "64,128,256".into())
        .split(',')
        .map(|r| r.parse().expect("--resolutions N,N,..."))
        .collect();
    // A renderer only for its frame context, which the pools are made in: one of a method that
    // reads the RSM, since the light injection binds it.
    let renderer = bench.renderer("rsm", &Default::default());
    let mut report = format!(
        "`vct`'s pools on {}.\n\n\
         | resolution | fragments | node pool MiB | brick pool MiB | values MiB | dense grid MiB |\n\
         | ---: | ---: | ---: | ---: | ---: | ---: |\n",
        bench.setting()
    );
    let defaults = VctOptions::default();
    for &resolution in &resolutions {
        // The pools as the method sizes them at its defaults (the bounces size nothing).
        let cones = defaults.bounce_params();
        let voxels = SparseVoxels::new(
            renderer.context(),
            bench.scene.bounds(),
            resolution,
            defaults.anisotropic,
            defaults.correct_opacity,
            &cones,
            runtime::common::converge::BouncePlan::exactly(0),
        )
        .expect("voxels");
        let (nodes, bricks, node_values) = voxels.svo.pool_bytes(&voxels.octree);
        // A dense grid: rgba16f leaves, and six rgba16f faces per voxel of the mip levels.
        let cube = (resolution as u64).pow(3);
        let dense = cube * 8 + cube / 7 * 8 * 6;
        let row = format!(
            "| {resolution}³ | {} | {:.1} | {:.1} | {:.1} | {:.1} |\n",
            voxels.voxelizer.capacity,
            mib(nodes),
            mib(bricks),
            mib(node_values),
            mib(dense)
        );
        print!("{row}");
        report += &row;
    }
    report += "\nPools as allocated (room for half as many fragments and tiles again); \
               *fragments* is the fragment list's capacity.\n";
    write_report(bench.out.as_deref(), &report);
}
