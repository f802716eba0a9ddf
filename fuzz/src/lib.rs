//! The bodies of the fuzz targets of `fuzz/fuzz_targets/`: one function per target, taking the
//! fuzzer's bytes, returning `Ok` when the input was accepted and `Err` with the library's
//! message when it was refused. A refusal is fine; a panic (here or in the library), an abort, a
//! run past libFuzzer's memory limit or timeout is a finding.
//!
//! | target | input | what runs |
//! |--------|-------|-----------|
//! | `cssm_header` | any bytes (short) | [`cssm::decode`] |
//! | `cssm_file` | any bytes (a whole file) | [`cssm::decode`], and [`cssm::read`] of the same bytes from a file: both must agree |
//! | `cssm_payload` | flag byte (bit 0: [`cssm::FLAG_PACKED_RUNS`]), then a raw bincode payload | [`cssm::frame_payload`] (a valid header and checksum), [`cssm::decode`], [`cssm::validate_for_scene`] against the built-in Cornell box |
//! | `scene_toml` | a `scene.toml` | [`Scene::load`] of a directory holding it and the built-in scenes' OBJs and MTLs |
//! | `obj_mtl` | an OBJ, then byte `0xFF`, then an MTL (no `0xFF`: no MTL file) | [`Scene::load`] of a directory holding `scene.obj` and `scene.mtl`, no `scene.toml` |
//!
//! Whatever the library accepts is then used as its callers use it, and must not panic either
//! ([`check_file`], [`check_scene`]): every run-data lookup, the hierarchy walked, visibility
//! queries, an encode / decode round trip; a loaded scene's indices and lengths consistent.
//! Oddities that are no crash (a default camera at infinity, say) are printed once per process
//! as `cssm-fuzz note: ...` on stderr.
//!
//! This file is shared with the root package's `tests/fuzzed.rs`, which includes it as a
//! module (`#[path = "../fuzz/src/lib.rs"] mod bodies;`) and replays every file of
//! `tests/fuzzed/<target>/` through the body of the same name ([`body`]). So it may use only what
//! the root package depends on: `cssm-formats`, `glam`, `serde`, `bincode` and std.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, Once, OnceLock, PoisonError};

use cssm_formats::cssm::{self, CssmFile, FileCoding, PackedRuns};
use cssm_formats::visibility::{QueryOptions, VisibilityQuery};
use cssm_formats::{BakeParams, Hierarchy, RunData, Scene, SceneRef, Texel, Traversal};

mod accepted;
mod scratch;
mod seeds;

pub use accepted::*;
pub use scratch::*;
pub use seeds::*;

/// The targets, in the order the README lists them: the folders of `fuzz/corpus/` and
/// `tests/fuzzed/`, the binaries of `fuzz/fuzz_targets/`.
pub const TARGETS: [&str; 6] = [
    "cssm_header",
    "cssm_file",
    "cssm_payload",
    "scene_toml",
    "obj_mtl",
    "gltf",
];

/// What a body returns: `Err` holds the message of a refused input.
pub type Outcome = Result<(), String>;

/// The body of the target named `target`.
pub fn body(target: &str) -> Option<fn(&[u8]) -> Outcome> {
    Some(match target {
        "cssm_header" => cssm_header,
        "cssm_file" => cssm_file,
        "cssm_payload" => cssm_payload,
        "scene_toml" => scene_toml,
        "obj_mtl" => obj_mtl,
        "gltf" => gltf,
        _ => return None,
    })
}

// ---------------------------------------------------------------------------------------------
// The bodies

/// `cssm_header`: [`cssm::decode`] of arbitrary (mostly short) bytes: the header checks.
pub fn cssm_header(data: &[u8]) -> Outcome {
    let file = cssm::decode(data).map_err(|e| e.to_string())?;
    check_file(&file, None);
    Ok(())
}

/// `cssm_file`: [`cssm::decode`] of arbitrary bytes, and [`cssm::read`] of the same bytes
/// written to a file (the runtime's path, which checks the header before it reads the rest):
/// both must accept the same inputs, and give the same contents.
pub fn cssm_file(data: &[u8]) -> Outcome {
    static DIR: ScratchDir = ScratchDir::new("cssm_file", &[]);
    let decoded = cssm::decode(data);
    let read = {
        let dir = DIR.lock();
        let path = dir.path().join("input.cssm");
        std::fs::write(&path, data).expect("write the scratch .cssm file");
        cssm::read(&path)
    };
    match (decoded, read) {
        (Ok(a), Ok(b)) => {
            assert!(
                a == b,
                "cssm::decode and cssm::read decode different contents"
            );
            check_file(&a, None);
            Ok(())
        }
        (Err(a), Err(_)) => Err(a.to_string()),
        (Ok(_), Err(e)) => panic!("cssm::decode accepts the bytes, cssm::read refuses them: {e}"),
        (Err(e), Ok(_)) => panic!("cssm::read accepts the bytes, cssm::decode refuses them: {e}"),
    }
}

/// `cssm_payload`: the first byte's bit 1 selects a chunk ([`cssm::FLAG_CHUNK`], decoded with
/// [`cssm::decode_chunk`]), else its bit 0 the flags (0, or [`cssm::FLAG_PACKED_RUNS`]),
/// the rest is a raw (bincode) payload, framed with a valid header and checksum by
/// [`cssm::frame_payload`] so that every mutation reaches bincode and the semantic checks; then
/// [`cssm::decode`] and, on success, [`cssm::validate_for_scene`] against the built-in Cornell
/// box, as the runtime does before rendering.
pub fn cssm_payload(data: &[u8]) -> Outcome {
    let Some((&first, raw)) = data.split_first() else {
        return Err("empty input".into());
    };
    if first & 2 != 0 {
        // A chunk of a chunked bake (`cssm bake --chunk`): one that passes its checks and is
        // the only chunk of its cut merges into a file that passes every check.
        let bytes = cssm::frame_payload(cssm::FLAG_CHUNK, raw).expect("frame_payload of any bytes");
        let chunk = cssm::decode_chunk(&bytes).map_err(|e| e.to_string())?;
        if chunk.spec().count() == 1 {
            let (file, _) = cssm::merge_chunks(vec![("input".into(), chunk)])
                .expect("a valid chunk 0/1 merges");
            check_file(&file, None);
        }
        return Ok(());
    }
    let flags = u32::from(first) & cssm::FLAG_PACKED_RUNS;
    let bytes = cssm::frame_payload(flags, raw).expect("frame_payload of any bytes");
    let file = cssm::decode(&bytes).map_err(|e| e.to_string())?;
    let scene = cornell_box();
    let for_scene = cssm::validate_for_scene(&file, scene);
    check_file(&file, for_scene.is_ok().then_some(scene));
    for_scene.map_err(|e| e.to_string())
}

/// `scene_toml`: [`Scene::load`] of a directory holding the input as `scene.toml` and the
/// meshes of the built-in scenes (`cornell-box.obj`, `cornell-glossy.obj` and their MTLs).
pub fn scene_toml(data: &[u8]) -> Outcome {
    static DIR: ScratchDir = ScratchDir::new("scene_toml", &MESHES);
    tolerate_caught_tobj_panics();
    let dir = DIR.lock();
    std::fs::write(dir.path().join("scene.toml"), data).expect("write the scratch scene.toml");
    let scene = Scene::load(dir.path()).map_err(|e| e.to_string())?;
    check_scene(&scene);
    Ok(())
}

/// `obj_mtl`: the input up to its first `0xFF` byte (which no UTF-8 text holds) is written as
/// `scene.obj`, the rest as `scene.mtl` (removed when there is no `0xFF`: a missing library);
/// then [`Scene::load`] of that directory, which has no `scene.toml`.
pub fn obj_mtl(data: &[u8]) -> Outcome {
    static DIR: ScratchDir = ScratchDir::new("obj_mtl", &[]);
    tolerate_caught_tobj_panics();
    let (obj, mtl) = split_obj_mtl(data);
    let dir = DIR.lock();
    std::fs::write(dir.path().join("scene.obj"), obj).expect("write the scratch scene.obj");
    let mtl_path = dir.path().join("scene.mtl");
    match mtl {
        Some(mtl) => std::fs::write(&mtl_path, mtl).expect("write the scratch scene.mtl"),
        None => match std::fs::remove_file(&mtl_path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                panic!("remove {}: {e}", mtl_path.display())
            }
            _ => {}
        },
    }
    let scene = Scene::load(dir.path()).map_err(|e| e.to_string())?;
    check_scene(&scene);
    Ok(())
}

/// `gltf`: the input written as `scene.glb` (the parser tells a GLB from a JSON glTF by its
/// first bytes, so either form works under that name), then [`Scene::load`] of that file. A
/// buffer or image URI that names a file finds the scratch directory's `scene.bin` (a copy of
/// the seed's buffer) or nothing.
pub fn gltf(data: &[u8]) -> Outcome {
    static DIR: ScratchDir = ScratchDir::new("gltf", &[("scene.bin", &TRIANGLE_BIN)]);
    let dir = DIR.lock();
    let path = dir.path().join("scene.glb");
    std::fs::write(&path, data).expect("write the scratch scene.glb");
    let scene = Scene::load(&path).map_err(|e| e.to_string())?;
    check_scene(&scene);
    Ok(())
}

/// The buffer of the `gltf` seeds: one triangle's three positions (f32) and indices (u32),
/// little-endian.
const TRIANGLE_BIN: [u8; 48] = {
    let floats: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    let mut out = [0u8; 48];
    let mut i = 0;
    while i < 9 {
        let b = floats[i].to_le_bytes();
        let mut j = 0;
        while j < 4 {
            out[4 * i + j] = b[j];
            j += 1;
        }
        i += 1;
    }
    let mut k = 0;
    while k < 3 {
        out[36 + 4 * k] = k as u8;
        k += 1;
    }
    out
};

/// The glTF JSON of the `gltf` seeds over [`TRIANGLE_BIN`] as buffer `uri` (`None`: a GLB's
/// binary chunk): the triangle in a node moved by (1, 2, 3), a material, a camera, a spot light.
fn triangle_gltf(uri: Option<&str>) -> String {
    let uri = uri.map_or(String::new(), |u| format!(r#""uri": "{u}", "#));
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0, 1, 2]}}],
"extensionsUsed": ["KHR_lights_punctual"],
"extensions": {{"KHR_lights_punctual": {{"lights": [{{"type": "spot", "intensity": 5,
  "spot": {{"innerConeAngle": 0.2, "outerConeAngle": 0.6}}}}]}}}},
"nodes": [{{"mesh": 0, "translation": [1, 2, 3], "children": []}},
  {{"camera": 0, "translation": [0.3, 0.3, 5]}},
  {{"rotation": [-0.7071068, 0, 0, 0.7071068], "translation": [0.3, 3, 0.3],
    "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}],
"cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.8, "znear": 0.01}}}}],
"meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
"materials": [{{"emissiveFactor": [0.5, 0.5, 0.5],
  "pbrMetallicRoughness": {{"baseColorFactor": [0.7, 0.5, 0.3, 1], "roughnessFactor": 0.4}}}}],
"buffers": [{{{uri}"byteLength": 48}}],
"bufferViews": [{{"buffer": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 12}}],
"accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
  "min": [0, 0, 0], "max": [1, 1, 0]}},
  {{"bufferView": 1, "componentType": 5125, "count": 3, "type": "SCALAR"}}]}}"#
    )
}

/// A GLB container (glTF 2.0 §4.4) of `json` and the binary chunk `bin`.
pub fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let padded = |bytes: &[u8], with: u8| {
        let mut b = bytes.to_vec();
        b.resize(bytes.len().div_ceil(4) * 4, with);
        b
    };
    let (json, bin) = (padded(json.as_bytes(), b' '), padded(bin, 0));
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = b"glTF".to_vec();
    for word in [2, total as u32, json.len() as u32] {
        out.extend_from_slice(&word.to_le_bytes());
    }
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// The OBJ and (after the first `0xFF`) MTL parts of an `obj_mtl` input.
pub fn split_obj_mtl(data: &[u8]) -> (&[u8], Option<&[u8]>) {
    match data.iter().position(|&b| b == 0xFF) {
        Some(at) => (&data[..at], Some(&data[at + 1..])),
        None => (data, None),
    }
}

/// An `obj_mtl` input of an OBJ and its MTL (see [`split_obj_mtl`]).
pub fn join_obj_mtl(obj: &[u8], mtl: Option<&[u8]>) -> Vec<u8> {
    let mut out = obj.to_vec();
    if let Some(mtl) = mtl {
        out.push(0xFF);
        out.extend_from_slice(mtl);
    }
    out
}
