//! The framing of a `.cssm` file: the fixed header (magic, version, flags, lengths, checksum),
//! the bounded zstd stage and the bincode encoding of the payload, for writing and for reading.

use std::io::{Read, Write};

use serde::Serialize;

use super::CssmError;

/// First eight bytes of every `.cssm` file.
pub const MAGIC: [u8; 8] = *b"CSSM\x00\r\n\x1a";
/// Version written by this build; files with a larger version are refused as "newer", files with
/// a smaller one as unsupported (version 2 added the texel [`Hierarchy`]; re-bake older files).
///
/// [`Hierarchy`]: crate::hierarchy::Hierarchy
pub const FORMAT_VERSION: u32 = 2;
/// Largest uncompressed payload a file may declare (8 GiB); larger ones are refused before any
/// allocation.
pub const MAX_UNCOMPRESSED_BYTES: u64 = 8 << 30;
/// zstd compression level of the payload (19 is far too slow for large bakes).
pub const ZSTD_LEVEL: i32 = 9;
/// Header flag: the run data is entropy-coded ([`PackedRuns`]) inside the payload.
///
/// [`PackedRuns`]: super::PackedRuns
pub const FLAG_PACKED_RUNS: u32 = 1;
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
pub(super) fn unframe(bytes: &[u8]) -> Result<(u32, Vec<u8>), CssmError> {
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

/// bincode-decodes the whole of `raw`.
pub(super) fn decode_body<T: serde::de::DeserializeOwned>(raw: &[u8]) -> Result<T, CssmError> {
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
