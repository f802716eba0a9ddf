//! The `.cssm` container: a versioned, checksummed, zstd-compressed file holding one baked
//! Coherent Surface Shadow Map (§3.2): the bake parameters, the atlas texel table, the
//! traversal sequence, the texel hierarchy (§4.2) and the piecewise-constant run data laid out
//! for random access.
//!
//! # Layout
//!
//! | bytes | field |
//! |-------|-------|
//! | 8     | [`MAGIC`] |
//! | 4     | format version, `u32` little-endian ([`FORMAT_VERSION`]) |
//! | 4     | flags, `u32` LE: any of [`FLAG_PACKED_RUNS`], [`FLAG_STAGGERED_GRID`], [`FLAG_TURNED_FRAME`] |
//! | 8     | uncompressed payload length, `u64` LE (at most [`MAX_UNCOMPRESSED_BYTES`]) |
//! | 8     | compressed payload length, `u64` LE (= the rest of the file) |
//! | 16    | checksum: first 16 bytes of BLAKE3 of the compressed payload |
//! | ...   | payload: zstd (level [`ZSTD_LEVEL`]) of the bincode 2 (serde, standard config) encoding of [`CssmFile`] (flags 0), or of the same fields with the run data entropy-coded as [`PackedRuns`] ([`FLAG_PACKED_RUNS`]) |
//!
//! The body's fields, in order: params, scene, texels, triangle_uvs, sequence, hierarchy
//! ([`Hierarchy`], since version 2), the run data, then the coherent shadow maps of the rigid
//! objects ([`CssmFile::csms`], since version 3).
//!
//! The entropy stage ([`FileCoding::Packed`], the default since it makes files smaller) changes
//! only the file: it decodes to exactly the same [`RunData`], the layout the GPU queries. Files
//! without it (flags 0) are read as well; a build that predates it refuses packed files with
//! "unsupported header flags". Version-1 files (before the hierarchy) are refused with
//! [`CssmError::UnsupportedVersion`]: re-bake them.
//!
//! [`FLAG_STAGGERED_GRID`] says the cube maps sample staggered pixel grids ([`CssmFile::pixel_grid`]);
//! files without it (every file before it) sample the paper's centred grid and read as before.
//! [`FLAG_TURNED_FRAME`] says the cube maps are turned against the world
//! ([`CssmFile::cube_frame`]); files without it have their faces on the world's axes.
//!
//! Encoding is deterministic: the same [`CssmFile`] always gives the same bytes. Decoding checks
//! every field before trusting it, bounds every allocation, and finishes with [`validate`].
//!
//! [`validate`]: fn@validate

mod chunk;
mod framing;
mod runs;
mod validate;
mod write;

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::hierarchy::Hierarchy;
use crate::texel::{Texel, Traversal};

pub use chunk::{
    ChunkMerger, ChunkSpec, CssmChunk, FLAG_CHUNK, MAX_CHUNKS, MergeError, decode_chunk,
    encode_chunk, merge_chunks, read_chunk, write_chunk_atomic,
};
pub use framing::{
    FLAG_PACKED_RUNS, FLAG_STAGGERED_GRID, FLAG_TURNED_FRAME, FORMAT_VERSION, HEADER_LEN, MAGIC,
    MAX_UNCOMPRESSED_BYTES, MAX_ZSTD_RATIO, PLAUSIBLE_NEWER_VERSIONS, RATIO_FREE_BYTES, ZSTD_LEVEL,
    frame_payload,
};
pub use runs::{PackedRuns, RunData, SEGMENT_MAPS};
pub use validate::{validate, validate_for_scene, validate_run_layout};
pub use write::{MAX_NAME_BYTES, destination, write_atomic, write_atomic_with, write_bytes_atomic};

use framing::{compress_payload, decode_body, unframe};

/// Valid range of [`BakeParams::atlas_resolution`].
pub const ATLAS_RESOLUTION_RANGE: std::ops::RangeInclusive<u32> = 32..=1024;
/// Valid range of [`BakeParams::cube_resolution`].
pub const CUBE_RESOLUTION_RANGE: std::ops::RangeInclusive<u32> = 8..=128;

/// What the bake was asked to do.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeParams {
    /// Atlas width and height in texels (32..=1024).
    pub atlas_resolution: u32,
    /// Cube face width and height in pixels (8..=128); a map has `6 * N * N` pixels.
    pub cube_resolution: u32,
    /// Distance the cube-map centre is pushed off the surface along the normal, and near plane
    /// of the linear depth range (scene units), §3.2.1.
    pub near: f32,
    /// Far plane of the linear depth range: the scene diameter (scene units), §3.2.1.
    pub far: f32,
    /// Order of the depth-map sequence.
    pub traversal: Traversal,
}

/// Which scene the file was baked from, so that `check` and the runtime can find the geometry
/// and refuse a scene that has changed since.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneRef {
    /// Absolute path the scene was loaded from at bake time: its directory, or its mesh file
    /// (`Scene::path`). The field keeps its name, which the format's readers know.
    pub dir: String,
    /// Scene name (from `scene.toml`, or the directory name).
    pub name: String,
    /// BLAKE3 hash over the scene's files (see `scene::Scene::content_hash`).
    pub content_hash: [u8; 32],
    /// Number of triangles of the loaded scene (a cheap second check).
    pub triangle_count: u32,
}

/// How the run data is coded in the file (the GPU-resident [`RunData`] is the same either way).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FileCoding {
    /// bincode of the offsets and packed runs, then zstd (the first file format).
    Plain,
    /// Entropy stage before zstd ([`PackedRuns`]): per (segment, pixel) the run count, then
    /// every run's length and its depth as a difference to the run before it, all as varints,
    /// in three separate streams.
    #[default]
    Packed,
}

impl FileCoding {
    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            FileCoding::Plain => "plain",
            FileCoding::Packed => "packed",
        }
    }
}

impl std::fmt::Display for FileCoding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for FileCoding {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "plain" => Ok(FileCoding::Plain),
            "packed" => Ok(FileCoding::Packed),
            other => Err(format!(
                "unknown file coding '{other}': expected packed or plain"
            )),
        }
    }
}

/// A [`CssmFile`] with its run data packed: the payload of a file flagged [`FLAG_PACKED_RUNS`].
/// Field for field the same as [`CssmFile`], with `runs` as [`PackedRuns`] and its two counts.
#[derive(Serialize, Deserialize)]
struct PackedFile {
    params: BakeParams,
    scene: SceneRef,
    texels: Vec<Texel>,
    triangle_uvs: Vec<[[f32; 2]; 3]>,
    sequence: Vec<u32>,
    hierarchy: Hierarchy,
    map_count: u32,
    pixel_count: u32,
    runs: PackedRuns,
    csms: Vec<crate::csm::CsmData>,
}

/// A whole baked CSSM.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CssmFile {
    /// Bake parameters.
    pub params: BakeParams,
    /// The scene it was baked from.
    pub scene: SceneRef,
    /// Defined atlas texels, in atlas row-major order (y, then x).
    pub texels: Vec<Texel>,
    /// Atlas coordinates (in texels, `0..atlas_resolution`) of the three corners of every scene
    /// triangle, in the scene's triangle order; lets any surface point find its texel.
    pub triangle_uvs: Vec<[[f32; 2]; 3]>,
    /// `sequence[k]` is the texel index of the `k`-th depth map.
    pub sequence: Vec<u32>,
    /// The median-cut hierarchy over the texels (§4.2), for the hierarchical radiosity and final
    /// gathering of §4.3-§4.4; its texel indices index `texels`.
    pub hierarchy: Hierarchy,
    /// The compressed depth maps.
    pub runs: RunData,
    /// The coherent shadow maps of the scene's rigid objects (§3.1, §3.3; [`crate::csm`]), in
    /// object order; empty for a scene without `[[objects]]`. Since version 3.
    pub csms: Vec<crate::csm::CsmData>,
    /// Where each texel's cube-map pixels sit ([`crate::cube::PixelGrid`]): stored as the
    /// header's [`FLAG_STAGGERED_GRID`], not in the payload, so that every older file reads as
    /// the centred grid it was baked with.
    #[serde(skip)]
    pub pixel_grid: crate::cube::PixelGrid,
    /// How every texel's cube map lies in the world ([`crate::cube::CubeFrame`]): stored as the
    /// header's [`FLAG_TURNED_FRAME`], so that every older file reads as the world frame it was
    /// baked in.
    #[serde(skip)]
    pub cube_frame: crate::cube::CubeFrame,
}

/// Everything that can go wrong reading, writing or validating a `.cssm` file. Every message is
/// complete on its own (it names the path where there is one); no error is chained as a
/// `source`, so printing the error chain never repeats a message.
#[derive(Debug, thiserror::Error)]
pub enum CssmError {
    /// An I/O operation on `path` failed.
    #[error("{path}: {error}", path = .path.display())]
    Io {
        /// File (or temporary file) the operation was on.
        path: PathBuf,
        /// The underlying error.
        error: std::io::Error,
    },
    /// A decode error of the file at `path` (wraps any other variant).
    #[error("{path}: {inner}", path = .path.display())]
    File {
        /// The file being read.
        path: PathBuf,
        /// What was wrong with it.
        inner: Box<CssmError>,
    },
    /// The input is shorter than the fixed header.
    #[error("truncated .cssm file: {len} bytes, shorter than the {HEADER_LEN}-byte header")]
    TooShort {
        /// Length of the input.
        len: usize,
    },
    /// The magic bytes do not match.
    #[error("not a .cssm file (bad magic bytes)")]
    NotCssm,
    /// The file was written by a newer build.
    #[error(
        "file version {version} is newer than this build's version {FORMAT_VERSION}; upgrade cssm"
    )]
    NewerVersion {
        /// Version found in the header.
        version: u32,
    },
    /// The version field holds no version any build wrote or is likely to write: the header
    /// is corrupted.
    #[error(
        "corrupted header: the version field holds {version} ({version:#010x}), no version of \
         the format (this build reads version {FORMAT_VERSION})"
    )]
    CorruptVersion {
        /// Version field found in the header.
        version: u32,
    },
    /// A header field holds a value no file can have.
    #[error("corrupted header: {0}")]
    CorruptHeader(String),
    /// The version is older than (or otherwise unknown to) this build.
    #[error(
        "file version {version} is not supported (this build reads version {FORMAT_VERSION}); re-bake it"
    )]
    UnsupportedVersion {
        /// Version found in the header.
        version: u32,
    },
    /// Reserved flag bits are set.
    #[error(
        "unknown header flags {flags:#x} (this build knows {FLAG_PACKED_RUNS:#x}, packed runs, \
         {FLAG_CHUNK:#x}, a chunk, {FLAG_STAGGERED_GRID:#x}, staggered pixel grids, and \
         {FLAG_TURNED_FRAME:#x}, turned cube maps): a \
         corrupted file or one from a newer build"
    )]
    UnsupportedFlags {
        /// Flags found in the header.
        flags: u32,
    },
    /// A chunk of a chunked bake where a whole file was expected.
    #[error(
        "one chunk of a chunked bake (cssm bake --chunk), not a whole file: join the chunks \
         with cssm merge"
    )]
    IsChunk,
    /// A whole file where a chunk was expected.
    #[error("a whole .cssm file, not a chunk of a chunked bake (cssm bake --chunk)")]
    NotAChunk,
    /// The header's compressed length does not match the bytes that follow it.
    #[error(
        "header says {expected} payload bytes follow but {actual} do: file is {}",
        if .actual < .expected { "truncated" } else { "followed by trailing garbage" }
    )]
    LengthMismatch {
        /// Compressed length from the header.
        expected: u64,
        /// Bytes actually present after the header.
        actual: u64,
    },
    /// The checksum of the compressed payload does not match.
    #[error("payload checksum mismatch: the file is corrupted")]
    ChecksumMismatch,
    /// The declared uncompressed size is above [`MAX_UNCOMPRESSED_BYTES`].
    #[error(
        "declared uncompressed size {len} bytes exceeds the limit of {MAX_UNCOMPRESSED_BYTES} bytes"
    )]
    TooLarge {
        /// Declared (or, when encoding, actual) uncompressed size.
        len: u64,
    },
    /// The header claims a payload that inflates far beyond what zstd gives real files (a
    /// "zstd bomb"): refused before a byte is inflated.
    #[error(
        "the header says {compressed} compressed bytes inflate to {uncompressed}, more than \
         {MAX_ZSTD_RATIO} times their size: a corrupted or hostile file"
    )]
    ImplausibleRatio {
        /// Compressed length from the header.
        compressed: u64,
        /// Uncompressed length from the header.
        uncompressed: u64,
    },
    /// Memory for the uncompressed payload could not be reserved.
    #[error("cannot allocate {len} bytes for the uncompressed payload")]
    OutOfMemory {
        /// Requested size.
        len: u64,
    },
    /// zstd failed to decompress the payload.
    #[error("corrupted payload: zstd: {0}")]
    Decompress(String),
    /// The payload decompressed to a different size than the header declares.
    #[error("corrupted payload: decompressed to {actual} bytes, header says {expected}")]
    DecodedLength {
        /// Size from the header.
        expected: u64,
        /// Size actually decompressed (capped at `expected + 1`).
        actual: u64,
    },
    /// The decompressed payload is not a bincode-encoded [`CssmFile`].
    #[error("malformed payload: {0}")]
    Malformed(String),
    /// Encoding (bincode or zstd) failed.
    #[error("cannot encode .cssm: {0}")]
    Encode(String),
    /// The contents are inconsistent (see [`validate`]).
    ///
    /// [`validate`]: fn@validate
    #[error("invalid .cssm contents: {0}")]
    Invalid(String),
}

impl CssmError {
    /// The error without any [`CssmError::File`] wrapper: handy to match on the kind.
    pub fn root(&self) -> &CssmError {
        match self {
            CssmError::File { inner, .. } => inner.root(),
            other => other,
        }
    }
}

/// Encodes `file` into the bytes of a `.cssm` file with the default [`FileCoding`]. Validates it
/// first ([`validate`]), so that nothing is written that [`decode`] would refuse. Deterministic.
///
/// [`validate`]: fn@validate
pub fn encode(file: &CssmFile) -> Result<Vec<u8>, CssmError> {
    encode_with(file, FileCoding::default())
}

/// [`encode`] with the run data coded as `coding` says.
pub fn encode_with(file: &CssmFile, coding: FileCoding) -> Result<Vec<u8>, CssmError> {
    let (mut bytes, head) = encode_into(file, coding, vec![0u8; HEADER_LEN])?;
    bytes[..HEADER_LEN].copy_from_slice(&head);
    Ok(bytes)
}

/// Validates `file`, then streams its payload into `out` (after whatever `out` already holds)
/// and returns `out` with the header that belongs in front of the payload.
fn encode_into<W: Write>(
    file: &CssmFile,
    coding: FileCoding,
    out: W,
) -> Result<(W, Vec<u8>), CssmError> {
    validate(file)?;
    let grid = layout_flags(file);
    match coding {
        FileCoding::Plain => compress_payload(grid, file, out),
        FileCoding::Packed => {
            // Borrow-free copy of the small tables; the run data is replaced by its packed form.
            let packed = PackedFile {
                params: file.params.clone(),
                scene: file.scene.clone(),
                texels: file.texels.clone(),
                triangle_uvs: file.triangle_uvs.clone(),
                sequence: file.sequence.clone(),
                hierarchy: file.hierarchy.clone(),
                map_count: file.runs.map_count,
                pixel_count: file.runs.pixel_count,
                runs: PackedRuns::pack(&file.runs),
                csms: file.csms.clone(),
            };
            compress_payload(FLAG_PACKED_RUNS | grid, &packed, out)
        }
    }
}

/// Decodes the bytes of a `.cssm` file: header, checksum, bounded decompression, bincode, then
/// [`validate`]. Never panics on any input.
///
/// [`validate`]: fn@validate
pub fn decode(bytes: &[u8]) -> Result<CssmFile, CssmError> {
    let (flags, raw) = unframe(bytes)?;
    if flags & FLAG_CHUNK != 0 {
        return Err(CssmError::IsChunk);
    }
    let mut file: CssmFile = if flags & FLAG_PACKED_RUNS != 0 {
        let p: PackedFile = decode_body(&raw)?;
        // The sizes the run data will be unpacked to must agree with the tables already read
        // (which the payload's own length bounds) before anything is allocated for it.
        if p.map_count as usize != p.texels.len() || p.map_count == 0 {
            return Err(CssmError::Invalid(format!(
                "map_count {} for {} texels",
                p.map_count,
                p.texels.len()
            )));
        }
        let n = p.params.cube_resolution;
        if !CUBE_RESOLUTION_RANGE.contains(&n) || p.pixel_count != 6 * n * n {
            return Err(CssmError::Invalid(format!(
                "pixel_count {} for cube resolution {n}",
                p.pixel_count
            )));
        }
        let runs = p.runs.unpack(p.map_count, p.pixel_count)?;
        CssmFile {
            params: p.params,
            scene: p.scene,
            texels: p.texels,
            triangle_uvs: p.triangle_uvs,
            sequence: p.sequence,
            hierarchy: p.hierarchy,
            runs,
            csms: p.csms,
            pixel_grid: Default::default(),
            cube_frame: Default::default(),
        }
    } else {
        decode_body(&raw)?
    };
    apply_layout_flags(&mut file, flags);
    validate(&file)?;
    Ok(file)
}

/// The header flags that store `file`'s pixel grid and cube frame.
fn layout_flags(file: &CssmFile) -> u32 {
    let grid = match file.pixel_grid {
        crate::cube::PixelGrid::Centred => 0,
        crate::cube::PixelGrid::Staggered => FLAG_STAGGERED_GRID,
    };
    let frame = match file.cube_frame {
        crate::cube::CubeFrame::World => 0,
        crate::cube::CubeFrame::Turned => FLAG_TURNED_FRAME,
    };
    grid | frame
}

/// Sets `file`'s pixel grid and cube frame from the header flags `flags`.
fn apply_layout_flags(file: &mut CssmFile, flags: u32) {
    file.pixel_grid = if flags & FLAG_STAGGERED_GRID != 0 {
        crate::cube::PixelGrid::Staggered
    } else {
        crate::cube::PixelGrid::Centred
    };
    file.cube_frame = if flags & FLAG_TURNED_FRAME != 0 {
        crate::cube::CubeFrame::Turned
    } else {
        crate::cube::CubeFrame::World
    };
}

/// Reads and decodes the `.cssm` file at `path`. Every error names the path.
///
/// Only a regular file is read (a FIFO or a device is refused before it is opened), and of it
/// first the header: a foreign file, however large, is refused after its first bytes; a file
/// longer than its header says is refused before the rest is read.
pub fn read(path: &Path) -> Result<CssmFile, CssmError> {
    let bytes = read_bytes(path)?;
    decode(&bytes).map_err(|e| CssmError::File {
        path: path.to_path_buf(),
        inner: Box::new(e),
    })
}

/// The bytes of the file at `path` after the checks of its header that [`read`] makes before
/// reading the rest (regular file, header, length); errors name the path.
fn read_bytes(path: &Path) -> Result<Vec<u8>, CssmError> {
    let io = |error| CssmError::Io {
        path: path.to_path_buf(),
        error,
    };
    let in_file = |e| CssmError::File {
        path: path.to_path_buf(),
        inner: Box::new(e),
    };
    let (file, size) = crate::files::open_regular(path).map_err(io)?;
    let mut reader = std::io::BufReader::new(file);
    let mut bytes = Vec::new();
    (&mut reader)
        .take(HEADER_LEN as u64)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    framing::check_header(&bytes).map_err(in_file)?;
    // The header is whole and ours: the payload must be exactly what it declares.
    let total = HEADER_LEN as u64 + u64::from_le_bytes(bytes[24..32].try_into().expect("8 bytes"));
    if size != total {
        return Err(in_file(CssmError::LengthMismatch {
            expected: total - HEADER_LEN as u64,
            actual: size.saturating_sub(HEADER_LEN as u64),
        }));
    }
    bytes
        .try_reserve_exact((total as usize).saturating_sub(bytes.len()))
        .map_err(|_| in_file(CssmError::OutOfMemory { len: total }))?;
    reader
        .take(total + 1 - HEADER_LEN as u64)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    Ok(bytes)
}
