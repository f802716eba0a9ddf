//! What a bake, a `.cssm` file and an accuracy check come to, as `cssm bake`, `cssm inspect` and
//! `cssm check` print them: one struct per command, written as
//! one JSON object for `--json` ([`BakeSummary::to_json`]) and formatted as text otherwise (its
//! `Display`), so the two outputs always tell the same figures. `cssm report compression` reads
//! its child processes' `--json` back into the same types.
//!
//! The JSON has its keys in alphabetical order and its floats printed as `f64`: the bytes these
//! commands have always printed, which scripts parse.
//!
//! ```
//! let json = r#"{"agreement":0.98,"causes_atlas":0,"causes_cube":0,"causes_filter":1,"causes_near":0,"exchanging_agreement":0.99,"exchanging_false_occluded_rate":0.01,"exchanging_false_visible_rate":0.02,"exchanging_pairs":7,"false_occluded_rate":0.01,"false_visible_rate":0.03,"occluded_occluded":4,"occluded_visible":0,"pairs":10,"seconds":0.5,"unmapped":0,"visible_occluded":1,"visible_visible":5}"#;
//! let check: cssm_bake::summary::CheckSummary = serde_json::from_str(json)?;
//! assert_eq!(check.exchanging_pairs, 7);
//! assert_eq!(check.to_json(), json);
//! # Ok::<(), serde_json::Error>(())
//! ```

use std::{fmt, path::Path, path::PathBuf};

use serde::{Deserialize, Serialize};

use cssm_formats::{self as formats, CssmFile, Scene};

use crate::{self as bake, check::Agreement};

/// `value` as one line of JSON, keys in alphabetical order (serde_json's map) and `f32` fields
/// printed as the `f64` they widen to.
fn json_line<T: Serialize>(value: &T) -> String {
    serde_json::to_value(value)
        .expect("a summary has string keys only")
        .to_string()
}

/// Fields of moving objects stay out of a static scene's JSON, which keeps the keys it always had.
fn is_zero(n: &u64) -> bool {
    *n == 0
}

fn is_zero_seconds(s: &f64) -> bool {
    *s == 0.0
}

fn human_bytes(bytes: u64) -> String {
    formats::files::human_bytes(bytes, 2)
}

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

/// `cssm inspect`: a `.cssm` file's header and sizes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InspectSummary {
    /// The file, as given (the text's first line; not in the JSON).
    #[serde(skip)]
    pub path: PathBuf,
    /// Version of the container format.
    pub format_version: u32,
    /// Scene name.
    pub scene: String,
    /// Scene path (directory or mesh file) recorded in the file.
    pub scene_dir: String,
    /// Content hash of the scene when baked, hexadecimal.
    pub scene_hash: String,
    /// Scene triangles when baked.
    pub triangles: u32,
    /// Atlas width and height in texels.
    pub atlas_resolution: u32,
    /// Cube-map face resolution N.
    pub cube_resolution: u32,
    /// Near distance of the depth maps.
    pub near: f32,
    /// Far distance of the depth maps.
    pub far: f32,
    /// Texel order ([`formats::Traversal::name`]).
    pub traversal: String,
    /// Where each texel's pixels sit ([`formats::cube::PixelGrid::name`]).
    pub pixel_grid: String,
    /// How the cube maps lie in the world ([`formats::cube::CubeFrame::name`]).
    pub cube_frame: String,
    /// Defined texels: depth maps.
    pub defined_texels: u64,
    /// Runs.
    pub runs: u64,
    /// 2 bytes per cube-map pixel.
    pub uncompressed_bytes: u64,
    /// GPU-resident run data.
    pub gpu_bytes: u64,
    /// File size.
    pub file_bytes: u64,
    /// Uncompressed / GPU-resident size.
    pub ratio_gpu: f64,
    /// Uncompressed / file size (the coherent shadow maps counted in both).
    pub ratio_file: f64,
    /// Coherent shadow maps of the rigid objects (one per `[[objects]]` entry).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub csms: u64,
    /// Their run data in memory, bytes.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub csm_gpu_bytes: u64,
}

impl InspectSummary {
    /// The summary of `file`, read from `path`, which has `file_bytes`.
    pub fn new(path: &Path, file: &CssmFile, file_bytes: u64) -> Self {
        let p = &file.params;
        let uncompressed = file.runs.uncompressed_bytes();
        let gpu = file.runs.gpu_bytes();
        Self {
            path: path.to_path_buf(),
            format_version: formats::cssm::FORMAT_VERSION,
            scene: file.scene.name.clone(),
            scene_dir: file.scene.dir.clone(),
            scene_hash: formats::scene::hash_hex(&file.scene.content_hash),
            triangles: file.scene.triangle_count,
            atlas_resolution: p.atlas_resolution,
            cube_resolution: p.cube_resolution,
            near: p.near,
            far: p.far,
            traversal: p.traversal.name().into(),
            pixel_grid: file.pixel_grid.name().into(),
            cube_frame: file.cube_frame.name().into(),
            defined_texels: file.texels.len() as u64,
            runs: file.runs.runs.len() as u64,
            uncompressed_bytes: uncompressed,
            gpu_bytes: gpu,
            file_bytes,
            ratio_gpu: uncompressed as f64 / gpu.max(1) as f64,
            ratio_file: (uncompressed
                + file
                    .csms
                    .iter()
                    .map(|c| c.runs.uncompressed_bytes())
                    .sum::<u64>()) as f64
                / file_bytes.max(1) as f64,
            csms: file.csms.len() as u64,
            csm_gpu_bytes: file.csms.iter().map(|c| c.runs.gpu_bytes()).sum(),
        }
    }

    /// `--json`: one line.
    pub fn to_json(&self) -> String {
        json_line(self)
    }
}

impl fmt::Display for InspectSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: CSSM format version {}",
            self.path.display(),
            self.format_version
        )?;
        writeln!(
            f,
            "  scene          {} ({}, {} triangles)",
            self.scene, self.scene_dir, self.triangles
        )?;
        writeln!(f, "  scene hash     {}", self.scene_hash)?;
        writeln!(
            f,
            "  atlas          {a}x{a}, {} defined texels",
            self.defined_texels,
            a = self.atlas_resolution
        )?;
        writeln!(
            f,
            "  cube maps      6x{c}x{c}, near {:.4}, far {:.4}",
            self.near,
            self.far,
            c = self.cube_resolution
        )?;
        writeln!(f, "  traversal      {}", self.traversal)?;
        writeln!(f, "  pixel grid     {}", self.pixel_grid)?;
        writeln!(f, "  cube frame     {}", self.cube_frame)?;
        writeln!(f, "  runs           {}", self.runs)?;
        writeln!(
            f,
            "  uncompressed   {:>12}",
            human_bytes(self.uncompressed_bytes)
        )?;
        writeln!(
            f,
            "  in memory      {:>12}  ratio {:.1} : 1",
            human_bytes(self.gpu_bytes),
            self.ratio_gpu
        )?;
        write!(
            f,
            "  file           {:>12}  ratio {:.1} : 1",
            human_bytes(self.file_bytes),
            self.ratio_file
        )?;
        if self.csms > 0 {
            write!(
                f,
                "\n  moving objects {:>12}  in {} coherent shadow map{}",
                human_bytes(self.csm_gpu_bytes),
                self.csms,
                if self.csms == 1 { "" } else { "s" }
            )?;
        }
        Ok(())
    }
}

/// `cssm bake --chunk I/N`: which slice the chunk holds and what baking it took.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChunkSummary {
    /// The chunk file written.
    pub path: PathBuf,
    /// Scene name.
    pub scene: String,
    /// Chunk index, from 0.
    pub chunk: u32,
    /// Chunks in all.
    pub chunks: u32,
    /// First map of the slice (position in the traversal).
    pub first_map: u32,
    /// One past its last map.
    pub end_map: u32,
    /// Maps of the whole bake.
    pub total_maps: u32,
    /// Rays cast for the slice (when it was just baked; `cssm inspect` of a chunk cannot tell).
    pub rays: Option<u64>,
    /// Runs of the slice.
    pub runs: u64,
    /// Chunk file size.
    pub file_bytes: u64,
    /// Whole process, seconds (when it was just baked).
    pub seconds: Option<f64>,
}

impl ChunkSummary {
    /// The summary of `chunk`, at `path` (`file_bytes`); with the bake's `stats` and seconds
    /// when it was just baked.
    pub fn new(
        path: &Path,
        chunk: &formats::cssm::CssmChunk,
        baked: Option<(&bake::BakeStats, f64)>,
        file_bytes: u64,
    ) -> Self {
        let maps = chunk.maps();
        Self {
            path: path.to_path_buf(),
            scene: chunk.file().scene.name.clone(),
            chunk: chunk.spec().index(),
            chunks: chunk.spec().count(),
            first_map: maps.start,
            end_map: maps.end,
            total_maps: chunk.total_maps(),
            rays: baked.map(|(stats, _)| stats.rays),
            runs: chunk.file().runs.runs.len() as u64,
            file_bytes,
            seconds: baked.map(|(_, seconds)| seconds),
        }
    }

    /// `--json`: one line.
    pub fn to_json(&self) -> String {
        json_line(self)
    }
}

impl fmt::Display for ChunkSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}{}: chunk {} of {} of {}",
            if self.seconds.is_some() { "wrote " } else { "" },
            self.path.display(),
            self.chunk,
            self.chunks,
            self.scene
        )?;
        if self.first_map == self.end_map {
            writeln!(
                f,
                "  depth maps     none (more chunks than segments of {} maps; merge it all the same)",
                formats::cssm::SEGMENT_MAPS
            )?;
        } else {
            writeln!(
                f,
                "  depth maps     {} to {} of {} ({}{} runs)",
                self.first_map,
                self.end_map - 1,
                self.total_maps,
                self.rays.map_or(String::new(), |r| format!("{r} rays, ")),
                self.runs
            )?;
        }
        writeln!(f, "  file           {:>12}", human_bytes(self.file_bytes))?;
        if let Some(seconds) = self.seconds {
            writeln!(f, "  time           {seconds:.2} s")?;
        }
        write!(
            f,
            "  next           cssm merge <all {} chunks> -o <file>",
            self.chunks
        )
    }
}

/// `cssm check`: the confusion matrix of the CSSM against exact ray casts over every pair, and
/// the agreement over the pairs that exchange light ([`bake::check::Measurement`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CheckSummary {
    /// The `.cssm` file, as given (the text's first line; not in the JSON).
    #[serde(skip)]
    pub file: PathBuf,
    /// Pairs tested (the sender point had a texel).
    pub pairs: u64,
    /// Pairs skipped: no texel stood for either point.
    pub unmapped: u64,
    /// Truly visible, reported visible.
    pub visible_visible: u64,
    /// Truly visible, reported occluded.
    pub visible_occluded: u64,
    /// Truly occluded, reported visible.
    pub occluded_visible: u64,
    /// Truly occluded, reported occluded.
    pub occluded_occluded: u64,
    /// Fraction of the pairs where the CSSM agrees with the ray cast.
    pub agreement: f64,
    /// Truly occluded pairs reported visible, as a fraction of the truly occluded.
    pub false_visible_rate: f64,
    /// Truly visible pairs reported occluded, as a fraction of the truly visible.
    pub false_occluded_rate: f64,
    /// Pairs that exchange light (each point in front of the other's surface).
    pub exchanging_pairs: u64,
    /// [`Self::agreement`] over the pairs that exchange light.
    pub exchanging_agreement: f64,
    /// [`Self::false_visible_rate`] over the pairs that exchange light.
    pub exchanging_false_visible_rate: f64,
    /// [`Self::false_occluded_rate`] over the pairs that exchange light.
    pub exchanging_false_occluded_rate: f64,
    /// Disagreements over the pairs that exchange light that the atlas explains
    /// ([`bake::check::Causes`]).
    #[serde(default)]
    pub causes_atlas: u64,
    /// ... that the near distance explains.
    #[serde(default)]
    pub causes_near: u64,
    /// ... that the sender texel's own cube map explains.
    #[serde(default)]
    pub causes_cube: u64,
    /// ... that the filters (sender filter, both ends) explain.
    #[serde(default)]
    pub causes_filter: u64,
    /// Time of the measurement.
    pub seconds: f64,
    /// The confusion matrix of the pairs that exchange light, for the text (not in the JSON:
    /// `None` when read back from it).
    #[serde(skip)]
    pub exchanging: Option<Agreement>,
}

impl CheckSummary {
    /// The summary of measurement `m` of the file `file`, which took `seconds`.
    pub fn new(file: &Path, m: &bake::check::Measurement, seconds: f64) -> Self {
        let (a, x) = (&m.all, &m.exchanging);
        Self {
            file: file.to_path_buf(),
            pairs: a.total(),
            unmapped: a.unmapped,
            visible_visible: a.visible_visible,
            visible_occluded: a.visible_occluded,
            occluded_visible: a.occluded_visible,
            occluded_occluded: a.occluded_occluded,
            agreement: a.agreement(),
            false_visible_rate: a.false_visible_rate(),
            false_occluded_rate: a.false_occluded_rate(),
            exchanging_pairs: x.total(),
            exchanging_agreement: x.agreement(),
            exchanging_false_visible_rate: x.false_visible_rate(),
            exchanging_false_occluded_rate: x.false_occluded_rate(),
            causes_atlas: m.causes.atlas,
            causes_near: m.causes.near,
            causes_cube: m.causes.cube,
            causes_filter: m.causes.filter,
            seconds,
            exchanging: Some(*x),
        }
    }

    /// The confusion matrix over every pair.
    pub fn all(&self) -> Agreement {
        Agreement {
            visible_visible: self.visible_visible,
            visible_occluded: self.visible_occluded,
            occluded_visible: self.occluded_visible,
            occluded_occluded: self.occluded_occluded,
            unmapped: self.unmapped,
        }
    }

    /// `--json`: one line.
    pub fn to_json(&self) -> String {
        json_line(self)
    }
}

impl fmt::Display for CheckSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: {} random surface point pairs against exact ray casts",
            self.file.display(),
            self.pairs
        )?;
        writeln!(f, "{}", self.all())?;
        writeln!(
            f,
            "\nthe {} of them that exchange light (each in front of the other's surface):",
            self.exchanging_pairs
        )?;
        match &self.exchanging {
            Some(x) => write!(f, "{x}")?,
            None => write!(
                f,
                "agreement {:.3}% of {} pairs; occluded reported visible {:.3}%; visible reported occluded {:.3}%",
                100.0 * self.exchanging_agreement,
                self.exchanging_pairs,
                100.0 * self.exchanging_false_visible_rate,
                100.0 * self.exchanging_false_occluded_rate
            )?,
        }
        let wrong = self.causes_atlas + self.causes_near + self.causes_cube + self.causes_filter;
        if wrong > 0 {
            let share = |n: u64| 100.0 * n as f64 / self.exchanging_pairs.max(1) as f64;
            write!(
                f,
                "\ndisagreements by cause, seen from the sender (% of these pairs): atlas {:.3}% \
                 (--atlas), near distance {:.3}% (--near), cube map {:.3}% (--cube), filters \
                 {:.3}%",
                share(self.causes_atlas),
                share(self.causes_near),
                share(self.causes_cube),
                share(self.causes_filter)
            )?;
        }
        if self.unmapped > 0 {
            write!(
                f,
                "\n({} pairs had no texel for either point and were skipped)",
                self.unmapped
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reads `value`'s JSON back and checks that it says the same: every key and integer
    /// exactly, every float to the last bit but one (serde_json parses floats fast, not always
    /// correctly rounded: 0.9473684210526315 reads as ...316).
    fn read_back<T: Serialize + serde::de::DeserializeOwned>(value: &T) -> T {
        let back: T = serde_json::from_str(&json_line(value)).unwrap();
        let (a, b) = (
            serde_json::to_value(value).unwrap(),
            serde_json::to_value(&back).unwrap(),
        );
        let (a, b) = (a.as_object().unwrap(), b.as_object().unwrap());
        assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
        for (key, x) in a {
            match (x.as_f64(), &b[key]) {
                (Some(x), y) if y.is_f64() => {
                    let y = y.as_f64().unwrap();
                    assert!(
                        (x - y).abs() <= 2.0 * f64::EPSILON * x.abs(),
                        "{key}: {x} {y}"
                    );
                }
                (_, y) => assert_eq!(x, y, "{key}"),
            }
        }
        back
    }

    fn keys(json: &str) -> Vec<String> {
        let value: serde_json::Value = serde_json::from_str(json).unwrap();
        value.as_object().unwrap().keys().cloned().collect()
    }

    fn bake_summary() -> BakeSummary {
        BakeSummary {
            scene: "cornell-box".into(),
            output: "/tmp/x.cssm".into(),
            triangles: 34,
            atlas_resolution: 32,
            cube_resolution: 8,
            traversal: "hilbert".into(),
            chart_order: "nearest".into(),
            run_value: "middle".into(),
            merge_short_runs: 0,
            second_layer: "any".into(),
            pixel_grid: "staggered".into(),
            cube_frame: "turned".into(),
            file_coding: "packed".into(),
            charts: 30,
            defined_texels: 500,
            rays: 190_000,
            runs: 9_000,
            uncompressed_bytes: 384_000,
            gpu_bytes: 40_000,
            file_bytes: 20_001,
            ratio_gpu: 9.6,
            ratio_file: 384_000.0 / 20_001.0,
            csms: 0,
            csm_gpu_bytes: 0,
            csm_seconds: 0.0,
            atlas_seconds: 0.01,
            traversal_seconds: 0.001,
            maps_seconds: 0.1,
            hierarchy_seconds: 0.0001,
            total_seconds: 0.2,
            rays_per_second: 1.9e6,
            threads: 2,
            gpu: None,
            peak_rss_bytes: Some(12 << 20),
        }
    }

    /// `cssm report compression` reads these keys of `cssm bake --json` and `cssm check --json`
    /// (`report::bake_and_check`); every summary reads back equal from its JSON.
    #[test]
    fn summaries_round_trip_through_json_with_the_keys_the_report_reads() {
        let bake = bake_summary();
        let json = bake.to_json();
        assert_eq!(
            keys(&json),
            [
                "atlas_resolution",
                "atlas_seconds",
                "chart_order",
                "charts",
                "cube_frame",
                "cube_resolution",
                "defined_texels",
                "file_bytes",
                "file_coding",
                "gpu_bytes",
                "hierarchy_seconds",
                "maps_seconds",
                "merge_short_runs",
                "output",
                "peak_rss_bytes",
                "pixel_grid",
                "ratio_file",
                "ratio_gpu",
                "rays",
                "rays_per_second",
                "run_value",
                "runs",
                "scene",
                "second_layer",
                "threads",
                "total_seconds",
                "traversal",
                "traversal_seconds",
                "triangles",
                "uncompressed_bytes",
            ]
        );
        for key in [
            "triangles",
            "charts",
            "defined_texels",
            "runs",
            "uncompressed_bytes",
            "gpu_bytes",
            "file_bytes",
            "total_seconds",
            "peak_rss_bytes",
        ] {
            assert!(keys(&json).iter().any(|k| k == key), "{key}");
        }
        read_back(&bake);
        // Where the system reports no peak memory the key is null, and reads back as None.
        let no_rss = BakeSummary {
            peak_rss_bytes: None,
            ..bake
        };
        assert!(no_rss.to_json().contains("\"peak_rss_bytes\":null"));
        assert_eq!(read_back(&no_rss).peak_rss_bytes, None);

        let m = bake::check::Measurement {
            all: Agreement {
                visible_visible: 50,
                visible_occluded: 2,
                occluded_visible: 3,
                occluded_occluded: 40,
                unmapped: 5,
            },
            exchanging: Agreement {
                visible_visible: 30,
                visible_occluded: 1,
                occluded_visible: 1,
                occluded_occluded: 20,
                unmapped: 2,
            },
            causes: bake::check::Causes {
                atlas: 1,
                near: 0,
                cube: 1,
                filter: 0,
            },
        };
        let check = CheckSummary::new(Path::new("x.cssm"), &m, 0.25);
        let json = check.to_json();
        assert_eq!(
            keys(&json),
            [
                "agreement",
                "causes_atlas",
                "causes_cube",
                "causes_filter",
                "causes_near",
                "exchanging_agreement",
                "exchanging_false_occluded_rate",
                "exchanging_false_visible_rate",
                "exchanging_pairs",
                "false_occluded_rate",
                "false_visible_rate",
                "occluded_occluded",
                "occluded_visible",
                "pairs",
                "seconds",
                "unmapped",
                "visible_occluded",
                "visible_visible",
            ]
        );
        let back = read_back(&check);
        assert_eq!(
            (back.file.as_os_str(), back.exchanging),
            ("".as_ref(), None)
        );
        assert_eq!(back.all(), m.all);
        assert_eq!(back.exchanging_pairs, 52);
        // The text tells both confusion matrices; read back from the JSON, which has only the
        // exchanging pairs' figures, the same figures in one line.
        let full = check.to_string();
        assert!(full.contains(&m.all.to_string()), "{full}");
        assert!(full.contains(&m.exchanging.to_string()), "{full}");
        assert!(full.ends_with("(5 pairs had no texel for either point and were skipped)"));
        assert!(
            full.contains("atlas 1.923% (--atlas), near distance 0.000% (--near), cube map 1.923%"),
            "{full}"
        );
        let text = back.to_string();
        let last = m.exchanging.to_string().lines().last().unwrap().to_string();
        assert!(
            text.contains(&format!(":\n{last}\n")),
            "{text}\n---\n{last}"
        );
    }

    /// The bytes are those of the `serde_json::json!` object `--json` printed before these
    /// types: keys sorted, `f32` fields as the `f64` they widen to.
    #[test]
    fn json_is_the_bytes_the_commands_always_printed() {
        let inspect = InspectSummary {
            path: PathBuf::from("x.cssm"),
            format_version: 2,
            scene: "cornell-box".into(),
            scene_dir: "/scenes/cornell-box".into(),
            scene_hash: "ab".repeat(32),
            triangles: 34,
            atlas_resolution: 32,
            cube_resolution: 8,
            near: 1.1056,
            far: 552.8,
            traversal: "hilbert".into(),
            pixel_grid: "centred".into(),
            cube_frame: "world".into(),
            defined_texels: 500,
            runs: 9_000,
            uncompressed_bytes: 384_000,
            gpu_bytes: 40_000,
            file_bytes: 20_001,
            ratio_gpu: 9.6,
            ratio_file: 384_000.0 / 20_001.0,
            csms: 0,
            csm_gpu_bytes: 0,
        };
        let i = &inspect;
        let old = serde_json::json!({
            "format_version": i.format_version,
            "scene": i.scene,
            "scene_dir": i.scene_dir,
            "scene_hash": i.scene_hash,
            "triangles": i.triangles,
            "atlas_resolution": i.atlas_resolution,
            "cube_resolution": i.cube_resolution,
            "near": i.near,
            "far": i.far,
            "traversal": i.traversal,
            "pixel_grid": i.pixel_grid,
            "cube_frame": i.cube_frame,
            "defined_texels": i.defined_texels,
            "runs": i.runs,
            "uncompressed_bytes": i.uncompressed_bytes,
            "gpu_bytes": i.gpu_bytes,
            "file_bytes": i.file_bytes,
            "ratio_gpu": i.ratio_gpu,
            "ratio_file": i.ratio_file,
        });
        assert_eq!(inspect.to_json(), old.to_string());
        let back = read_back(&inspect);
        assert_eq!(back.near, inspect.near, "an f32 reads back as itself");
        assert_eq!(back.path, PathBuf::new());
        assert!(
            inspect
                .to_string()
                .starts_with("x.cssm: CSSM format version 2\n")
        );
        assert!(inspect.to_string().contains("near 1.1056, far 552.8000"));
    }
}
