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
//! | 4     | flags, `u32` LE: 0, or [`FLAG_PACKED_RUNS`] |
//! | 8     | uncompressed payload length, `u64` LE (at most [`MAX_UNCOMPRESSED_BYTES`]) |
//! | 8     | compressed payload length, `u64` LE (= the rest of the file) |
//! | 16    | checksum: first 16 bytes of BLAKE3 of the compressed payload |
//! | ...   | payload: zstd (level [`ZSTD_LEVEL`]) of the bincode 2 (serde, standard config) encoding of [`CssmFile`] (flags 0), or of the same fields with the run data entropy-coded as [`PackedRuns`] ([`FLAG_PACKED_RUNS`]) |
//!
//! The body's fields, in order: params, scene, texels, triangle_uvs, sequence, hierarchy
//! ([`Hierarchy`], since version 2), then the run data.
//!
//! The entropy stage ([`FileCoding::Packed`], the default since it makes files smaller) changes
//! only the file: it decodes to exactly the same [`RunData`], the layout the GPU queries. Files
//! without it (flags 0) are read as well; a build that predates it refuses packed files with
//! "unsupported header flags". Version-1 files (before the hierarchy) are refused with
//! [`CssmError::UnsupportedVersion`]: re-bake them.
//!
//! Encoding is deterministic: the same [`CssmFile`] always gives the same bytes. Decoding checks
//! every field before trusting it, bounds every allocation, and finishes with [`validate`].

use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::hierarchy::Hierarchy;
use crate::texel::{Texel, Traversal};

/// First eight bytes of every `.cssm` file.
pub const MAGIC: [u8; 8] = *b"CSSM\x00\r\n\x1a";
/// Version written by this build; files with a larger version are refused as "newer", files with
/// a smaller one as unsupported (version 2 added the texel [`Hierarchy`]; re-bake older files).
pub const FORMAT_VERSION: u32 = 2;
/// Number of consecutive depth maps per run-data segment: run starts are stored relative to
/// their segment in 16 bits, so a segment holds at most 2^16 maps.
pub const SEGMENT_MAPS: u32 = 1 << 16;
/// Largest uncompressed payload a file may declare (8 GiB); larger ones are refused before any
/// allocation.
pub const MAX_UNCOMPRESSED_BYTES: u64 = 8 << 30;
/// zstd compression level of the payload (19 is far too slow for large bakes).
pub const ZSTD_LEVEL: i32 = 9;
/// Header flag: the run data is entropy-coded ([`PackedRuns`]) inside the payload.
pub const FLAG_PACKED_RUNS: u32 = 1;
/// Size of the fixed header in bytes.
pub const HEADER_LEN: usize = 8 + 4 + 4 + 8 + 8 + 16;
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
    /// Absolute path of the scene directory at bake time.
    pub dir: String,
    /// Scene name (from `scene.toml`, or the directory name).
    pub name: String,
    /// BLAKE3 hash over the scene's files (see `scene::Scene::content_hash`).
    pub content_hash: [u8; 32],
    /// Number of triangles of the loaded scene (a cheap second check).
    pub triangle_count: u32,
}

/// Piecewise-constant runs of every cube-map pixel along the depth-map sequence, laid out for
/// random access by (map index, pixel) (§3.1, §3.2).
///
/// The sequence of `map_count` maps is cut into segments of [`SEGMENT_MAPS`] maps. For segment
/// `s` and pixel `p` (`p = face * N * N + row * N + col`), the runs are
/// `runs[offsets[s * pixel_count + p] .. offsets[s * pixel_count + p + 1]]`, sorted by start;
/// the first one starts at 0. A run is one `u32`: `(start_within_segment << 16) | depth16`.
/// The depth of map `m` at pixel `p` is the value of the last run of segment `m / SEGMENT_MAPS`
/// whose start is `<= m % SEGMENT_MAPS`: a binary search over a handful of entries.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunData {
    /// Number of depth maps (= defined texels).
    pub map_count: u32,
    /// Pixels per cube map, `6 * N * N`.
    pub pixel_count: u32,
    /// `segment_count * pixel_count + 1` prefix offsets into `runs`.
    pub offsets: Vec<u32>,
    /// Packed runs, `(start_within_segment << 16) | depth16`.
    pub runs: Vec<u32>,
}

impl RunData {
    /// Number of segments of [`SEGMENT_MAPS`] maps.
    pub fn segment_count(&self) -> u32 {
        self.map_count.div_ceil(SEGMENT_MAPS)
    }

    /// Quantised depth of map `map` at pixel `pixel`. Both must be in range.
    #[inline]
    pub fn lookup(&self, map: u32, pixel: u32) -> u16 {
        let segment = map / SEGMENT_MAPS;
        let local = map % SEGMENT_MAPS;
        let slot = (segment * self.pixel_count + pixel) as usize;
        let (lo, hi) = (self.offsets[slot] as usize, self.offsets[slot + 1] as usize);
        let runs = &self.runs[lo..hi];
        // Last run whose start <= local: partition point of "start <= local".
        let idx = runs.partition_point(|&r| (r >> 16) <= local);
        (runs[idx.max(1) - 1] & 0xFFFF) as u16
    }

    /// Bytes the random-access run data occupies in GPU memory: offsets plus runs.
    pub fn gpu_bytes(&self) -> u64 {
        4 * (self.offsets.len() as u64 + self.runs.len() as u64)
    }

    /// Uncompressed size, the denominator of every ratio: 2 bytes per cube-map pixel (paper,
    /// Tables 2 and 3).
    pub fn uncompressed_bytes(&self) -> u64 {
        2 * self.map_count as u64 * self.pixel_count as u64
    }
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

/// The entropy-coded form of a [`RunData`] (the file's "entropy stage"; the GPU keeps
/// [`RunData`]). Three streams, slot by slot in `(segment, pixel)` order: `counts` holds each
/// slot's number of runs (LEB128 varints); `lengths` every run's length in maps but each slot's
/// last (varints; the first run starts at 0); `depths` every run's depth as the 16-bit wrapping
/// difference (little-endian) to the depth that the *previous slot* (the neighbouring pixel)
/// holds at the run's start, since neighbouring pixels see nearly the same depths. Separate
/// streams keep similar numbers together for zstd. On the Cornell box (atlas 128, cube 32) the
/// file shrinks by about a quarter against zstd of the plain layout.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PackedRuns {
    /// Runs per slot.
    pub counts: Vec<u8>,
    /// Run lengths (maps), all but each slot's last run.
    pub lengths: Vec<u8>,
    /// Depth differences to the previous slot, 2 bytes each.
    pub depths: Vec<u8>,
}

fn put_varint(out: &mut Vec<u8>, mut v: u32) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Reads varints from a byte stream, refusing overlong or truncated ones.
struct VarintReader<'a> {
    bytes: &'a [u8],
    at: usize,
    name: &'static str,
}

impl VarintReader<'_> {
    fn next(&mut self) -> Result<u32, CssmError> {
        let mut v: u64 = 0;
        for shift in (0..35).step_by(7) {
            let Some(&b) = self.bytes.get(self.at) else {
                return Err(CssmError::Malformed(format!(
                    "packed runs: the {} stream ends early",
                    self.name
                )));
            };
            self.at += 1;
            v |= u64::from(b & 0x7F) << shift;
            if b & 0x80 == 0 {
                return u32::try_from(v).map_err(|_| {
                    CssmError::Malformed(format!("packed runs: a {} value overflows", self.name))
                });
            }
        }
        Err(CssmError::Malformed(format!(
            "packed runs: an over-long varint in the {} stream",
            self.name
        )))
    }

    fn finish(&self) -> Result<(), CssmError> {
        if self.at != self.bytes.len() {
            return Err(CssmError::Malformed(format!(
                "packed runs: {} trailing bytes in the {} stream",
                self.bytes.len() - self.at,
                self.name
            )));
        }
        Ok(())
    }
}

/// Depth that the runs of a slot (sorted by start) hold at map `start` of the segment, walking
/// `cursor` forward (starts are visited in increasing order); 0 for an empty slot.
#[inline]
fn depth_at(slot: &[u32], cursor: &mut usize, start: u32) -> u16 {
    while *cursor + 1 < slot.len() && slot[*cursor + 1] >> 16 <= start {
        *cursor += 1;
    }
    slot.get(*cursor).map_or(0, |&r| (r & 0xFFFF) as u16)
}

impl PackedRuns {
    /// Packs run data (deterministic).
    pub fn pack(runs: &RunData) -> PackedRuns {
        let mut p = PackedRuns::default();
        let mut prev: &[u32] = &[];
        for w in runs.offsets.windows(2) {
            let slot = &runs.runs[w[0] as usize..w[1] as usize];
            put_varint(&mut p.counts, slot.len() as u32);
            let mut cursor = 0;
            for (i, &r) in slot.iter().enumerate() {
                if let Some(&next) = slot.get(i + 1) {
                    put_varint(&mut p.lengths, (next >> 16) - (r >> 16));
                }
                let predicted = depth_at(prev, &mut cursor, r >> 16);
                let delta = ((r & 0xFFFF) as u16).wrapping_sub(predicted);
                p.depths.extend_from_slice(&delta.to_le_bytes());
            }
            prev = slot;
        }
        p
    }

    /// Unpacks into the run data of `map_count` maps of `pixel_count` pixels. Every count is
    /// checked against the bytes left before anything is allocated for it (a slot takes at least
    /// one byte of `counts`, a run two of `depths`), so a damaged stream cannot make this
    /// allocate more than its own size allows. The result still has to pass [`validate`].
    pub fn unpack(&self, map_count: u32, pixel_count: u32) -> Result<RunData, CssmError> {
        let slots = u64::from(map_count.div_ceil(SEGMENT_MAPS)) * u64::from(pixel_count);
        if slots > self.counts.len() as u64 {
            return Err(CssmError::Malformed(format!(
                "packed runs: {slots} slots but only {} count bytes",
                self.counts.len()
            )));
        }
        if self.depths.len() % 2 != 0 {
            return Err(CssmError::Malformed(
                "packed runs: the depth stream has an odd length".into(),
            ));
        }
        let mut counts = VarintReader {
            bytes: &self.counts,
            at: 0,
            name: "count",
        };
        let mut lengths = VarintReader {
            bytes: &self.lengths,
            at: 0,
            name: "length",
        };
        let mut offsets = Vec::with_capacity(slots as usize + 1);
        offsets.push(0u32);
        let mut total: u64 = 0;
        for _ in 0..slots {
            let c = counts.next()?;
            if c == 0 {
                return Err(CssmError::Malformed(
                    "packed runs: a slot with no runs".into(),
                ));
            }
            total += u64::from(c);
            if total > self.depths.len() as u64 / 2 {
                return Err(CssmError::Malformed(format!(
                    "packed runs: {total} runs but only {} depth bytes",
                    self.depths.len()
                )));
            }
            offsets.push(total as u32);
        }
        counts.finish()?;
        if total != self.depths.len() as u64 / 2 {
            return Err(CssmError::Malformed(format!(
                "packed runs: {} trailing bytes in the depth stream",
                self.depths.len() as u64 - 2 * total
            )));
        }
        let mut runs: Vec<u32> = Vec::with_capacity(total as usize);
        let mut prev = 0..0;
        for w in offsets.windows(2) {
            let here = runs.len();
            let mut start: u32 = 0;
            let mut cursor = 0;
            for i in w[0]..w[1] {
                if i > w[0] {
                    let len = lengths.next()?;
                    start = start
                        .checked_add(len)
                        .filter(|&s| len > 0 && s < SEGMENT_MAPS)
                        .ok_or_else(|| {
                            CssmError::Malformed(
                                "packed runs: a run start beyond its segment".into(),
                            )
                        })?;
                }
                let predicted = depth_at(&runs[prev.clone()], &mut cursor, start);
                let at = 2 * i as usize;
                let delta = u16::from_le_bytes([self.depths[at], self.depths[at + 1]]);
                runs.push((start << 16) | u32::from(predicted.wrapping_add(delta)));
            }
            prev = here..runs.len();
        }
        lengths.finish()?;
        Ok(RunData {
            map_count,
            pixel_count,
            offsets,
            runs,
        })
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
    /// The version is older than (or otherwise unknown to) this build.
    #[error(
        "file version {version} is not supported (this build reads version {FORMAT_VERSION}); re-bake it"
    )]
    UnsupportedVersion {
        /// Version found in the header.
        version: u32,
    },
    /// Reserved flag bits are set.
    #[error("unsupported header flags {flags:#x} (this build knows none); corrupted or newer file")]
    UnsupportedFlags {
        /// Flags found in the header.
        flags: u32,
    },
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

const BINCODE_LIMIT: usize = if (usize::MAX as u64) < MAX_UNCOMPRESSED_BYTES {
    usize::MAX
} else {
    MAX_UNCOMPRESSED_BYTES as usize
};

fn bincode_config() -> impl bincode::config::Config {
    bincode::config::standard().with_limit::<BINCODE_LIMIT>()
}

fn checksum(payload: &[u8]) -> [u8; 16] {
    let hash = blake3::hash(payload);
    let mut out = [0u8; 16];
    out.copy_from_slice(&hash.as_bytes()[..16]);
    out
}

/// The fixed header of a file whose zstd payload has `compressed_len` bytes with `sum` as
/// checksum, and `uncompressed_len` bytes once decompressed.
fn header(flags: u32, uncompressed_len: u64, compressed_len: u64, sum: [u8; 16]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER_LEN);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&flags.to_le_bytes());
    out.extend_from_slice(&uncompressed_len.to_le_bytes());
    out.extend_from_slice(&compressed_len.to_le_bytes());
    out.extend_from_slice(&sum);
    out
}

/// Encodes `file` into the bytes of a `.cssm` file with the default [`FileCoding`]. Validates it
/// first ([`validate`]), so that nothing is written that [`decode`] would refuse. Deterministic.
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
    match coding {
        FileCoding::Plain => compress_payload(0, file, out),
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
            };
            compress_payload(FLAG_PACKED_RUNS, &packed, out)
        }
    }
}

/// bincode of `body` streamed through zstd into `out`; returns `out` and the header (with
/// `flags`) for the payload written.
fn compress_payload<T: Serialize, W: Write>(
    flags: u32,
    body: &T,
    out: W,
) -> Result<(W, Vec<u8>), CssmError> {
    // Stream bincode straight into zstd and zstd straight into `out`, counting and hashing on
    // the way, so neither the uncompressed body (hundreds of MiB for a 512 atlas) nor the
    // compressed one need exist in memory as a whole when `out` is a file.
    let hashing = HashingWriter {
        inner: out,
        hasher: blake3::Hasher::new(),
        count: 0,
    };
    let mut encoder = zstd::stream::Encoder::new(hashing, ZSTD_LEVEL)
        .map_err(|e| CssmError::Encode(format!("zstd: {e}")))?;
    // zstd's multi-threaded output is the same for any number of workers, so this stays
    // deterministic while compressing on every core.
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get()) as u32;
    encoder
        .multithread(workers)
        .map_err(|e| CssmError::Encode(format!("zstd: {e}")))?;
    let mut sink = CountingWriter {
        inner: encoder,
        count: 0,
    };
    bincode::serde::encode_into_std_write(body, &mut sink, bincode_config())
        .map_err(|e| CssmError::Encode(format!("bincode: {e}")))?;
    let uncompressed_len = sink.count;
    if uncompressed_len > MAX_UNCOMPRESSED_BYTES {
        return Err(CssmError::TooLarge {
            len: uncompressed_len,
        });
    }
    let hashing = sink
        .inner
        .finish()
        .map_err(|e| CssmError::Encode(format!("zstd: {e}")))?;
    let mut sum = [0u8; 16];
    sum.copy_from_slice(&hashing.hasher.finalize().as_bytes()[..16]);
    Ok((
        hashing.inner,
        header(flags, uncompressed_len, hashing.count, sum),
    ))
}

/// A writer that counts and BLAKE3-hashes what passes through it.
struct HashingWriter<W> {
    inner: W,
    hasher: blake3::Hasher,
    count: u64,
}

impl<W: Write> Write for HashingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.hasher.update(&buf[..n]);
        self.count += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

/// A writer that counts what passes through it.
struct CountingWriter<W> {
    inner: W,
    count: u64,
}

impl<W: std::io::Write> std::io::Write for CountingWriter<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.count += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().expect("4 bytes"))
}

fn u64_at(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().expect("8 bytes"))
}

/// Checks the header and checksum, decompresses (bounded), and returns the flags and the raw
/// payload.
fn unframe(bytes: &[u8]) -> Result<(u32, Vec<u8>), CssmError> {
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
        // A short prefix of a real file is "truncated", anything else is foreign.
        if bytes.len() < MAGIC.len() && MAGIC.starts_with(bytes) {
            return Err(CssmError::TooShort { len: bytes.len() });
        }
        return Err(CssmError::NotCssm);
    }
    if bytes.len() < HEADER_LEN {
        return Err(CssmError::TooShort { len: bytes.len() });
    }
    let version = u32_at(bytes, 8);
    if version > FORMAT_VERSION {
        return Err(CssmError::NewerVersion { version });
    }
    if version != FORMAT_VERSION {
        return Err(CssmError::UnsupportedVersion { version });
    }
    let flags = u32_at(bytes, 12);
    if flags & !FLAG_PACKED_RUNS != 0 {
        return Err(CssmError::UnsupportedFlags { flags });
    }
    let uncompressed_len = u64_at(bytes, 16);
    let compressed_len = u64_at(bytes, 24);
    let sum: [u8; 16] = bytes[32..48].try_into().expect("16 bytes");
    let payload = &bytes[HEADER_LEN..];
    if compressed_len != payload.len() as u64 {
        return Err(CssmError::LengthMismatch {
            expected: compressed_len,
            actual: payload.len() as u64,
        });
    }
    if checksum(payload) != sum {
        return Err(CssmError::ChecksumMismatch);
    }
    if uncompressed_len > MAX_UNCOMPRESSED_BYTES || uncompressed_len > usize::MAX as u64 / 2 {
        return Err(CssmError::TooLarge {
            len: uncompressed_len,
        });
    }
    let mut out = Vec::new();
    out.try_reserve_exact(uncompressed_len as usize)
        .map_err(|_| CssmError::OutOfMemory {
            len: uncompressed_len,
        })?;
    let decoder = zstd::stream::read::Decoder::with_buffer(payload)
        .map_err(|e| CssmError::Decompress(e.to_string()))?;
    decoder
        .take(uncompressed_len + 1)
        .read_to_end(&mut out)
        .map_err(|e| CssmError::Decompress(e.to_string()))?;
    if out.len() as u64 != uncompressed_len {
        return Err(CssmError::DecodedLength {
            expected: uncompressed_len,
            actual: out.len() as u64,
        });
    }
    Ok((flags, out))
}

/// Decodes the bytes of a `.cssm` file: header, checksum, bounded decompression, bincode, then
/// [`validate`]. Never panics on any input.
pub fn decode(bytes: &[u8]) -> Result<CssmFile, CssmError> {
    let (flags, raw) = unframe(bytes)?;
    let file = if flags & FLAG_PACKED_RUNS != 0 {
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
        }
    } else {
        decode_body(&raw)?
    };
    validate(&file)?;
    Ok(file)
}

/// bincode-decodes the whole of `raw`.
fn decode_body<T: serde::de::DeserializeOwned>(raw: &[u8]) -> Result<T, CssmError> {
    let (body, used): (T, usize) = bincode::serde::decode_from_slice(raw, bincode_config())
        .map_err(|e| CssmError::Malformed(e.to_string()))?;
    if used != raw.len() {
        return Err(CssmError::Malformed(format!(
            "{} trailing bytes after the encoded contents",
            raw.len() - used
        )));
    }
    Ok(body)
}

/// Reads and decodes the `.cssm` file at `path`. Every error names the path.
pub fn read(path: &Path) -> Result<CssmFile, CssmError> {
    let bytes = std::fs::read(path).map_err(|error| CssmError::Io {
        path: path.to_path_buf(),
        error,
    })?;
    decode(&bytes).map_err(|e| CssmError::File {
        path: path.to_path_buf(),
        inner: Box::new(e),
    })
}

/// Writes `file` to `path` atomically (see [`write_bytes_atomic`]) with the default
/// [`FileCoding`]. Returns the number of bytes written.
pub fn write_atomic(path: &Path, file: &CssmFile) -> Result<u64, CssmError> {
    write_atomic_with(path, file, FileCoding::default())
}

/// [`write_atomic`] with the run data coded as `coding` says.
///
/// The payload is streamed into the temporary file and the header written last, so the file's
/// bytes are never all in memory at once (the same bytes as [`encode_with`]).
pub fn write_atomic_with(
    path: &Path,
    file: &CssmFile,
    coding: FileCoding,
) -> Result<u64, CssmError> {
    // Check before creating anything, so an invalid file leaves nothing behind.
    validate(file)?;
    let mut written = 0;
    write_atomic_by(path, &mut |f, tmp| {
        let io = |error| CssmError::Io {
            path: tmp.to_path_buf(),
            error,
        };
        f.write_all(&[0u8; HEADER_LEN]).map_err(io)?;
        let (out, head) = encode_into(file, coding, std::io::BufWriter::new(&mut *f))?;
        out.into_inner().map_err(|e| io(e.into_error()))?;
        f.seek(std::io::SeekFrom::Start(0)).map_err(io)?;
        f.write_all(&head).map_err(io)?;
        written = f.seek(std::io::SeekFrom::End(0)).map_err(io)?;
        Ok(())
    })?;
    Ok(written)
}

/// Writes `bytes` to `path` atomically: a temporary file `.NAME.tmp-PID` in the same directory,
/// fsynced, then renamed over `path`. On any error the temporary file is removed and `path` is
/// left untouched. Used for `.cssm` files and for the reports.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<(), CssmError> {
    write_atomic_by(path, &mut |f, tmp| {
        f.write_all(bytes).map_err(|error| CssmError::Io {
            path: tmp.to_path_buf(),
            error,
        })
    })
}

/// The temporary-file-and-rename frame of the atomic writes: `fill(file, temporary path)`
/// writes the contents.
fn write_atomic_by(
    path: &Path,
    fill: &mut dyn FnMut(&mut std::fs::File, &Path) -> Result<(), CssmError>,
) -> Result<(), CssmError> {
    let name = path.file_name().ok_or_else(|| CssmError::Io {
        path: path.to_path_buf(),
        error: std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file path"),
    })?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    let tmp = dir.join(tmp_name);

    let result = (|| -> Result<(), CssmError> {
        let io = |error| CssmError::Io {
            path: tmp.clone(),
            error,
        };
        let mut f = std::fs::File::create(&tmp).map_err(io)?;
        fill(&mut f, &tmp)?;
        f.sync_all().map_err(io)?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(|error| CssmError::Io {
            path: path.to_path_buf(),
            error,
        })?;
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        // Name the destination too when the failure was on the temporary file.
        return Err(match e {
            CssmError::Io { path: p, error } if p == tmp => CssmError::Io {
                path: path.to_path_buf(),
                error: std::io::Error::new(
                    error.kind(),
                    format!("writing temporary file {}: {error}", p.display()),
                ),
            },
            other => other,
        });
    }
    // Best effort: persist the rename itself.
    #[cfg(unix)]
    if let Ok(d) = std::fs::File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

macro_rules! invalid {
    ($($arg:tt)*) => {
        return Err(CssmError::Invalid(format!($($arg)*)))
    };
}

/// Semantic checks of a [`CssmFile`]: parameter ranges, table sizes, the sequence being a
/// permutation, texel coordinates in range and unique, finite geometry, the hierarchy
/// ([`Hierarchy::validate`]: a well-formed tree over the texels), and the run-data layout
/// (offsets, run starts) that [`RunData::lookup`] relies on. [`decode`] and [`encode`] call it;
/// the bake can call it on its own output.
pub fn validate(file: &CssmFile) -> Result<(), CssmError> {
    let p = &file.params;
    if !ATLAS_RESOLUTION_RANGE.contains(&p.atlas_resolution) {
        invalid!(
            "atlas_resolution {} outside {}..={}",
            p.atlas_resolution,
            ATLAS_RESOLUTION_RANGE.start(),
            ATLAS_RESOLUTION_RANGE.end()
        );
    }
    if !CUBE_RESOLUTION_RANGE.contains(&p.cube_resolution) {
        invalid!(
            "cube_resolution {} outside {}..={}",
            p.cube_resolution,
            CUBE_RESOLUTION_RANGE.start(),
            CUBE_RESOLUTION_RANGE.end()
        );
    }
    if !(p.near.is_finite() && p.near > 0.0) {
        invalid!("near {} must be finite and > 0", p.near);
    }
    if !(p.far.is_finite() && p.far > p.near) {
        invalid!("far {} must be finite and > near {}", p.far, p.near);
    }
    let r = &file.runs;
    let n = p.cube_resolution;
    if r.pixel_count != 6 * n * n {
        invalid!(
            "pixel_count {} != 6 * {n} * {n} = {}",
            r.pixel_count,
            6 * n * n
        );
    }
    let maps = r.map_count as usize;
    if maps == 0 {
        invalid!("no depth maps (map_count 0)");
    }
    if file.texels.len() != maps || file.sequence.len() != maps {
        invalid!(
            "map_count {maps}, {} texels and {} sequence entries must all be equal",
            file.texels.len(),
            file.sequence.len()
        );
    }
    if file.triangle_uvs.len() as u64 != file.scene.triangle_count as u64 {
        invalid!(
            "{} triangle_uvs for a scene of {} triangles",
            file.triangle_uvs.len(),
            file.scene.triangle_count
        );
    }
    if let Some(t) = file
        .triangle_uvs
        .iter()
        .position(|uv| uv.iter().flatten().any(|c| !c.is_finite()))
    {
        invalid!("triangle_uvs[{t}] is not finite");
    }
    let mut seen = vec![false; maps];
    for (k, &t) in file.sequence.iter().enumerate() {
        match seen.get_mut(t as usize) {
            None => invalid!("sequence[{k}] = {t} is not a texel index (< {maps})"),
            Some(s) if *s => invalid!("sequence[{k}] = {t} repeats a texel: not a permutation"),
            Some(s) => *s = true,
        }
    }
    let res = p.atlas_resolution as usize;
    let mut used = vec![false; res * res];
    for (i, t) in file.texels.iter().enumerate() {
        if t.x as usize >= res || t.y as usize >= res {
            invalid!(
                "texel {i} at ({}, {}) outside the {res}x{res} atlas",
                t.x,
                t.y
            );
        }
        let slot = &mut used[t.y as usize * res + t.x as usize];
        if *slot {
            invalid!("texel {i} at ({}, {}) duplicates another texel", t.x, t.y);
        }
        *slot = true;
        if !(t.position.iter().all(|c| c.is_finite()) && t.normal.iter().all(|c| c.is_finite())) {
            invalid!("texel {i} has a non-finite position or normal");
        }
        if !(t.area.is_finite() && t.area >= 0.0) {
            invalid!("texel {i} has invalid area {}", t.area);
        }
    }
    if let Err(e) = file.hierarchy.validate(maps) {
        invalid!("hierarchy: {e}");
    }
    let segments = r.segment_count() as u64;
    let slots = segments * r.pixel_count as u64;
    if r.offsets.len() as u64 != slots + 1 {
        invalid!(
            "{} run offsets, expected segment_count * pixel_count + 1 = {}",
            r.offsets.len(),
            slots + 1
        );
    }
    if r.offsets[0] != 0 {
        invalid!("first run offset is {}, not 0", r.offsets[0]);
    }
    if *r.offsets.last().expect("non-empty") as usize != r.runs.len() {
        invalid!(
            "last run offset {} != number of runs {}",
            r.offsets.last().expect("non-empty"),
            r.runs.len()
        );
    }
    if let Some(i) = r.offsets.windows(2).position(|w| w[1] < w[0]) {
        invalid!(
            "run offsets decrease at segment {}, pixel {}",
            i / r.pixel_count as usize,
            i % r.pixel_count as usize
        );
    }
    for slot in 0..slots as usize {
        let (lo, hi) = (r.offsets[slot] as usize, r.offsets[slot + 1] as usize);
        let (segment, pixel) = (slot / r.pixel_count as usize, slot % r.pixel_count as usize);
        let in_segment = (maps - segment * SEGMENT_MAPS as usize).min(SEGMENT_MAPS as usize);
        let runs = &r.runs[lo..hi];
        let Some(first) = runs.first() else {
            invalid!("segment {segment}, pixel {pixel} has no runs");
        };
        if first >> 16 != 0 {
            invalid!(
                "segment {segment}, pixel {pixel}: first run starts at {}, not 0",
                first >> 16
            );
        }
        for w in runs.windows(2) {
            if w[1] >> 16 <= w[0] >> 16 {
                invalid!("segment {segment}, pixel {pixel}: run starts not strictly increasing");
            }
        }
        let last = (runs[runs.len() - 1] >> 16) as usize;
        if last >= in_segment {
            invalid!(
                "segment {segment}, pixel {pixel}: run starts at map {last}, segment has {in_segment}"
            );
        }
    }
    Ok(())
}
