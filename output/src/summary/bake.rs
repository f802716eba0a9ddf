//! `cssm bake`'s summary ([`BakeSummary`]): the settings, the bake's figures and times, and the
//! memory the process used ([`peak_rss_bytes`], which the compression report reads too).

use std::{fmt, path::Path};

use serde::{Deserialize, Serialize};

use cssm_formats::{self as formats, Scene};

use super::{human_bytes, is_zero, is_zero_seconds, json_line};
use cssm_bake as bake;

/// `cssm bake`: the settings, the figures of the bake and of the file written, the time each
/// stage took and the memory the process used.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeSummary {
    /// Scene name.
    pub scene: String,
    /// The file written, as given.
    pub output: String,
    /// Scene triangles.
    pub triangles: u64,
    /// Atlas width and height in texels.
    pub atlas_resolution: u32,
    /// Cube-map face resolution N.
    pub cube_resolution: u32,
    /// Texel order ([`formats::Traversal::name`]).
    pub traversal: String,
    /// Next-chart rule ([`bake::traverse::ChartOrder::name`]).
    pub chart_order: String,
    /// Stored code of each run ([`bake::compress::RunValue::name`]).
    pub run_value: String,
    /// Lossy short-run merging (0: lossless).
    pub merge_short_runs: u32,
    /// Which intersection closes a pixel's interval ([`bake::cubemap::SecondLayer::name`]).
    pub second_layer: String,
    /// Where each texel's pixels sit ([`formats::cube::PixelGrid::name`]).
    pub pixel_grid: String,
    /// How the cube maps lie in the world ([`formats::cube::CubeFrame::name`]).
    pub cube_frame: String,
    /// How the file codes the runs ([`formats::cssm::FileCoding::name`]).
    pub file_coding: String,
    /// Atlas charts.
    pub charts: u32,
    /// Defined texels: depth maps.
    pub defined_texels: u64,
    /// Rays cast.
    pub rays: u64,
    /// Runs.
    pub runs: u64,
    /// 2 bytes per cube-map pixel.
    pub uncompressed_bytes: u64,
    /// GPU-resident run data.
    pub gpu_bytes: u64,
    /// Size of the file written.
    pub file_bytes: u64,
    /// Uncompressed / GPU-resident size: the ratio of the paper's tables.
    pub ratio_gpu: f64,
    /// Uncompressed / file size (with the coherent shadow maps' uncompressed size when the
    /// scene has moving objects: the file holds both).
    pub ratio_file: f64,
    /// Coherent shadow maps of the rigid objects.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub csms: u64,
    /// Their run data in memory.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub csm_gpu_bytes: u64,
    /// Their bake time.
    #[serde(default, skip_serializing_if = "is_zero_seconds")]
    pub csm_seconds: f64,
    /// Atlas time.
    pub atlas_seconds: f64,
    /// Traversal time.
    pub traversal_seconds: f64,
    /// Depth maps and their compression.
    pub maps_seconds: f64,
    /// Texel hierarchy.
    pub hierarchy_seconds: f64,
    /// Process start to file written.
    pub total_seconds: f64,
    /// Rays per second of the depth maps.
    pub rays_per_second: f64,
    /// Cores available.
    pub threads: u64,
    /// The GPU that cast the depth maps' rays (`--device gpu`), as its driver names it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gpu: Option<String>,
    /// Peak resident memory of the process, where the system reports it.
    pub peak_rss_bytes: Option<u64>,
}

impl BakeSummary {
    /// The summary of a bake of `scene` with `options` whose file, written to `output` with
    /// `file_coding`, has `file_bytes`; `total_seconds` since the process started. The threads
    /// and the peak memory are this process's, read now.
    pub fn new(
        scene: &Scene,
        output: &Path,
        options: &bake::BakeOptions,
        file_coding: formats::cssm::FileCoding,
        stats: &bake::BakeStats,
        file_bytes: u64,
        total_seconds: f64,
    ) -> Self {
        let s = stats;
        Self {
            scene: scene.name.clone(),
            output: output.display().to_string(),
            triangles: scene.triangles.len() as u64,
            atlas_resolution: options.atlas_resolution,
            cube_resolution: options.cube_resolution,
            traversal: options.traversal.name().into(),
            chart_order: options.chart_order.name().into(),
            run_value: options.run_value.name().into(),
            merge_short_runs: options.merge_short_runs,
            second_layer: options.second_layer.name().into(),
            pixel_grid: options.pixel_grid.name().into(),
            cube_frame: options.cube_frame.name().into(),
            file_coding: file_coding.name().into(),
            charts: s.charts,
            defined_texels: s.defined_texels,
            rays: s.rays,
            runs: s.runs,
            uncompressed_bytes: s.uncompressed_bytes,
            gpu_bytes: s.gpu_bytes,
            file_bytes,
            ratio_gpu: s.ratio_gpu(),
            ratio_file: (s.uncompressed_bytes + s.csm_uncompressed_bytes) as f64
                / file_bytes.max(1) as f64,
            csms: s.csms,
            csm_gpu_bytes: s.csm_gpu_bytes,
            csm_seconds: s.csm_time.as_secs_f64(),
            atlas_seconds: s.atlas_time.as_secs_f64(),
            traversal_seconds: s.traversal_time.as_secs_f64(),
            maps_seconds: s.maps_time.as_secs_f64(),
            hierarchy_seconds: s.hierarchy_time.as_secs_f64(),
            total_seconds,
            rays_per_second: s.rays as f64 / s.maps_time.as_secs_f64().max(1e-9),
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()) as u64,
            gpu: s.gpu.clone(),
            peak_rss_bytes: peak_rss_bytes(),
        }
    }

    /// `--json`: one line.
    pub fn to_json(&self) -> String {
        json_line(self)
    }
}

impl fmt::Display for BakeSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let maps_seconds = self.maps_seconds.max(1e-9);
        writeln!(f, "baked {} -> {}", self.scene, self.output)?;
        writeln!(
            f,
            "  atlas {a}x{a}: {} defined texels (depth maps) in {} charts",
            self.defined_texels,
            self.charts,
            a = self.atlas_resolution
        )?;
        writeln!(
            f,
            "  cube 6x{c}x{c} ({} pixel grid, {} frame), {} traversal, {} rays ({:.1} M rays/s, {:.0} maps/s)",
            self.pixel_grid,
            self.cube_frame,
            self.traversal,
            self.rays,
            self.rays_per_second / 1e6,
            self.defined_texels as f64 / maps_seconds,
            c = self.cube_resolution
        )?;
        if let Some(gpu) = &self.gpu {
            writeln!(f, "  rays cast on   {gpu}")?;
        }
        writeln!(
            f,
            "  uncompressed   {:>12}",
            human_bytes(self.uncompressed_bytes)
        )?;
        writeln!(
            f,
            "  in memory      {:>12}  ratio {:.1} : 1  ({} runs)",
            human_bytes(self.gpu_bytes),
            self.ratio_gpu,
            self.runs
        )?;
        if self.csms > 0 {
            writeln!(
                f,
                "  moving objects {:>12}  in {} coherent shadow map{}",
                human_bytes(self.csm_gpu_bytes),
                self.csms,
                if self.csms == 1 { "" } else { "s" }
            )?;
        }
        writeln!(
            f,
            "  file           {:>12}  ratio {:.1} : 1",
            human_bytes(self.file_bytes),
            self.ratio_file
        )?;
        write!(
            f,
            "  time {:.2} s (atlas {:.2} s, traversal {:.2} s, depth maps {:.2} s, hierarchy {:.2} s",
            self.total_seconds,
            self.atlas_seconds,
            self.traversal_seconds,
            self.maps_seconds,
            self.hierarchy_seconds
        )?;
        if self.csms > 0 {
            write!(f, ", moving objects {:.2} s", self.csm_seconds)?;
        }
        write!(f, ")")
    }
}

/// This process's peak resident set size so far (`VmHWM` of `/proc/self/status`), where the
/// system reports one (Linux); the compression report reads it from every bake it runs.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
