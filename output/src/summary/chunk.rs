//! The summary of one chunk of a bake split with `cssm bake --chunk I/N` ([`ChunkSummary`]),
//! printed when it is baked and by `cssm inspect` of a chunk file.

use std::{
    fmt,
    path::{Path, PathBuf},
};

use serde::{Deserialize, Serialize};

use cssm_formats as formats;

use super::{human_bytes, json_line};
use cssm_bake as bake;

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
