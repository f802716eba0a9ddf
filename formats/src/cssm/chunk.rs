//! Chunks of a chunked bake, for batch farms: `cssm bake --chunk I/N` bakes the depth maps of
//! one contiguous slice of the traversal into a chunk file, and `cssm merge` joins the `N`
//! chunks into the file a single bake writes, byte for byte.
//!
//! A slice is a run of whole segments of the random-access layout ([`SEGMENT_MAPS`] maps):
//! the compressor starts every segment from nothing, so a segment's runs do not depend on the
//! maps before it and the chunks compress independently. Chunk `I` of `N` takes segments
//! `floor(I S / N)` to `floor((I + 1) S / N)` of the `S` the bake has; with more chunks than
//! segments some chunks are empty (they still have to be merged, so that a missing chunk is
//! always noticed).
//!
//! A chunk file has the `.cssm` container's header with [`FLAG_CHUNK`] set, and its payload is
//! a [`CssmChunk`]: the whole bake's tables (every chunk computes the same atlas, traversal and
//! hierarchy: the bake is deterministic) and its slice's run data, coded plainly. [`super::read`]
//! refuses a chunk, saying to merge it, and a build that predates chunks refuses it as an
//! unknown flag.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use super::framing::{compress_payload, decode_body, unframe};
use super::validate::{validate_csms, validate_params, validate_runs, validate_tables};
use super::write::write_atomic_by;
use super::{
    CssmError, CssmFile, FLAG_STAGGERED_GRID, FLAG_TURNED_FRAME, FileCoding, HEADER_LEN, RunData,
    SEGMENT_MAPS, apply_layout_flags, layout_flags,
};

/// Header flag of a chunk file (payload: a [`CssmChunk`]).
pub const FLAG_CHUNK: u32 = 2;

/// The most chunks a bake may be cut into.
pub const MAX_CHUNKS: u32 = 65_536;

/// Which chunk of how many: `I/N` on the command line, `I` counted from 0 (as Kubernetes'
/// `JOB_COMPLETION_INDEX` is; a Slurm job array run with `--array=0-(N-1)`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChunkSpec {
    index: u32,
    count: u32,
}

impl ChunkSpec {
    /// Chunk `index` of `count`; `index < count <= MAX_CHUNKS`.
    ///
    /// ```
    /// use cssm_formats::cssm::ChunkSpec;
    /// let spec = ChunkSpec::new(2, 8).unwrap();
    /// assert_eq!(spec, "2/8".parse().unwrap());
    /// assert!(ChunkSpec::new(8, 8).is_err());
    /// ```
    ///
    /// # Errors
    /// A message saying what is out of range.
    pub fn new(index: u32, count: u32) -> Result<Self, String> {
        if count == 0 || count > MAX_CHUNKS {
            return Err(format!(
                "{count} chunks: the count must be 1 to {MAX_CHUNKS}"
            ));
        }
        if index >= count {
            return Err(format!(
                "chunk {index} of {count}: chunks are numbered from 0 to {}",
                count - 1
            ));
        }
        Ok(Self { index, count })
    }

    /// The chunk's index, from 0.
    pub fn index(self) -> u32 {
        self.index
    }

    /// How many chunks the bake is cut into.
    pub fn count(self) -> u32 {
        self.count
    }

    /// The positions in the traversal sequence of the maps this chunk bakes, for a bake of
    /// `map_count` maps: whole segments, the chunks together covering every map once.
    ///
    /// ```
    /// use cssm_formats::cssm::{ChunkSpec, SEGMENT_MAPS};
    /// let maps = 3 * SEGMENT_MAPS + 10;
    /// let first = ChunkSpec::new(0, 2).unwrap().maps(maps);
    /// let second = ChunkSpec::new(1, 2).unwrap().maps(maps);
    /// assert_eq!((first.start, first.end, second.end), (0, 2 * SEGMENT_MAPS, maps));
    /// ```
    pub fn maps(self, map_count: u32) -> Range<u32> {
        let segments = u64::from(map_count.div_ceil(SEGMENT_MAPS));
        let bound = |i: u32| {
            let segment = segments * u64::from(i) / u64::from(self.count);
            (segment * u64::from(SEGMENT_MAPS)).min(u64::from(map_count)) as u32
        };
        bound(self.index)..bound(self.index + 1)
    }
}

impl std::fmt::Display for ChunkSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl FromStr for ChunkSpec {
    type Err = String;

    /// `I/N`, for example `3/8` (the fourth of eight chunks).
    fn from_str(s: &str) -> Result<Self, String> {
        let (i, n) = s
            .split_once('/')
            .ok_or_else(|| format!("'{s}' is not I/N (chunk I of N, from 0: 0/8 to 7/8)"))?;
        let number = |t: &str| {
            t.trim()
                .parse::<u32>()
                .map_err(|_| format!("'{s}' is not I/N: '{t}' is not a whole number"))
        };
        Self::new(number(i)?, number(n)?)
    }
}

/// How the merged file codes its runs, recorded in each chunk (serde's view of
/// [`FileCoding`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
enum Coding {
    Plain,
    Packed,
}

/// One chunk of a chunked bake: the bake's whole tables and one slice of its run data.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CssmChunk {
    spec: ChunkSpec,
    coding: Coding,
    /// Params, scene, texels, triangle_uvs, sequence and hierarchy of the whole bake; `runs`
    /// holds the maps `spec.maps(texels.len())` of the sequence only.
    file: CssmFile,
}

impl CssmChunk {
    /// The chunk `spec` of a bake whose tables are `tables` (its run data is ignored) and whose
    /// slice of maps compressed to `runs`; the merged file will code its runs as `coding`.
    ///
    /// # Errors
    /// [`CssmError::Invalid`] when the tables or the runs are not consistent, or `runs` does
    /// not hold the maps of the slice `spec` names.
    pub fn new(
        spec: ChunkSpec,
        coding: FileCoding,
        mut tables: CssmFile,
        runs: RunData,
    ) -> Result<Self, CssmError> {
        tables.runs = runs;
        let chunk = Self {
            spec,
            coding: match coding {
                FileCoding::Plain => Coding::Plain,
                FileCoding::Packed => Coding::Packed,
            },
            file: tables,
        };
        chunk.validate()?;
        Ok(chunk)
    }

    /// Which chunk this is.
    pub fn spec(&self) -> ChunkSpec {
        self.spec
    }

    /// Maps of the whole bake.
    pub fn total_maps(&self) -> u32 {
        self.file.texels.len() as u32
    }

    /// The positions in the traversal of the maps this chunk holds.
    pub fn maps(&self) -> Range<u32> {
        self.spec.maps(self.total_maps())
    }

    /// The coding the merged file will have.
    pub fn coding(&self) -> FileCoding {
        match self.coding {
            Coding::Plain => FileCoding::Plain,
            Coding::Packed => FileCoding::Packed,
        }
    }

    /// The whole bake's tables, with this chunk's runs.
    pub fn file(&self) -> &CssmFile {
        &self.file
    }

    fn validate(&self) -> Result<(), CssmError> {
        let invalid = |why: String| Err(CssmError::Invalid(why));
        ChunkSpec::new(self.spec.index, self.spec.count).map_err(CssmError::Invalid)?;
        validate_params(&self.file.params)?;
        if self.file.texels.is_empty() {
            return invalid("no depth maps (no texels)".into());
        }
        validate_tables(&self.file)?;
        validate_csms(&self.file.csms)?;
        let slice = self.maps();
        if self.file.runs.map_count != slice.len() as u32 {
            return invalid(format!(
                "chunk {} holds {} maps, its slice of {} maps has {}",
                self.spec,
                self.file.runs.map_count,
                self.total_maps(),
                slice.len()
            ));
        }
        validate_runs(&self.file.runs, self.file.params.cube_resolution)
    }
}

/// The bytes of a chunk file. Deterministic.
///
/// # Errors
/// [`CssmError::Invalid`] for an inconsistent chunk, [`CssmError::Encode`] when encoding fails.
pub fn encode_chunk(chunk: &CssmChunk) -> Result<Vec<u8>, CssmError> {
    chunk.validate()?;
    let flags = FLAG_CHUNK | layout_flags(&chunk.file);
    let (mut bytes, head) = compress_payload(flags, chunk, vec![0u8; HEADER_LEN])?;
    bytes[..HEADER_LEN].copy_from_slice(&head);
    Ok(bytes)
}

/// Writes `chunk` to `path` atomically, as [`super::write_atomic`] writes a file; returns the
/// bytes written.
///
/// # Errors
/// As [`encode_chunk`], and [`CssmError::Io`] naming the path.
pub fn write_chunk_atomic(path: &Path, chunk: &CssmChunk) -> Result<u64, CssmError> {
    let bytes = encode_chunk(chunk)?;
    write_atomic_by(path, &mut |f, tmp| {
        std::io::Write::write_all(f, &bytes).map_err(|error| CssmError::Io {
            path: tmp.to_path_buf(),
            error,
        })
    })?;
    Ok(bytes.len() as u64)
}

/// Decodes the bytes of a chunk file, with every check of [`super::decode`]. Never panics.
///
/// # Errors
/// [`CssmError::NotAChunk`] for a whole `.cssm` file, or any error of [`super::decode`].
pub fn decode_chunk(bytes: &[u8]) -> Result<CssmChunk, CssmError> {
    let (flags, raw) = unframe(bytes)?;
    if flags & !(FLAG_STAGGERED_GRID | FLAG_TURNED_FRAME) != FLAG_CHUNK {
        return Err(if flags & FLAG_CHUNK == 0 {
            CssmError::NotAChunk
        } else {
            CssmError::UnsupportedFlags { flags }
        });
    }
    let mut chunk: CssmChunk = decode_body(&raw)?;
    apply_layout_flags(&mut chunk.file, flags);
    chunk.validate()?;
    Ok(chunk)
}

/// Reads the chunk file at `path`, with the checks of [`super::read`]; every error names it.
///
/// # Errors
/// As [`decode_chunk`], wrapped in [`CssmError::File`]; [`CssmError::Io`] when it cannot be
/// read.
pub fn read_chunk(path: &Path) -> Result<CssmChunk, CssmError> {
    let bytes = super::read_bytes(path)?;
    decode_chunk(&bytes).map_err(|e| CssmError::File {
        path: path.to_path_buf(),
        inner: Box::new(e),
    })
}

/// Why chunks cannot be merged. Every message names the files.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// No chunk was given.
    #[error("no chunks to merge")]
    NoChunks,
    /// Two chunks of different cuts.
    #[error(
        "{} is chunk {} but {} is chunk {}: chunks of different cuts of a bake",
        .first.display(), .first_spec, .other.display(), .other_spec
    )]
    OtherCut {
        /// The first chunk given.
        first: PathBuf,
        /// Its spec.
        first_spec: ChunkSpec,
        /// The chunk that disagrees.
        other: PathBuf,
        /// Its spec.
        other_spec: ChunkSpec,
    },
    /// The same chunk twice.
    #[error("{} and {} are both chunk {}", .first.display(), .second.display(), .spec)]
    Twice {
        /// One file.
        first: PathBuf,
        /// The other.
        second: PathBuf,
        /// The chunk they both are.
        spec: ChunkSpec,
    },
    /// Chunks missing (a failed or unfinished job of the farm).
    #[error("{}", missing_message(.missing, *.count))]
    Missing {
        /// Indices of the missing chunks.
        missing: Vec<u32>,
        /// The chunk count.
        count: u32,
    },
    /// A chunk of another bake (another scene, other options or another build).
    #[error(
        "{} and {} come from different bakes (their {what} differ): bake every chunk from the \
         same scene with the same options",
        .first.display(), .other.display()
    )]
    OtherBake {
        /// The first chunk given.
        first: PathBuf,
        /// The chunk that disagrees.
        other: PathBuf,
        /// Which table differs.
        what: &'static str,
    },
    /// The merged file is not valid (cannot happen with chunks that passed their own checks).
    #[error("the merged file is not valid: {0}")]
    Invalid(CssmError),
}

fn missing_message(missing: &[u32], count: u32) -> String {
    match missing {
        [one] => format!(
            "chunk {one} of {count} missing: bake it with --chunk {one}/{count} and merge again"
        ),
        many => format!(
            "chunks {} of {count} missing: bake each with --chunk I/{count} and merge again",
            list(many)
        ),
    }
}

fn list(indices: &[u32]) -> String {
    const SHOWN: usize = 16;
    let mut out: Vec<String> = indices.iter().take(SHOWN).map(u32::to_string).collect();
    if indices.len() > SHOWN {
        out.push(format!("and {} more", indices.len() - SHOWN));
    }
    out.join(", ")
}

/// Joins the chunks of one bake (each with the path it was read from, for the messages), in any
/// order, into the file the single bake gives, and the coding to write it with. Every chunk
/// `0..N` must be there exactly once and all must hold the same tables. [`ChunkMerger`] does the
/// same one chunk at a time.
///
/// ```
/// # fn demo(parts: Vec<(std::path::PathBuf, cssm_formats::cssm::CssmChunk)>) {
/// use cssm_formats::cssm;
/// match cssm::merge_chunks(parts) {
///     Ok((file, coding)) => { cssm::write_atomic_with("out.cssm".as_ref(), &file, coding).unwrap(); }
///     Err(e) => eprintln!("{e}"),
/// }
/// # }
/// ```
///
/// # Errors
/// [`MergeError`], naming the chunks' files.
pub fn merge_chunks(
    chunks: Vec<(PathBuf, CssmChunk)>,
) -> Result<(CssmFile, FileCoding), MergeError> {
    let mut merger = ChunkMerger::default();
    for (path, chunk) in chunks {
        merger.add(path, chunk)?;
    }
    merger.finish()
}

/// Joins the chunks of one bake as they are read: the first chunk's tables are kept, every
/// later chunk's are compared with them and dropped, and only its run data stays. Memory is
/// one set of tables and the merged runs (what the file holds), whatever the number of chunks.
///
/// ```
/// # fn demo(paths: &[std::path::PathBuf]) -> Result<(), Box<dyn std::error::Error>> {
/// use cssm_formats::cssm;
/// let mut merger = cssm::ChunkMerger::default();
/// for path in paths {
///     merger.add(path.clone(), cssm::read_chunk(path)?)?;
/// }
/// let (file, coding) = merger.finish()?;
/// cssm::write_atomic_with("out.cssm".as_ref(), &file, coding)?;
/// # Ok(()) }
/// ```
#[derive(Default)]
pub struct ChunkMerger {
    /// The first chunk added (its run data taken out) and its file.
    first: Option<(PathBuf, CssmChunk)>,
    /// By chunk index: the file it came from and its run data.
    slots: Vec<Option<(PathBuf, RunData)>>,
}

impl ChunkMerger {
    /// Adds the chunk read from `path`.
    ///
    /// # Errors
    /// [`MergeError::OtherCut`], [`MergeError::Twice`] or [`MergeError::OtherBake`] against the
    /// chunks added before.
    pub fn add(&mut self, path: PathBuf, mut chunk: CssmChunk) -> Result<(), MergeError> {
        let runs = std::mem::take(&mut chunk.file.runs);
        let spec = chunk.spec;
        let Some((first_path, first)) = &self.first else {
            self.slots = vec![None; spec.count as usize];
            self.slots[spec.index as usize] = Some((path.clone(), runs));
            self.first = Some((path, chunk));
            return Ok(());
        };
        if spec.count != first.spec.count {
            return Err(MergeError::OtherCut {
                first: first_path.clone(),
                first_spec: first.spec,
                other: path,
                other_spec: spec,
            });
        }
        let slot = &mut self.slots[spec.index as usize];
        if let Some((earlier, _)) = slot {
            return Err(MergeError::Twice {
                first: earlier.clone(),
                second: path,
                spec,
            });
        }
        let (a, b) = (&first.file, &chunk.file);
        let differs = [
            (a.params != b.params, "bake parameters"),
            (a.scene != b.scene, "scenes"),
            (a.texels != b.texels, "atlas texels"),
            (a.triangle_uvs != b.triangle_uvs, "atlas coordinates"),
            (a.sequence != b.sequence, "traversals"),
            (a.hierarchy != b.hierarchy, "hierarchies"),
            (a.csms != b.csms, "coherent shadow maps"),
            (a.pixel_grid != b.pixel_grid, "pixel grids (--pixel-grid)"),
            (a.cube_frame != b.cube_frame, "cube frames (--cube-frame)"),
            (first.coding != chunk.coding, "file codings (--coding)"),
        ];
        if let Some(&(_, what)) = differs.iter().find(|(d, _)| *d) {
            return Err(MergeError::OtherBake {
                first: first_path.clone(),
                other: path,
                what,
            });
        }
        *slot = Some((path, runs));
        Ok(())
    }

    /// The merged file and the coding to write it with.
    ///
    /// # Errors
    /// [`MergeError::NoChunks`], [`MergeError::Missing`], or [`MergeError::Invalid`] when the
    /// runs overflow the file's offsets.
    pub fn finish(self) -> Result<(CssmFile, FileCoding), MergeError> {
        let Some((_, first)) = self.first else {
            return Err(MergeError::NoChunks);
        };
        let missing: Vec<u32> = (0..first.spec.count)
            .filter(|&i| self.slots[i as usize].is_none())
            .collect();
        if !missing.is_empty() {
            return Err(MergeError::Missing {
                missing,
                count: first.spec.count,
            });
        }
        let coding = first.coding();
        let mut file = first.file;
        // The slices in traversal order, each one's runs dropped as it is appended, so the
        // peak is about one copy of the run data.
        let mut offsets: Vec<u32> = vec![0];
        let mut runs: Vec<u32> = Vec::new();
        let mut pixel_count = 0;
        for (_, part_runs) in self.slots.into_iter().flatten() {
            let base = runs.len() as u64;
            pixel_count = part_runs.pixel_count;
            let too_many = || {
                MergeError::Invalid(CssmError::Invalid(
                    "more than 2^32 runs in all: too large for the run offsets".into(),
                ))
            };
            for &o in &part_runs.offsets[1..] {
                offsets.push(u32::try_from(base + u64::from(o)).map_err(|_| too_many())?);
            }
            runs.extend_from_slice(&part_runs.runs);
        }
        file.runs = RunData {
            map_count: file.texels.len() as u32,
            pixel_count,
            offsets,
            runs,
        };
        super::validate(&file).map_err(MergeError::Invalid)?;
        Ok((file, coding))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_cover_every_map_once_in_whole_segments() {
        for maps in [
            1,
            5,
            SEGMENT_MAPS - 1,
            SEGMENT_MAPS,
            SEGMENT_MAPS + 1,
            7 * SEGMENT_MAPS + 3,
        ] {
            for count in [1, 2, 3, 4, 7, 8, 100] {
                let mut next = 0;
                for index in 0..count {
                    let slice = ChunkSpec::new(index, count).unwrap().maps(maps);
                    assert_eq!(slice.start, next, "{maps} maps, chunk {index}/{count}");
                    assert!(slice.start % SEGMENT_MAPS == 0 || slice.start == maps);
                    next = slice.end;
                }
                assert_eq!(next, maps, "{maps} maps in {count} chunks");
            }
        }
        // As even as whole segments allow.
        let sizes: Vec<u32> = (0..4)
            .map(|i| ChunkSpec::new(i, 4).unwrap().maps(8 * SEGMENT_MAPS).len() as u32)
            .collect();
        assert_eq!(sizes, vec![2 * SEGMENT_MAPS; 4]);
    }

    #[test]
    fn chunk_specs_parse_and_refuse() {
        assert_eq!(
            "0/1".parse::<ChunkSpec>().unwrap(),
            ChunkSpec::new(0, 1).unwrap()
        );
        assert_eq!(" 7 / 8".parse::<ChunkSpec>().unwrap().to_string(), "7/8");
        for bad in [
            "", "3", "3/", "/3", "-1/3", "3/3", "0/0", "a/b", "1/65537", "1.5/3",
        ] {
            assert!(bad.parse::<ChunkSpec>().is_err(), "{bad:?} parsed");
        }
    }

    #[test]
    fn a_chunk_is_not_a_file_nor_a_file_a_chunk() {
        let bytes = frame_chunk_flagged(b"anything");
        assert!(matches!(
            super::super::decode(&bytes),
            Err(CssmError::IsChunk)
        ));
        let whole = super::super::frame_payload(0, b"anything").unwrap();
        assert!(matches!(decode_chunk(&whole), Err(CssmError::NotAChunk)));
        // Any bytes behind a valid chunk header are refused, never a panic.
        assert!(matches!(decode_chunk(&bytes), Err(CssmError::Malformed(_))));
        let both =
            super::super::frame_payload(FLAG_CHUNK | super::super::FLAG_PACKED_RUNS, b"x").unwrap();
        assert!(matches!(
            decode_chunk(&both),
            Err(CssmError::UnsupportedFlags { .. })
        ));
    }

    fn frame_chunk_flagged(raw: &[u8]) -> Vec<u8> {
        super::super::frame_payload(FLAG_CHUNK, raw).unwrap()
    }

    #[test]
    fn merging_nothing_is_an_error() {
        assert!(matches!(
            merge_chunks(Vec::new()),
            Err(MergeError::NoChunks)
        ));
    }
}
