//! The framing of a `.cssm` file: the fixed header (magic, version, flags, lengths, checksum),
//! the bounded zstd stage and the bincode encoding of the payload, for writing and for reading.

use std::io::{Read, Write};

use serde::Serialize;

use super::CssmError;

/// First eight bytes of every `.cssm` file.
pub const MAGIC: [u8; 8] = *b"CSSM\x00\r\n\x1a";
/// Version written by this build; files with a larger version are refused as "newer", files with
/// a smaller one as unsupported (version 2 added the texel [`Hierarchy`], version 3 the rigid
/// objects' coherent shadow maps, version 4 the texels' objects, whose depth maps see their
/// own object only; re-bake older files).
///
/// [`Hierarchy`]: crate::hierarchy::Hierarchy
pub const FORMAT_VERSION: u32 = 4;
/// Largest uncompressed payload a file may declare (8 GiB); larger ones are refused before any
/// allocation.
pub const MAX_UNCOMPRESSED_BYTES: u64 = 8 << 30;
/// How many versions past [`FORMAT_VERSION`] a header may name and be taken for a newer
/// build's file; a larger number is a corrupted header.
pub const PLAUSIBLE_NEWER_VERSIONS: u32 = 64;
/// Largest ratio of a payload's declared uncompressed size to its compressed size, beyond
/// [`RATIO_FREE_BYTES`]. Real files' payloads inflate about 2 times (bincode of packed runs;
/// 2.1 for the Sibenik cathedral at atlas 256, 2.2 for the Cornell box at atlas 64);
/// zstd itself tops out near 32,000.
pub const MAX_ZSTD_RATIO: u64 = 1024;
/// A payload may always declare up to this many uncompressed bytes, whatever its ratio.
pub const RATIO_FREE_BYTES: u64 = 64 << 20;
/// zstd compression level of the payload (19 is far too slow for large bakes).
pub const ZSTD_LEVEL: i32 = 9;
/// Header flag: the run data is entropy-coded ([`PackedRuns`]) inside the payload.
///
/// [`PackedRuns`]: super::PackedRuns
pub const FLAG_PACKED_RUNS: u32 = 1;

/// Header flag of a file (or chunk) whose cube maps sample staggered pixel grids
/// ([`crate::cube::PixelGrid::Staggered`]); without it, the paper's centred grid. A build that
/// predates staggered grids refuses such a file as an unknown flag rather than misread it.
pub const FLAG_STAGGERED_GRID: u32 = 4;
/// Header flag of a file (or chunk) whose cube maps are turned against the world
/// ([`crate::cube::CubeFrame::Turned`]); without it, faces on the world's axes (the paper). A
/// build that predates turned cube maps refuses such a file as an unknown flag.
pub const FLAG_TURNED_FRAME: u32 = 8;
/// Size of the fixed header in bytes.
pub const HEADER_LEN: usize = 8 + 4 + 4 + 8 + 8 + 16;

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

/// bincode of `body` streamed through zstd into `out`; returns `out` and the header (with
/// `flags`) for the payload written.
pub(super) fn compress_payload<T: Serialize, W: Write>(
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

/// The bytes of a `.cssm` file whose payload, once decompressed, is `raw` (the bincode body)
/// with header flags `flags`: a valid header and checksum around any contents. For tests and
/// fuzzers that craft a file's contents, so that [`super::decode`] reaches the checks past
/// the checksum; the tool itself writes files with [`super::encode`].
///
/// ```
/// use cssm_formats::cssm;
/// // A checksum-valid frame around contents that are not a bake.
/// let bytes = cssm::frame_payload(0, b"not bincode of a bake").unwrap();
/// assert!(matches!(cssm::decode(&bytes), Err(cssm::CssmError::Malformed(_))));
/// ```
///
/// # Errors
/// [`CssmError::Encode`] when zstd fails.
pub fn frame_payload(flags: u32, raw: &[u8]) -> Result<Vec<u8>, CssmError> {
    let compressed =
        zstd::bulk::compress(raw, 1).map_err(|e| CssmError::Encode(format!("zstd: {e}")))?;
    let mut out = header(
        flags,
        raw.len() as u64,
        compressed.len() as u64,
        checksum(&compressed),
    );
    out.extend_from_slice(&compressed);
    Ok(out)
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

/// The checks of the fixed header alone (`bytes` holds at least its start): magic, length,
/// version, flags, and the declared sizes against [`MAX_UNCOMPRESSED_BYTES`] and
/// [`MAX_ZSTD_RATIO`]. [`super::read`] runs them before it reads the payload.
pub(super) fn check_header(bytes: &[u8]) -> Result<(), CssmError> {
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
    // A flipped bit in the version field is a corrupted file, not one from a newer build:
    // versions grow one at a time.
    if version == 0 || version > FORMAT_VERSION + PLAUSIBLE_NEWER_VERSIONS {
        return Err(CssmError::CorruptVersion { version });
    }
    if version > FORMAT_VERSION {
        return Err(CssmError::NewerVersion { version });
    }
    if version != FORMAT_VERSION {
        return Err(CssmError::UnsupportedVersion { version });
    }
    let flags = u32_at(bytes, 12);
    if flags & !(FLAG_PACKED_RUNS | super::FLAG_CHUNK | FLAG_STAGGERED_GRID | FLAG_TURNED_FRAME)
        != 0
    {
        return Err(CssmError::UnsupportedFlags { flags });
    }
    let (uncompressed_len, compressed_len) = (u64_at(bytes, 16), u64_at(bytes, 24));
    // zstd never grows data by more than a few bytes per block: a longer compressed payload
    // than any file's uncompressed one is a corrupted header (and would overflow the file
    // length computed from it).
    if compressed_len > MAX_UNCOMPRESSED_BYTES {
        return Err(CssmError::CorruptHeader(format!(
            "it declares {compressed_len} compressed bytes, more than the \
             {MAX_UNCOMPRESSED_BYTES} any file's payload may hold"
        )));
    }
    if uncompressed_len > MAX_UNCOMPRESSED_BYTES || uncompressed_len > usize::MAX as u64 / 2 {
        return Err(CssmError::TooLarge {
            len: uncompressed_len,
        });
    }
    // A zstd bomb: a small payload that claims to inflate past any real file's ratio is
    // refused before a byte is inflated.
    if uncompressed_len > RATIO_FREE_BYTES.max(compressed_len.saturating_mul(MAX_ZSTD_RATIO)) {
        return Err(CssmError::ImplausibleRatio {
            compressed: compressed_len,
            uncompressed: uncompressed_len,
        });
    }
    Ok(())
}

/// Checks the header and checksum, decompresses (bounded), and returns the flags and the raw
/// payload.
pub(super) fn unframe(bytes: &[u8]) -> Result<(u32, Vec<u8>), CssmError> {
    check_header(bytes)?;
    let flags = u32_at(bytes, 12);
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

/// bincode's decode error in words (its own `Display` prints the `Debug` form).
fn describe_decode_error(e: &bincode::error::DecodeError) -> String {
    use bincode::error::DecodeError as E;
    match e {
        E::UnexpectedEnd { additional } => {
            format!("the contents end early ({additional} more bytes expected)")
        }
        E::LimitExceeded => "a length in the contents is beyond the size limit".into(),
        E::InvalidIntegerType { .. } | E::NonZeroTypeIsZero { .. } => {
            "a number in the contents is not encoded as one".into()
        }
        E::UnexpectedVariant {
            type_name, found, ..
        } => format!("{found} is not a value of {type_name}"),
        E::Utf8 { .. } | E::InvalidCharEncoding(_) => "text that is not UTF-8".into(),
        E::InvalidBooleanValue(v) => format!("{v} where a true/false byte belongs"),
        E::ArrayLengthMismatch { required, found } => {
            format!("an array of {found} values where {required} belong")
        }
        E::OutsideUsizeRange(v) => format!("a length of {v}, beyond this machine's range"),
        E::Other(message) => (*message).to_string(),
        E::OtherString(message) => message.clone(),
        _ => "the contents are not a bake's encoding".into(),
    }
}

/// bincode-decodes the whole of `raw`.
///
/// bincode allocates a string's or byte array's declared length before it reads the bytes,
/// up to its configured limit: the limit is chosen from `raw`'s own length (the smallest of a
/// few steps at least twice it: at most four times the payload, and at least 1 MiB), so a
/// 17-byte payload declaring a 4 GiB name is refused instead of allocating 4 GiB (found by
/// fuzzing: `tests/fuzzed/cssm_payload/`). Everything the body holds is read from `raw`, so
/// no valid body claims more than `raw.len()` bytes.
pub(super) fn decode_body<T: serde::de::DeserializeOwned>(raw: &[u8]) -> Result<T, CssmError> {
    fn with_limit<T: serde::de::DeserializeOwned, const LIMIT: usize>(
        raw: &[u8],
    ) -> Result<(T, usize), bincode::error::DecodeError> {
        bincode::serde::decode_from_slice(raw, bincode::config::standard().with_limit::<LIMIT>())
    }
    // The limit on this machine's address space too (a 32-bit build caps every step).
    const fn step(bytes: u64) -> usize {
        if bytes > BINCODE_LIMIT as u64 {
            BINCODE_LIMIT
        } else {
            bytes as usize
        }
    }
    let claim = (raw.len() as u64).saturating_mul(2);
    let decoded = if claim <= 1 << 20 {
        with_limit::<T, { step(1 << 20) }>(raw)
    } else if claim <= 1 << 24 {
        with_limit::<T, { step(1 << 24) }>(raw)
    } else if claim <= 1 << 28 {
        with_limit::<T, { step(1 << 28) }>(raw)
    } else if claim <= 1 << 30 {
        with_limit::<T, { step(1 << 30) }>(raw)
    } else if claim <= 1 << 31 {
        with_limit::<T, { step(1 << 31) }>(raw)
    } else if claim <= 1 << 32 {
        with_limit::<T, { step(1 << 32) }>(raw)
    } else {
        with_limit::<T, BINCODE_LIMIT>(raw)
    };
    let (body, used) = decoded.map_err(|e| CssmError::Malformed(describe_decode_error(&e)))?;
    if used != raw.len() {
        return Err(CssmError::Malformed(format!(
            "{} trailing bytes after the encoded contents",
            raw.len() - used
        )));
    }
    Ok(body)
}
