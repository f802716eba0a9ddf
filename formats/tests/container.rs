//! Tests of the `.cssm` container: roundtrip, determinism, every refusal, atomic writes, and
//! fuzzing that decoding never panics.

use std::path::Path;

use cssm_formats::Hierarchy;
use cssm_formats::cssm::{
    self, CssmError, CssmFile, FLAG_PACKED_RUNS, FORMAT_VERSION, FileCoding, HEADER_LEN, MAGIC,
    PackedRuns, RunData,
};
use proptest::prelude::*;

#[path = "common/sample.rs"]
mod common_sample;
use common_sample::sample;

fn root(e: &CssmError) -> &CssmError {
    e.root()
}

/// Builds a file from a raw (bincode) payload with a correct header, following the documented
/// layout independently of the crate's encoder.
fn frame_raw(raw: &[u8]) -> Vec<u8> {
    frame_raw_flags(raw, 0)
}

/// [`frame_raw`] with header flags `flags`.
fn frame_raw_flags(raw: &[u8], flags: u32) -> Vec<u8> {
    let compressed = zstd::bulk::compress(raw, 3).unwrap();
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&flags.to_le_bytes());
    out.extend_from_slice(&(raw.len() as u64).to_le_bytes());
    out.extend_from_slice(&(compressed.len() as u64).to_le_bytes());
    out.extend_from_slice(&blake3::hash(&compressed).as_bytes()[..16]);
    out.extend_from_slice(&compressed);
    out
}

fn raw_payload(file: &CssmFile) -> Vec<u8> {
    bincode::serde::encode_to_vec(file, bincode::config::standard()).unwrap()
}

/// The decompressed payload of a file the crate wrote with the entropy stage.
fn packed_payload(file: &CssmFile) -> Vec<u8> {
    let bytes = cssm::encode_with(file, FileCoding::Packed).unwrap();
    assert_eq!(bytes[12..16], FLAG_PACKED_RUNS.to_le_bytes());
    zstd::decode_all(&bytes[HEADER_LEN..]).unwrap()
}

#[test]
fn roundtrip_and_lookup() {
    let f = sample();
    let bytes = cssm::encode(&f).unwrap();
    assert_eq!(&bytes[..8], &MAGIC);
    let back = cssm::decode(&bytes).unwrap();
    assert_eq!(back, f);
    assert_eq!(back.runs.lookup(0, 5), 5);
    assert_eq!(back.runs.lookup(1, 5), 0xABCD);
    assert_eq!(back.runs.lookup(1, 7), 7);
}

#[test]
fn header_layout_matches_documentation() {
    let f = sample();
    let ours = cssm::encode_with(&f, FileCoding::Plain).unwrap();
    // Same header fields as an independent framing of the same payload (zstd level may differ).
    let theirs = frame_raw(&raw_payload(&f));
    assert_eq!(ours[..24], theirs[..24]);
    assert_eq!(cssm::decode(&theirs).unwrap(), f);
}

#[test]
fn encode_is_deterministic() {
    let f = sample();
    let a = cssm::encode(&f).unwrap();
    let b = cssm::encode(&f.clone()).unwrap();
    assert_eq!(a, b);
    let c = cssm::encode(&cssm::decode(&a).unwrap()).unwrap();
    assert_eq!(a, c);
}

#[test]
fn truncated_files_are_refused() {
    let bytes = cssm::encode(&sample()).unwrap();
    for len in [
        0,
        3,
        8,
        12,
        20,
        HEADER_LEN - 1,
        HEADER_LEN,
        HEADER_LEN + 1,
        bytes.len() - 1,
    ] {
        let err = cssm::decode(&bytes[..len]).unwrap_err();
        match err {
            CssmError::TooShort { .. } => assert!(len < HEADER_LEN, "len {len}"),
            CssmError::LengthMismatch { .. } => {
                assert!(len >= HEADER_LEN);
                assert!(err.to_string().contains("truncated"), "{err}");
            }
            other => panic!("len {len}: unexpected {other:?}"),
        }
    }
}

#[test]
fn trailing_garbage_is_refused() {
    let mut bytes = cssm::encode(&sample()).unwrap();
    bytes.extend_from_slice(b"junk");
    let err = cssm::decode(&bytes).unwrap_err();
    assert!(matches!(err, CssmError::LengthMismatch { .. }), "{err:?}");
    assert!(err.to_string().contains("trailing garbage"), "{err}");
}

#[test]
fn flipped_payload_byte_is_a_checksum_error() {
    let bytes = cssm::encode(&sample()).unwrap();
    for at in [HEADER_LEN, HEADER_LEN + 7, bytes.len() - 1] {
        let mut b = bytes.clone();
        b[at] ^= 0x40;
        let err = cssm::decode(&b).unwrap_err();
        assert!(matches!(err, CssmError::ChecksumMismatch), "{err:?}");
        assert!(err.to_string().contains("corrupted"));
    }
    // A flipped checksum byte too.
    let mut b = bytes.clone();
    b[40] ^= 1;
    assert!(matches!(cssm::decode(&b), Err(CssmError::ChecksumMismatch)));
}

#[test]
fn foreign_files_are_refused() {
    let mut bytes = cssm::encode(&sample()).unwrap();
    bytes[0] = b'X';
    let err = cssm::decode(&bytes).unwrap_err();
    assert!(matches!(err, CssmError::NotCssm));
    assert!(err.to_string().contains("not a .cssm file"));
    assert!(matches!(
        cssm::decode(b"# a text file, certainly not a cssm container\n"),
        Err(CssmError::NotCssm)
    ));
    assert!(matches!(cssm::decode(b"PK"), Err(CssmError::NotCssm)));
}

#[test]
fn versions_and_flags() {
    assert_eq!(FORMAT_VERSION, 4);
    let bytes = cssm::encode(&sample()).unwrap();
    assert_eq!(bytes[8..12], 4u32.to_le_bytes());
    let mut newer = bytes.clone();
    newer[8..12].copy_from_slice(&5u32.to_le_bytes());
    let err = cssm::decode(&newer).unwrap_err();
    assert!(matches!(err, CssmError::NewerVersion { version: 5 }));
    assert!(
        err.to_string()
            .contains("file version 5 is newer than this build's version 4; upgrade cssm"),
        "{err}"
    );
    // Versions 2 (before the coherent shadow maps of rigid objects) and 3 (before the texels'
    // objects): re-bake.
    for version in [2u32, 3] {
        let mut old = bytes.clone();
        old[8..12].copy_from_slice(&version.to_le_bytes());
        let err = cssm::decode(&old).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "file version {version} is not supported (this build reads version 4); re-bake it"
            )
        );
    }
    let mut older = bytes.clone();
    older[8..12].copy_from_slice(&1u32.to_le_bytes());
    assert!(matches!(
        cssm::decode(&older),
        Err(CssmError::UnsupportedVersion { version: 1 })
    ));
    // A flipped bit or byte in the version field is corruption, not a newer build's file.
    for version in [
        0u32,
        FORMAT_VERSION | 1 << 31,
        FORMAT_VERSION | 0x80 << 8,
        FORMAT_VERSION + 1 + cssm::PLAUSIBLE_NEWER_VERSIONS,
    ] {
        let mut corrupt = bytes.clone();
        corrupt[8..12].copy_from_slice(&version.to_le_bytes());
        let err = cssm::decode(&corrupt).unwrap_err();
        assert!(
            matches!(err, CssmError::CorruptVersion { .. }),
            "{version:#x}: {err}"
        );
        assert!(err.to_string().starts_with("corrupted header"), "{err}");
    }
    // A version-1 file (written before the hierarchy): the body of a version-1 file, framed
    // with version 1, is refused by its version before anything is decoded.
    let f = sample();
    let v1_body = (
        &f.params,
        &f.scene,
        &f.texels,
        &f.triangle_uvs,
        &f.sequence,
        &f.runs,
    );
    let mut v1 =
        frame_raw(&bincode::serde::encode_to_vec(v1_body, bincode::config::standard()).unwrap());
    v1[8..12].copy_from_slice(&1u32.to_le_bytes());
    let err = cssm::decode(&v1).unwrap_err();
    assert!(
        matches!(err, CssmError::UnsupportedVersion { version: 1 }),
        "{err:?}"
    );
    assert_eq!(
        err.to_string(),
        "file version 1 is not supported (this build reads version 4); re-bake it"
    );
    // Bit 1 is a chunk of a chunked bake (FLAG_CHUNK), bit 2 staggered pixel grids, bit 3
    // turned cube maps, bit 4 nothing yet.
    let mut flags = bytes.clone();
    flags[12] = 16;
    assert!(matches!(
        cssm::decode(&flags),
        Err(CssmError::UnsupportedFlags { flags: 16 })
    ));
    flags[12] = bytes[12] | 8;
    let turned = cssm::decode(&flags).unwrap();
    assert_eq!(turned.cube_frame, cssm_formats::cube::CubeFrame::Turned);
    assert_eq!(turned.pixel_grid, cssm_formats::cube::PixelGrid::Centred);
    assert_eq!(cssm::encode(&turned).unwrap(), flags);
    assert_eq!(
        cssm::decode(&bytes).unwrap().cube_frame,
        cssm_formats::cube::CubeFrame::World,
        "a file without the flag has its faces on the world's axes"
    );
    flags[12] = bytes[12] | 4;
    let staggered = cssm::decode(&flags).unwrap();
    assert_eq!(
        staggered.pixel_grid,
        cssm_formats::cube::PixelGrid::Staggered
    );
    assert_eq!(cssm::encode(&staggered).unwrap(), flags);
    flags[12] = 2;
    assert!(matches!(cssm::decode(&flags), Err(CssmError::IsChunk)));
}

#[test]
fn huge_uncompressed_len_is_refused_before_allocating() {
    let bytes = cssm::encode(&sample()).unwrap();
    for len in [u64::MAX, cssm::MAX_UNCOMPRESSED_BYTES + 1] {
        let mut b = bytes.clone();
        b[16..24].copy_from_slice(&len.to_le_bytes());
        let err = cssm::decode(&b).unwrap_err();
        assert!(matches!(err, CssmError::TooLarge { .. }), "{err:?}");
    }
    // A lie within the limit is caught after bounded decompression.
    let real = u64::from_le_bytes(bytes[16..24].try_into().unwrap());
    for len in [0, real - 1, real + 1, 1 << 20] {
        let mut b = bytes.clone();
        b[16..24].copy_from_slice(&len.to_le_bytes());
        let err = cssm::decode(&b).unwrap_err();
        assert!(matches!(err, CssmError::DecodedLength { .. }), "{err:?}");
    }
}

#[test]
fn malformed_payloads() {
    let err = cssm::decode(&frame_raw(b"definitely not bincode")).unwrap_err();
    assert!(matches!(err, CssmError::Malformed(_)), "{err:?}");
    let mut raw = raw_payload(&sample());
    raw.push(0);
    let err = cssm::decode(&frame_raw(&raw)).unwrap_err();
    assert!(matches!(err, CssmError::Malformed(_)), "{err:?}");
    let err = cssm::decode(&frame_raw(&[])).unwrap_err();
    assert!(matches!(err, CssmError::Malformed(_)), "{err:?}");
}

#[test]
fn both_file_codings_decode_to_the_same_file() {
    let f = sample();
    let plain = cssm::encode_with(&f, FileCoding::Plain).unwrap();
    let packed = cssm::encode_with(&f, FileCoding::Packed).unwrap();
    assert_eq!(plain[12..16], 0u32.to_le_bytes());
    assert_eq!(cssm::encode(&f).unwrap(), packed, "packed is the default");
    assert_eq!(cssm::decode(&plain).unwrap(), f);
    assert_eq!(cssm::decode(&packed).unwrap(), f);
    // A file written before the entropy stage (flags 0, bincode of CssmFile) still reads.
    assert_eq!(cssm::decode(&frame_raw(&raw_payload(&f))).unwrap(), f);
}

/// Bad packed streams: each gives a clear error, never a panic or a huge allocation.
#[test]
fn bad_packed_runs_are_refused() {
    let f = sample();
    let good = PackedRuns::pack(&f.runs);
    assert_eq!(
        good.unpack(f.runs.map_count, f.runs.pixel_count).unwrap(),
        f.runs
    );
    let (maps, pixels) = (f.runs.map_count, f.runs.pixel_count);
    let refused = |p: &PackedRuns, maps: u32, pixels: u32, needle: &str| {
        let err = p.unpack(maps, pixels).unwrap_err();
        assert!(matches!(err, CssmError::Malformed(_)), "{err:?}");
        assert!(err.to_string().contains(needle), "{needle}: {err}");
    };
    // More slots than count bytes: refused before allocating the offsets.
    refused(&good, 1 << 31, u32::MAX, "slots but only");
    let mut p = good.clone();
    p.counts[0] = 0;
    refused(&p, maps, pixels, "no runs");
    let mut p = good.clone();
    p.counts[0] = 0xFF; // an unfinished varint swallowing the next count
    refused(&p, maps, pixels, "");
    let mut p = good.clone();
    p.counts = vec![0xFF; pixels as usize + 8];
    refused(&p, maps, pixels, "over-long varint");
    let mut p = good.clone();
    p.counts[0] = 0x7F; // 127 runs in the first slot: more than the depth bytes left
    p.depths.truncate(100);
    refused(&p, maps, pixels, "depth bytes");
    let mut p = good.clone();
    p.counts.push(1);
    refused(&p, maps, pixels, "trailing bytes in the count stream");
    let mut p = good.clone();
    p.depths.extend_from_slice(&[0, 0]);
    refused(&p, maps, pixels, "trailing bytes in the depth stream");
    let mut p = good.clone();
    p.depths.push(0);
    refused(&p, maps, pixels, "odd length");
    let mut p = good.clone();
    p.lengths.clear();
    refused(&p, maps, pixels, "length stream ends early");
    let mut p = good.clone();
    p.lengths.push(1);
    refused(&p, maps, pixels, "trailing bytes in the length stream");
    let mut p = good.clone();
    p.lengths = vec![0];
    refused(&p, maps, pixels, "beyond its segment");
    let mut p = good.clone();
    p.lengths = vec![0x80, 0x80, 0x04]; // 65536
    refused(&p, maps, pixels, "beyond its segment");
    // Any depth difference decodes to some depth: a flipped depth byte is a different file,
    // caught by the checksum in a real file, never a panic here.
    let mut p = good.clone();
    p.depths[0] ^= 0xFF;
    assert_ne!(p.unpack(maps, pixels).unwrap(), f.runs);
}

#[test]
fn packed_files_with_wrong_sizes_are_refused_before_unpacking() {
    // Re-frame a packed payload whose map count disagrees with its texel table.
    let mut f = sample();
    let raw = packed_payload(&f);
    assert_eq!(
        cssm::decode(&frame_raw_flags(&raw, FLAG_PACKED_RUNS)).unwrap(),
        f
    );
    // Flags 0 on a packed payload: not a plain CssmFile.
    assert!(cssm::decode(&frame_raw(&raw)).is_err());
    f.params.cube_resolution = 16; // pixel_count 384 no longer matches 6 * 16 * 16
    let err = cssm::decode(&frame_raw_flags(
        &packed_payload_unchecked(&f),
        FLAG_PACKED_RUNS,
    ))
    .unwrap_err();
    assert!(matches!(err, CssmError::Invalid(_)), "{err:?}");
    assert!(err.to_string().contains("pixel_count"), "{err}");
}

/// Like [`packed_payload`] for a file that does not validate: the payload is written by hand
/// in the documented field order (the crate's encoder validates first).
fn packed_payload_unchecked(f: &CssmFile) -> Vec<u8> {
    let body = (
        &f.params,
        &f.scene,
        &f.texels,
        &f.triangle_uvs,
        &f.sequence,
        &f.hierarchy,
        f.runs.map_count,
        f.runs.pixel_count,
        PackedRuns::pack(&f.runs),
        &f.csms,
    );
    bincode::serde::encode_to_vec(body, bincode::config::standard()).unwrap()
}

type Mutation = (&'static str, fn(&mut CssmFile));

#[test]
fn every_validation_failure_is_reported() {
    let cases: &[Mutation] = &[
        ("atlas_resolution", |f| f.params.atlas_resolution = 16),
        ("atlas_resolution", |f| f.params.atlas_resolution = 2048),
        ("cube_resolution", |f| f.params.cube_resolution = 4),
        ("cube_resolution", |f| f.params.cube_resolution = 256),
        ("near", |f| f.params.near = 0.0),
        ("near", |f| f.params.near = f32::NAN),
        ("far", |f| f.params.far = 0.001),
        ("far", |f| f.params.far = f32::INFINITY),
        ("pixel_count", |f| f.runs.pixel_count += 1),
        ("map_count", |f| f.runs.map_count = 3),
        ("map_count", |f| {
            f.sequence.push(2);
        }),
        ("no depth maps", |f| {
            f.runs.map_count = 0;
            f.texels.clear();
            f.sequence.clear();
        }),
        ("permutation", |f| f.sequence = vec![1, 1]),
        ("not a texel index", |f| f.sequence = vec![0, 2]),
        ("outside the 32x32 atlas", |f| f.texels[1].x = 32),
        ("outside the 32x32 atlas", |f| f.texels[0].y = 40),
        ("duplicates another texel", |f| f.texels[1] = f.texels[0]),
        ("non-finite position or normal", |f| {
            f.texels[0].position[1] = f32::NAN
        }),
        ("non-finite position or normal", |f| {
            f.texels[1].normal[2] = f32::INFINITY
        }),
        ("invalid area", |f| f.texels[1].area = -1.0),
        ("triangle_uvs", |f| f.scene.triangle_count = 3),
        ("triangle_uvs[1] is not finite", |f| {
            f.triangle_uvs[1][2][0] = f32::NAN
        }),
        ("run offsets", |f| {
            f.runs.offsets.pop();
        }),
        ("first run offset", |f| f.runs.offsets[0] = 1),
        ("last run offset", |f| {
            f.runs.runs.push(0);
        }),
        ("offsets decrease", |f| {
            f.runs.offsets[3] = 100;
            f.runs.offsets[4] = 2;
        }),
        ("has no runs", |f| {
            // Pixel 2 and 3 swap a run: pixel 2 empty, pixel 3 two runs.
            f.runs.offsets[3] = f.runs.offsets[2];
            f.runs.runs[2] = 0;
            f.runs.runs[3] = 1 << 16;
        }),
        ("not 0", |f| f.runs.runs[0] = 1 << 16),
        ("strictly increasing", |f| f.runs.runs[6] = 0x1234),
        ("segment has 2", |f| f.runs.runs[6] = (2 << 16) | 1),
        // The hierarchy: root 0 over leaves 1 and 2.
        ("hierarchy: node 1: skip 3, expected 2", |f| {
            f.hierarchy.nodes[1].skip = 3
        }),
        ("hierarchy: root node: first 0, count 2, skip 2", |f| {
            f.hierarchy.nodes[0].skip = 2
        }),
        (
            "hierarchy: leaf_texels[1] = 0 repeats a texel: not a permutation",
            |f| f.hierarchy.leaf_texels = vec![0, 0],
        ),
        ("hierarchy: leaf_texels[0] = 2 is not a texel index", |f| {
            f.hierarchy.leaf_texels[0] = 2
        }),
        ("hierarchy: 2 nodes, expected 2 * 2 texels - 1 = 3", |f| {
            f.hierarchy.nodes.pop();
        }),
        ("hierarchy: 4 nodes, expected", |f| {
            let extra = f.hierarchy.nodes[2];
            f.hierarchy.nodes.push(extra);
        }),
        ("hierarchy: 0 nodes, expected", |f| {
            f.hierarchy = Hierarchy::default()
        }),
        ("hierarchy: node 0: a non-finite value", |f| {
            f.hierarchy.nodes[0].radius = f32::NAN
        }),
        ("hierarchy: node 2: a non-finite value", |f| {
            f.hierarchy.nodes[2].normal[1] = f32::INFINITY
        }),
        ("hierarchy: node 1: negative radius", |f| {
            f.hierarchy.nodes[1].radius = -0.5
        }),
        ("hierarchy: node 0: cone_cos", |f| {
            f.hierarchy.nodes[0].cone_cos = -1.5
        }),
        ("hierarchy: node 2: representative 7", |f| {
            f.hierarchy.nodes[2].representative = 7
        }),
        ("hierarchy: node 1: leaves", |f| {
            f.hierarchy.nodes[1].first = 2
        }),
    ];
    for (expect, mutate) in cases {
        let mut f = sample();
        mutate(&mut f);
        let err = cssm::validate(&f).expect_err(expect);
        assert!(matches!(err, CssmError::Invalid(_)), "{expect}: {err:?}");
        assert!(
            err.to_string().contains(expect),
            "expected `{expect}` in: {err}"
        );
        // decode of such a file refuses it too, and encode never writes it.
        assert!(matches!(
            cssm::decode(&frame_raw(&raw_payload(&f))),
            Err(CssmError::Invalid(_))
        ));
        assert!(matches!(cssm::encode(&f), Err(CssmError::Invalid(_))));
    }
    cssm::validate(&sample()).unwrap();
}

/// Recognises the expected error kind.
type ErrorCheck = fn(&CssmError) -> bool;

/// The damaged files of `tests/bad/`, generated at run time into `dir`.
fn write_bad_files(dir: &Path) -> Vec<(&'static str, ErrorCheck)> {
    let good = cssm::encode(&sample()).unwrap();
    let mut corrupt = good.clone();
    let mid = HEADER_LEN + (good.len() - HEADER_LEN) / 2;
    corrupt[mid] ^= 0xFF;
    let mut newer = good.clone();
    newer[8..12].copy_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
    let files: [(&str, Vec<u8>); 4] = [
        ("truncated.cssm", good[..good.len() / 2].to_vec()),
        ("corrupt.cssm", corrupt),
        (
            "foreign.cssm",
            b"\x89PNG\r\n\x1a\n0000000000000000000000000000000000000000".to_vec(),
        ),
        ("newer-version.cssm", newer),
    ];
    for (name, bytes) in &files {
        std::fs::write(dir.join(name), bytes).unwrap();
    }
    vec![
        ("truncated.cssm", |e| {
            matches!(e, CssmError::LengthMismatch { .. })
        }),
        ("corrupt.cssm", |e| matches!(e, CssmError::ChecksumMismatch)),
        ("foreign.cssm", |e| matches!(e, CssmError::NotCssm)),
        ("newer-version.cssm", |e| {
            matches!(e, CssmError::NewerVersion { .. })
        }),
    ]
}

#[test]
fn bad_files_are_refused_with_their_path() {
    let dir = tempfile::tempdir().unwrap();
    for (name, is_expected) in write_bad_files(dir.path()) {
        let path = dir.path().join(name);
        let err = cssm::read(&path).unwrap_err();
        assert!(is_expected(root(&err)), "{name}: {err:?}");
        assert!(
            err.to_string().contains(&path.display().to_string()),
            "{err}"
        );
    }
    let missing = dir.path().join("missing.cssm");
    let err = cssm::read(&missing).unwrap_err();
    assert!(matches!(err, CssmError::Io { .. }));
    assert!(err.to_string().contains("missing.cssm"), "{err}");
}

#[test]
fn write_atomic_success_leaves_only_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.cssm");
    let f = sample();
    let n = cssm::write_atomic(&path, &f).unwrap();
    assert_eq!(n, std::fs::metadata(&path).unwrap().len());
    assert_eq!(cssm::read(&path).unwrap(), f);
    // Overwrite with a different file.
    let mut g = f.clone();
    g.scene.name = "other".into();
    cssm::write_atomic(&path, &g).unwrap();
    assert_eq!(cssm::read(&path).unwrap(), g);
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names, vec!["out.cssm".to_string()]);
}

#[test]
fn write_atomic_failure_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("no-such-dir").join("out.cssm");
    let err = cssm::write_atomic(&path, &sample()).unwrap_err();
    assert!(matches!(err, CssmError::Io { .. }), "{err:?}");
    assert!(
        err.to_string().contains(&path.display().to_string()),
        "{err}"
    );
    assert!(!path.exists());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);

    // An invalid file is refused before anything is written, and an existing file survives.
    let path = dir.path().join("keep.cssm");
    cssm::write_atomic(&path, &sample()).unwrap();
    let mut bad = sample();
    bad.sequence = vec![0, 0];
    assert!(matches!(
        cssm::write_atomic(&path, &bad),
        Err(CssmError::Invalid(_))
    ));
    assert_eq!(cssm::read(&path).unwrap(), sample());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

    // Renaming over a directory fails: the temporary file is cleaned up.
    let path = dir.path().join("a-directory");
    std::fs::create_dir(&path).unwrap();
    std::fs::write(path.join("x"), b"x").unwrap();
    assert!(cssm::write_atomic(&path, &sample()).is_err());
    let mut names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(
        names,
        vec!["a-directory".to_string(), "keep.cssm".to_string()]
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn decoding_arbitrary_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = cssm::decode(&bytes);
        let mut with_magic = MAGIC.to_vec();
        with_magic.extend_from_slice(&bytes);
        let _ = cssm::decode(&with_magic);
    }

    #[test]
    fn decoding_mutated_files_never_panics(
        flips in proptest::collection::vec((any::<prop::sample::Index>(), 1u8..=255), 1..8),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
    ) {
        let mut bytes = cssm::encode(&sample()).unwrap();
        for (at, x) in &flips {
            let i = at.index(bytes.len());
            bytes[i] ^= x;
        }
        if truncate {
            bytes.truncate(cut.index(bytes.len()));
        }
        prop_assert!(cssm::decode(&bytes).is_err());
    }

    #[test]
    fn packed_runs_roundtrip(
        counts in proptest::collection::vec(1u32..6, 1..40),
        seed in any::<u64>(),
    ) {
        // Random run data with `counts[s]` runs in each slot of 2 segments.
        let pixel_count = counts.len() as u32;
        let map_count = cssm::SEGMENT_MAPS + 10;
        let mut state = seed;
        let mut next = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        let mut offsets = vec![0u32];
        let mut runs = Vec::new();
        for segment in 0..2u32 {
            let len = if segment == 0 { cssm::SEGMENT_MAPS } else { 10 };
            for &c in &counts {
                let c = c.min(len);
                let mut starts: Vec<u32> = (0..c).map(|k| if k == 0 { 0 } else { 1 + next() % (len - 1) }).collect();
                starts.sort_unstable();
                starts.dedup();
                for s in starts {
                    runs.push((s << 16) | (next() & 0xFFFF));
                }
                offsets.push(runs.len() as u32);
            }
        }
        let rd = RunData { map_count, pixel_count, offsets, runs };
        let packed = PackedRuns::pack(&rd);
        prop_assert_eq!(packed.unpack(map_count, pixel_count).unwrap(), rd);
    }

    #[test]
    fn decoding_mutated_packed_payloads_never_panics(
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
    ) {
        let mut raw = packed_payload(&sample());
        for (at, x) in &flips {
            let i = at.index(raw.len());
            raw[i] = *x;
        }
        if truncate {
            raw.truncate(cut.index(raw.len()));
        }
        if let Ok(f) = cssm::decode(&frame_raw_flags(&raw, FLAG_PACKED_RUNS)) {
            cssm::validate(&f).unwrap();
            for m in 0..f.runs.map_count {
                for p in 0..f.runs.pixel_count {
                    let _ = f.runs.lookup(m, p);
                }
            }
        }
    }

    #[test]
    fn decoding_mutated_payloads_never_panics(
        flips in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..8),
        cut in any::<prop::sample::Index>(),
        truncate in any::<bool>(),
    ) {
        // Mutate the bincode payload and re-frame it with a valid checksum, to reach the
        // bincode decoder and the validation.
        let mut raw = raw_payload(&sample());
        for (at, x) in &flips {
            let i = at.index(raw.len());
            raw[i] = *x;
        }
        if truncate {
            raw.truncate(cut.index(raw.len()));
        }
        if let Ok(f) = cssm::decode(&frame_raw(&raw)) {
            // Whatever decodes is valid, and every lookup stays in bounds.
            cssm::validate(&f).unwrap();
            for m in 0..f.runs.map_count {
                for p in 0..f.runs.pixel_count {
                    let _ = f.runs.lookup(m, p);
                }
            }
        }
    }
}

#[test]
fn streamed_writes_equal_the_encoded_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let f = sample();
    for coding in [FileCoding::Plain, FileCoding::Packed] {
        let path = dir.path().join(format!("{coding}.cssm"));
        let n = cssm::write_atomic_with(&path, &f, coding).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(n, bytes.len() as u64);
        assert_eq!(bytes, cssm::encode_with(&f, coding).unwrap(), "{coding}");
        assert_eq!(cssm::read(&path).unwrap(), f);
    }
    // An invalid file is refused before anything is created.
    let mut bad = sample();
    bad.params.near = -1.0;
    let path = dir.path().join("bad.cssm");
    assert!(cssm::write_atomic(&path, &bad).is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}
