//! `cssm inspect`'s summary of a `.cssm` file ([`InspectSummary`]): its header and sizes.

use std::{
    fmt,
    path::{Path, PathBuf},
};

use serde::{Deserialize, Serialize};

use cssm_formats::{self as formats, CssmFile};

use super::{human_bytes, is_zero, json_line};

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
