//! The corpus of bad inputs in `tests/bad/` (issue 23): every file or scene directory listed in
//! `tests/bad/cases.txt` is given to the real `cssm` binary, which must refuse it with exit
//! status 2, the listed words in its message, no panic, within a time limit and a peak-memory
//! bound.
//!
//! The `.cssm` files of the corpus are made by [`corpus`] from the small hand-built file of
//! `formats/tests/common/sample.rs`, framed by hand or with `cssm::frame_payload` so that a
//! crafted payload passes the checksum and reaches the checks behind it. The test
//! `the_committed_corpus_is_what_the_generator_makes` holds the committed files to the
//! generator; after a format change, `CSSM_REGENERATE_BAD=1 cargo test --release --test
//! bad_inputs` rewrites them (then review the diff).

use std::{
    path::{Path, PathBuf},
    process::{Command, Stdio},
    time::{Duration, Instant},
};

use cssm_formats::cssm::{self, CssmFile, FLAG_PACKED_RUNS, HEADER_LEN};

#[path = "../formats/tests/common/sample.rs"]
mod sample;

/// Peak resident memory any refusal may take (a refusal measured 8 MiB; a valid inspect 9 MiB);
/// a file that makes `cssm` allocate what its header claims would be far above.
const PEAK_MEMORY_BOUND_BYTES: u64 = 64 << 20;
/// Longest any refusal may take.
const TIME_LIMIT: Duration = Duration::from_secs(30);

fn bad_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad")
}

/// The sample file, named as baked from `tests/bad/quad-scene` (the same triangle count and
/// content hash), so that a crafted file is refused for what was crafted and not for being
/// another scene's.
fn quad_file() -> CssmFile {
    let scene = cssm_formats::Scene::load(&bad_dir().join("quad-scene")).expect("quad scene");
    let mut file = sample::sample();
    file.scene.name = scene.name.clone();
    file.scene.dir = "tests/bad/quad-scene".into();
    file.scene.content_hash = scene.content_hash;
    file.scene.triangle_count = scene.triangles.len() as u32;
    file.triangle_uvs = vec![[[1.0, 1.0], [5.0, 1.0], [1.0, 5.0]]; scene.triangles.len()];
    cssm::validate(&file).expect("the quad file is valid");
    file
}

/// `file` framed without the validation `encode` runs: bincode of the plain body, then a
/// correct header and checksum.
fn framed_unchecked(file: &CssmFile) -> Vec<u8> {
    let raw = bincode::serde::encode_to_vec(file, bincode::config::standard()).expect("bincode");
    cssm::frame_payload(0, &raw).expect("frame")
}

/// A header (version, flags and declared sizes as given) with a zero checksum.
fn header(version: u32, flags: u32, uncompressed: u64, compressed: u64) -> Vec<u8> {
    let mut h = cssm::MAGIC.to_vec();
    h.extend_from_slice(&version.to_le_bytes());
    h.extend_from_slice(&flags.to_le_bytes());
    h.extend_from_slice(&uncompressed.to_le_bytes());
    h.extend_from_slice(&compressed.to_le_bytes());
    h.resize(HEADER_LEN, 0);
    h
}

/// Every `.cssm` file of the corpus: its path under `tests/bad/` and its bytes.
fn corpus() -> Vec<(&'static str, Vec<u8>)> {
    let good = quad_file();
    let bytes = cssm::encode(&good).expect("encode");
    let with = |edit: &dyn Fn(&mut Vec<u8>)| {
        let mut b = bytes.clone();
        edit(&mut b);
        b
    };
    let crafted = |edit: &dyn Fn(&mut CssmFile)| {
        let mut f = good.clone();
        edit(&mut f);
        framed_unchecked(&f)
    };
    // A zstd bomb: a real, checksum-valid frame of 1 MiB of zeros (a few dozen bytes) whose
    // header claims 6 GiB (the checksum covers only the compressed bytes).
    let mut bomb = cssm::frame_payload(0, &vec![0; 1 << 20]).expect("frame");
    bomb[16..24].copy_from_slice(&(6u64 << 30).to_le_bytes());
    // A checksum-valid packed payload whose first field, the parameters, is followed by a
    // texel count of 2^40 (bincode varint: 0xFD then 8 bytes) and nothing behind it.
    let mut huge_count =
        bincode::serde::encode_to_vec(&good.params, bincode::config::standard()).expect("bincode");
    huge_count
        .extend(bincode::serde::encode_to_vec(&good.scene, bincode::config::standard()).unwrap());
    huge_count.push(0xFD);
    huge_count.extend_from_slice(&(1u64 << 40).to_le_bytes());
    vec![
        (
            "cssm-truncated/half.cssm",
            bytes[..bytes.len() / 2].to_vec(),
        ),
        (
            "cssm-truncated/header-only.cssm",
            bytes[..HEADER_LEN].to_vec(),
        ),
        ("cssm-truncated/magic-only.cssm", bytes[..8].to_vec()),
        (
            "cssm-corrupt/payload-byte.cssm",
            with(&|b| *b.last_mut().unwrap() ^= 0x40),
        ),
        ("cssm-corrupt/checksum.cssm", with(&|b| b[40] ^= 1)),
        ("cssm-corrupt/version-bit.cssm", with(&|b| b[11] ^= 0x80)),
        ("cssm-corrupt/flags.cssm", with(&|b| b[12] |= 0x10)),
        (
            "cssm-foreign/png.cssm",
            b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR".to_vec(),
        ),
        (
            "cssm-foreign/text.cssm",
            b"# not a cssm file\nv 0 0 0\n".to_vec(),
        ),
        ("cssm-foreign/empty.cssm", Vec::new()),
        ("cssm-newer/version-5.cssm", with(&|b| b[8] = 5)),
        ("cssm-oversized/bomb.cssm", bomb),
        (
            "cssm-oversized/declared-9gib.cssm",
            header(cssm::FORMAT_VERSION, 0, 9 << 30, 1 << 30),
        ),
        (
            "cssm-oversized/texel-count.cssm",
            cssm::frame_payload(FLAG_PACKED_RUNS, &huge_count).expect("frame"),
        ),
        (
            "cssm-semantic/sequence-repeats.cssm",
            crafted(&|f| f.sequence = vec![0, 0]),
        ),
        (
            "cssm-semantic/hierarchy-pointer.cssm",
            crafted(&|f| f.hierarchy.leaf_texels[0] = 7),
        ),
        (
            "cssm-semantic/texel-outside-atlas.cssm",
            crafted(&|f| f.texels[1].x = 900),
        ),
        (
            "cssm-semantic/hierarchy-padding.cssm",
            crafted(&|f| f.hierarchy.nodes[0]._pad[1] = 7),
        ),
        (
            "cssm-semantic/uv-off-page.cssm",
            crafted(&|f| f.triangle_uvs[1][2] = [1.0e30, 2.0]),
        ),
        (
            "cssm-semantic/nan-position.cssm",
            crafted(&|f| f.texels[0].position[1] = f32::NAN),
        ),
        (
            "cssm-semantic/texel-material.cssm",
            framed_unchecked(&{
                let mut f = good.clone();
                f.texels[1].material = 99;
                f
            }),
        ),
        (
            "cssm-semantic/texel-object.cssm",
            framed_unchecked(&{
                let mut f = good.clone();
                f.texels[1].object = 7;
                f
            }),
        ),
        (
            "cssm-semantic/other-triangle-count.cssm",
            crafted(&|f| {
                f.scene.triangle_count = 3;
                f.triangle_uvs.push(f.triangle_uvs[0]);
            }),
        ),
    ]
}

#[test]
fn the_committed_corpus_is_what_the_generator_makes() {
    let regenerate = std::env::var_os("CSSM_REGENERATE_BAD").is_some();
    for (name, bytes) in corpus() {
        let path = bad_dir().join(name);
        if regenerate {
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(&path, &bytes).unwrap();
        }
        let committed = std::fs::read(&path)
            .unwrap_or_else(|e| panic!("{}: {e} (CSSM_REGENERATE_BAD=1 makes it)", path.display()));
        assert!(
            committed == bytes,
            "{name} differs from the generator's; regenerate with CSSM_REGENERATE_BAD=1 and \
             review the diff"
        );
    }
}

/// The peak resident memory of the children this process waited for, in bytes (Linux counts
/// `ru_maxrss` in KiB).
fn children_peak_memory() -> u64 {
    // SAFETY: getrusage writes the struct it is given.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let rc = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) };
    assert_eq!(rc, 0, "getrusage");
    usage.ru_maxrss as u64 * 1024
}

/// One line of `tests/bad/cases.txt`: `PATH | COMMAND | EXPECTED WORDS`.
struct Case {
    path: String,
    command: String,
    expected: String,
}

fn cases() -> Vec<Case> {
    let text = std::fs::read_to_string(bad_dir().join("cases.txt")).expect("cases.txt");
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| {
            let fields: Vec<&str> = l.split('|').map(str::trim).collect();
            assert_eq!(fields.len(), 3, "cases.txt: {l}");
            Case {
                path: fields[0].into(),
                command: fields[1].into(),
                expected: fields[2].into(),
            }
        })
        .collect()
}

/// Every case of `tests/bad/cases.txt`, one after the other (so that the children's peak
/// memory is each one's as it runs): exit status 2, the expected words, no panic, within
/// [`TIME_LIMIT`] and [`PEAK_MEMORY_BOUND_BYTES`]; nothing is written.
#[test]
fn every_bad_input_is_refused_in_words_within_the_bounds() {
    let out = tempfile::tempdir().unwrap();
    let bad = bad_dir();
    let cases = cases();
    // Every file of the corpus has a case.
    for (name, _) in corpus() {
        assert!(
            cases.iter().any(|c| c.path == name),
            "{name} has no case in cases.txt"
        );
    }
    for case in &cases {
        let path = bad.join(&case.path);
        assert!(path.exists(), "{}", path.display());
        let path = path.to_str().unwrap();
        let quad = bad.join("quad-scene");
        let output = out.path().join("out.cssm");
        let args: Vec<&str> = match case.command.as_str() {
            "inspect" => vec!["inspect", path],
            "check" => vec![
                "check",
                path,
                "--scene",
                quad.to_str().unwrap(),
                "--pairs",
                "100",
            ],
            "bake" => vec![
                "bake",
                path,
                "-o",
                output.to_str().unwrap(),
                "--atlas",
                "32",
                "--cube",
                "8",
            ],
            other => panic!("cases.txt: unknown command {other}"),
        };
        let start = Instant::now();
        // `CSSM_RELIABILITY_BIN` tests another build (reports/reliability.md).
        let binary = std::env::var_os("CSSM_RELIABILITY_BIN")
            .map_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_cssm")), PathBuf::from);
        let mut child = Command::new(binary)
            .args(&args)
            .current_dir(out.path())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed() > TIME_LIMIT {
                let _ = child.kill();
                panic!("{}: {} hung", case.path, case.command);
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let o = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        if std::env::var_os("CSSM_BAD_REPORT").is_some() {
            // One line per case for reports/reliability.md: what this build says.
            let first = stderr
                .lines()
                .find(|l| !l.starts_with("warning"))
                .unwrap_or("");
            eprintln!("CASE {} | {:?} | {first}", case.path, o.status.code());
            continue;
        }
        assert_eq!(o.status.code(), Some(2), "{}: {stderr}", case.path);
        assert!(
            stderr.contains(&case.expected),
            "{}: expected '{}' in: {stderr}",
            case.path,
            case.expected
        );
        assert!(!stderr.contains("panicked"), "{}: {stderr}", case.path);
        let peak = children_peak_memory();
        assert!(
            peak <= PEAK_MEMORY_BOUND_BYTES,
            "{}: peak memory {} MiB (so far)",
            case.path,
            peak >> 20
        );
        assert!(!output.exists(), "{}: wrote a file", case.path);
    }
}
