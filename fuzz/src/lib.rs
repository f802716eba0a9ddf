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

// ---------------------------------------------------------------------------------------------
// What is done with an accepted input

/// Most run-data lookups one check makes (larger files are sampled).
const MAX_LOOKUPS: u64 = 1 << 20;
/// Largest run data (offsets plus runs) that gets the encode / decode round trip.
const MAX_ROUND_TRIP_WORDS: usize = 1 << 16;

/// Uses a file that [`cssm::decode`] accepted as the runtime and the tools do; none of it may
/// panic. With `scene` (a scene the file passed [`cssm::validate_for_scene`] against), also the
/// queries from the scene's triangles.
pub fn check_file(file: &CssmFile, scene: Option<&Scene>) {
    // Every (map, pixel) lookup (sampled when there are very many).
    let runs = &file.runs;
    let total = u64::from(runs.map_count) * u64::from(runs.pixel_count);
    let stride = total.div_ceil(MAX_LOOKUPS).max(1);
    let mut k = 0;
    while k < total {
        let (map, pixel) = (
            k / u64::from(runs.pixel_count),
            k % u64::from(runs.pixel_count),
        );
        let _ = runs.lookup(map as u32, pixel as u32);
        k += stride;
    }

    // The hierarchy: every node's leaves and children, and the cuts at both extremes.
    let h = &file.hierarchy;
    for i in 0..h.nodes.len() {
        let _ = h.leaves(i);
        if let Some((l, r)) = h.children(i) {
            assert!(
                l < h.nodes.len() && r < h.nodes.len(),
                "node {i}: children {l}, {r}"
            );
        }
    }
    let leaves_of =
        |cut: &[usize]| -> u64 { cut.iter().map(|&i| u64::from(h.nodes[i].count)).sum() };
    assert_eq!(leaves_of(&h.cut(|_, _| false)), file.texels.len() as u64);
    assert_eq!(leaves_of(&h.cut(|_, _| true)), file.texels.len() as u64);

    // Visibility queries between a few texels, with and without the filters.
    let count = file.texels.len() as u32;
    let few: Vec<u32> = (0..count).step_by((count as usize / 8).max(1)).collect();
    for options in [
        QueryOptions::default(),
        QueryOptions {
            bias_near: 1.0,
            bias_relative: 0.01,
            pcf: false,
            sender_filter: false,
            both_ends: false,
        },
    ] {
        let q = VisibilityQuery::new(file, options);
        for &sender in &few {
            for &receiver in &few {
                let t = &file.texels[receiver as usize];
                let _ = q.visibility(sender, t.pos());
                let _ = q.visibility_oriented(sender, t.pos(), Some(t.nrm()));
                let _ = q.depth_code(sender, receiver % runs.pixel_count);
            }
            let t = &file.texels[sender as usize];
            let at = glam::Vec2::new(f32::from(t.x) + 0.5, f32::from(t.y) + 0.5);
            let _ = q.visibility_from_atlas(at, glam::Vec3::ZERO, None);
        }
        if let Some(scene) = scene {
            // As a renderer does: a surface point of every triangle against a receiver.
            let n = scene.triangles.len();
            for tri in 0..n {
                let [a, b, c] = scene.triangle(n - 1 - tri);
                let p_i = (a + b + c) / 3.0;
                let third = [1.0 / 3.0; 3];
                let _ = q.visibility_from_surface(tri, third, p_i, Some((b - a).cross(c - a)));
                let _ = q.sender_texels(tri, [1.0, 0.0, 0.0]);
            }
        }
    }

    // An accepted file encodes (both codings) and decodes back to itself.
    if runs.offsets.len() + runs.runs.len() <= MAX_ROUND_TRIP_WORDS {
        for coding in [FileCoding::Plain, FileCoding::Packed] {
            let bytes = cssm::encode_with(file, coding)
                .unwrap_or_else(|e| panic!("a decoded file does not encode ({coding}): {e}"));
            let back = cssm::decode(&bytes)
                .unwrap_or_else(|e| panic!("an encoded file does not decode ({coding}): {e}"));
            assert!(
                back == *file,
                "decode(encode(file)) differs from file ({coding})"
            );
        }
    }
}

/// Uses a scene that [`Scene::load`] accepted as the bake and the renderers do: every index in
/// range, the lengths the fields' docs promise, finite geometry, no degenerate triangle.
pub fn check_scene(s: &Scene) {
    let n = s.positions.len();
    assert!(!s.triangles.is_empty(), "a loaded scene without triangles");
    assert!(
        s.positions.iter().all(|p| p.is_finite()),
        "a non-finite position"
    );
    assert!(
        s.texcoords.is_empty() || s.texcoords.len() == n,
        "{} texcoords for {n} positions",
        s.texcoords.len()
    );
    assert_eq!(
        s.triangle_materials.len(),
        s.triangles.len(),
        "triangle_materials and triangles differ in length"
    );
    for t in 0..s.triangles.len() {
        let tri = s.triangles[t];
        assert!(
            tri.iter().all(|&i| (i as usize) < n),
            "triangle {t} {tri:?} indexes past the {n} positions"
        );
        let m = s.triangle_materials[t];
        assert!(
            (m as usize) < s.materials.len(),
            "triangle {t} has material {m} of {}",
            s.materials.len()
        );
        let [a, b, c] = s.triangle(t).map(|v| v.as_dvec3());
        let area2 = (b - a).cross(c - a).length_squared();
        assert!(
            area2 > 0.0,
            "triangle {t} is degenerate (kept by the loader)"
        );
        assert!(
            s.object_of(t) < s.objects.len(),
            "triangle {t} has no object"
        );
    }
    if let Err(e) = s.check_objects() {
        panic!("Scene::objects broken: {e}");
    }
    for m in &s.materials {
        let values = m.kd.iter().chain(&m.ks).chain([&m.ns]);
        assert!(
            values.clone().all(|v| v.is_finite() && *v >= 0.0),
            "material `{}`: negative or non-finite Kd, Ks or Ns",
            m.name
        );
    }
    assert!(!s.lights.is_empty(), "a loaded scene without lights");
    assert!(
        s.diameter().is_finite(),
        "diameter {} not finite",
        s.diameter()
    );
    // Not crashes, but worth a look: a camera or light at infinity renders nothing useful.
    let c = &s.camera;
    if !(c.position.is_finite() && c.target.is_finite() && c.up.is_finite()) {
        note(
            "camera-not-finite",
            &format!(
                "the camera is not finite: position {}, target {}, up {} (scene diameter {})",
                c.position,
                c.target,
                c.up,
                s.diameter()
            ),
        );
    }
    for (i, l) in s.lights.iter().enumerate() {
        if !(l.position.is_finite()
            && l.direction.is_finite()
            && l.intensity.iter().all(|v| v.is_finite()))
        {
            note(
                "light-not-finite",
                &format!(
                    "light {i} is not finite: position {}, direction {}, intensity {:?} (scene \
                     diameter {})",
                    l.position,
                    l.direction,
                    l.intensity,
                    s.diameter()
                ),
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The built-in scenes

/// The files of the built-in Cornell box (`scenes/cornell-box/`), `scene.toml` first.
pub const CORNELL_BOX: [(&str, &[u8]); 3] = [
    (
        "scene.toml",
        include_bytes!("../../scenes/cornell-box/scene.toml"),
    ),
    (
        "cornell-box.obj",
        include_bytes!("../../scenes/cornell-box/cornell-box.obj"),
    ),
    (
        "cornell-box.mtl",
        include_bytes!("../../scenes/cornell-box/cornell-box.mtl"),
    ),
];

/// The files of the built-in glossy Cornell box (`scenes/cornell-glossy/`), `scene.toml` first.
pub const CORNELL_GLOSSY: [(&str, &[u8]); 3] = [
    (
        "scene.toml",
        include_bytes!("../../scenes/cornell-glossy/scene.toml"),
    ),
    (
        "cornell-glossy.obj",
        include_bytes!("../../scenes/cornell-glossy/cornell-glossy.obj"),
    ),
    (
        "cornell-glossy.mtl",
        include_bytes!("../../scenes/cornell-glossy/cornell-glossy.mtl"),
    ),
];

/// The meshes of the built-in scenes, without their `scene.toml`s.
const MESHES: [(&str, &[u8]); 4] = [
    CORNELL_BOX[1],
    CORNELL_BOX[2],
    CORNELL_GLOSSY[1],
    CORNELL_GLOSSY[2],
];

/// The built-in Cornell box, loaded once per process (from a scratch copy of its files).
pub fn cornell_box() -> &'static Scene {
    static DIR: ScratchDir = ScratchDir::new("cornell-box", &CORNELL_BOX);
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(|| {
        let dir = DIR.lock();
        Scene::load(dir.path()).expect("the built-in Cornell box loads")
    })
}

// ---------------------------------------------------------------------------------------------
// Scratch directories

/// This process's scratch directory: `cssm-fuzz-<pid>` in `/dev/shm` where it can be made
/// there, else in [`std::env::temp_dir`]. Made empty on first use; the directories of processes
/// that have gone (where `/proc` says so) are removed then. [`remove_scratch`] removes it.
fn scratch_root() -> &'static Path {
    static ROOT: OnceLock<PathBuf> = OnceLock::new();
    ROOT.get_or_init(|| {
        let name = format!("cssm-fuzz-{}", std::process::id());
        let mut bases = vec![std::env::temp_dir()];
        if Path::new("/dev/shm").is_dir() {
            bases.insert(0, PathBuf::from("/dev/shm"));
        }
        for base in bases {
            let root = base.join(&name);
            let _ = std::fs::remove_dir_all(&root); // a former process of the same PID
            if std::fs::create_dir_all(&root).is_ok() {
                remove_stale(&base);
                return root;
            }
        }
        panic!("cannot make a scratch directory {name} in /dev/shm or the temp directory");
    })
}

/// Removes the `cssm-fuzz-<pid>` directories of `base` whose process has gone.
fn remove_stale(base: &Path) {
    if !Path::new("/proc/self").exists() {
        return; // No procfs: no way to tell.
    }
    let Ok(entries) = std::fs::read_dir(base) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| n.strip_prefix("cssm-fuzz-")) else {
            continue;
        };
        if pid.parse::<u32>().is_ok() && !Path::new("/proc").join(pid).exists() {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Removes this process's scratch directory (the fuzz targets never do; the next process
/// removes it when this one has gone).
pub fn remove_scratch() {
    let _ = std::fs::remove_dir_all(scratch_root());
}

/// A scratch directory of one target, made on first use with `files` in it, and locked while a
/// body uses it (the tests replay the targets on several threads).
struct ScratchDir {
    name: &'static str,
    files: &'static [(&'static str, &'static [u8])],
    path: Mutex<Option<PathBuf>>,
}

/// A [`ScratchDir`] in use.
struct Held<'a>(MutexGuard<'a, Option<PathBuf>>);

impl Held<'_> {
    fn path(&self) -> &Path {
        self.0.as_deref().expect("made on lock")
    }
}

impl ScratchDir {
    const fn new(name: &'static str, files: &'static [(&'static str, &'static [u8])]) -> Self {
        ScratchDir {
            name,
            files,
            path: Mutex::new(None),
        }
    }

    fn lock(&self) -> Held<'_> {
        // A panic while it was held (a finding, in a test) leaves the directory usable.
        let mut guard = self.path.lock().unwrap_or_else(PoisonError::into_inner);
        let path = guard.get_or_insert_with(|| scratch_root().join(self.name));
        if !path.is_dir() {
            std::fs::create_dir_all(&*path).expect("make a scratch directory");
            for (name, bytes) in self.files {
                std::fs::write(path.join(name), bytes).expect("write a scratch file");
            }
        }
        Held(guard)
    }
}

// ---------------------------------------------------------------------------------------------
// Panics that the library catches, and notes

/// The OBJ loader runs tobj under `catch_unwind` ("tobj has a few panicking paths on malformed
/// input: turn a panic into a parse error"), but libFuzzer's panic hook aborts on any panic,
/// caught or not. This hook lets a panic *inside tobj* unwind to that `catch_unwind` (noting
/// where it happened, once); every other panic goes to the previous hook (libFuzzer's abort,
/// or the test harness's). A tobj panic that nothing catches still ends in libFuzzer's own
/// `catch_unwind` around the target, which aborts.
fn tolerate_caught_tobj_panics() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| match info.location() {
            Some(at) if at.file().contains("tobj-") => {
                let message = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                let at = format!("{}:{}", at.file(), at.line());
                note(
                    &at,
                    &format!("tobj panicked at {at} (caught by Scene::load): {message}"),
                );
            }
            _ => previous(info),
        }));
    });
}

/// Prints `message` to stderr the first time this process notes `key`.
pub fn note(key: &str, message: &str) {
    static SEEN: Mutex<Option<HashSet<String>>> = Mutex::new(None);
    let mut seen = SEEN.lock().unwrap_or_else(PoisonError::into_inner);
    if seen
        .get_or_insert_with(HashSet::new)
        .insert(key.to_string())
    {
        eprintln!("cssm-fuzz note: {message}");
    }
}

// ---------------------------------------------------------------------------------------------
// Seeds

/// Inputs for `target` that need no bake: the built-in scenes' files, hand-written variants, and
/// a tiny hand-made CSSM of the Cornell box ([`tiny_file`]) in both codings. The seed corpora
/// start from them (`examples/make_seeds.rs`), and `tests/fuzzed.rs` replays them. The names
/// starting with `ok-` must be accepted.
pub fn seeds(target: &str) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = Vec::new();
    let mut add = |name: &str, bytes: Vec<u8>| out.push((name.to_string(), bytes));
    match target {
        "cssm_header" | "cssm_file" => {
            let file = tiny_file(cornell_box());
            for coding in [FileCoding::Plain, FileCoding::Packed] {
                let bytes = cssm::encode_with(&file, coding).expect("encode the tiny file");
                if target == "cssm_header" {
                    add(
                        &format!("header-{coding}"),
                        bytes[..cssm::HEADER_LEN].to_vec(),
                    );
                    add(&format!("header-and-more-{coding}"), bytes[..64].to_vec());
                } else {
                    add(&format!("ok-tiny-{coding}"), bytes);
                }
            }
            add("magic", cssm::MAGIC.to_vec());
            add("empty", Vec::new());
        }
        "cssm_payload" => {
            let file = tiny_file(cornell_box());
            let mut plain = vec![0u8];
            plain.extend(bincode_standard(&file));
            add("ok-tiny-plain", plain);
            let mut packed = vec![1u8];
            packed.extend(bincode_standard(&packed_fields(&file)));
            add("ok-tiny-packed", packed);
            add("not-bincode", b"\x00not bincode of a bake".to_vec());
        }
        "scene_toml" => {
            let toml = std::str::from_utf8(CORNELL_BOX[0].1).expect("UTF-8");
            add("ok-cornell-box", toml.as_bytes().to_vec());
            add("ok-mesh-only", b"mesh = \"cornell-box.obj\"\n".to_vec());
            let objects = format!(
                "{toml}\n[[objects]]\nname = \"copy\"\nmesh = \"cornell-box.obj\"\n\
                 translation = [600.0, 0.0, 0.0]\nrotation_deg = [0.0, 30.0, 0.0]\nscale = 0.5\n"
            );
            add("ok-objects", objects.into_bytes());
            add(
                "zero-direction",
                toml.replace("[0.0, -1.0, 0.0]", "[0.0, 0.0, 0.0]")
                    .into_bytes(),
            );
            add("missing-mesh", b"mesh = \"nope.obj\"\n".to_vec());
            add("unknown-key", format!("{toml}\nfoo = 1\n").into_bytes());
        }
        "obj_mtl" => {
            for files in [&CORNELL_BOX, &CORNELL_GLOSSY] {
                let stem = files[1].0.trim_end_matches(".obj");
                let obj = String::from_utf8_lossy(files[1].1)
                    .replace(&format!("mtllib {stem}.mtl"), "mtllib scene.mtl");
                add(
                    &format!("ok-{stem}"),
                    join_obj_mtl(obj.as_bytes(), Some(files[2].1)),
                );
                add(&format!("ok-{stem}-no-mtl"), obj.into_bytes());
            }
            let quad = "mtllib scene.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\n\
                        vt 1 1\nvt 0 1\nvn 0 0 1\ng quad\nusemtl wood\nf 1/1/1 2/2/1 3/3/1 4/4/1\n";
            let mtl = "newmtl wood\nKa 0.1\nKd 0.8 0.7 0.6\nKs 0.1 0.1 0.1\nNs 20\nd 1\nillum 2\n\
                       map_Kd wood.png\n";
            add(
                "ok-quad",
                join_obj_mtl(quad.as_bytes(), Some(mtl.as_bytes())),
            );
            let negative = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\no a\nf -4 -3 -2\no b\n\
                            f -3 -1 -2 -4\nl 1 2\np 3\n";
            add("ok-negative-indices", negative.as_bytes().to_vec());
            add(
                "nan-vertex",
                b"v 0 0 0\nv 1 0 0\nv nan 0 0\nf 1 2 3\n".to_vec(),
            );
            add(
                "two-value-kd",
                join_obj_mtl(quad.as_bytes(), Some(b"newmtl wood\nKd 1 2\n")),
            );
        }
        "gltf" => {
            add("ok-triangle-glb", glb(&triangle_gltf(None), &TRIANGLE_BIN));
            add(
                "ok-triangle-file-buffer",
                triangle_gltf(Some("scene.bin")).into_bytes(),
            );
            // The buffer as a data URI without base64: every byte percent-encoded.
            let percent: String = TRIANGLE_BIN.iter().map(|b| format!("%{b:02X}")).collect();
            let uri = format!("data:application/octet-stream,{percent}");
            add(
                "ok-triangle-data-uri",
                triangle_gltf(Some(&uri)).into_bytes(),
            );
            add(
                "missing-buffer",
                triangle_gltf(Some("nope.bin")).into_bytes(),
            );
            add(
                "view-past-buffer",
                glb(
                    &triangle_gltf(None).replace(
                        r#""byteOffset": 36, "byteLength": 12"#,
                        r#""byteOffset": 36, "byteLength": 4000"#,
                    ),
                    &TRIANGLE_BIN,
                ),
            );
            add("not-gltf", b"glTF\x02\x00\x00\x00".to_vec());
        }
        _ => {}
    }
    out
}

/// A tiny valid CSSM for `scene`: five texels of a 32x32 atlas, cube maps of 6x8x8 pixels with
/// a few runs each, a hierarchy, one triangle UV per scene triangle; every texel's material one
/// of the scene's. Passes [`cssm::validate`] and [`cssm::validate_for_scene`] with `scene`.
pub fn tiny_file(scene: &Scene) -> CssmFile {
    let texels: Vec<Texel> = (0..5u16)
        .map(|i| Texel {
            position: [100.0 * f32::from(i), 10.0, 50.0],
            normal: [0.0, 1.0, 0.0],
            area: 4.0,
            material: u32::from(i) % scene.materials.len() as u32,
            chart: u32::from(i / 3),
            object: 0,
            x: 3 * i,
            y: i,
        })
        .collect();
    let cube = 8;
    let pixel_count = 6 * cube * cube;
    let (mut offsets, mut runs) = (vec![0], Vec::new());
    for p in 0..pixel_count {
        runs.push((p * 97) % 0xFFFF);
        if p % 4 == 0 {
            runs.push((2 << 16) | (p * 13));
        }
        if p % 8 == 0 {
            runs.push((4 << 16) | 0xFFFF);
        }
        offsets.push(runs.len() as u32);
    }
    let triangle_uvs = (0..scene.triangles.len())
        .map(|t| {
            let x = (t % 30) as f32;
            [[x, 1.0], [x + 1.5, 1.0], [x, 2.5]]
        })
        .collect();
    let hierarchy = Hierarchy::build(&texels);
    CssmFile {
        params: BakeParams {
            atlas_resolution: 32,
            cube_resolution: cube,
            near: 1.0,
            far: 1000.0,
            traversal: Traversal::Greedy,
        },
        scene: SceneRef {
            dir: scene.path.to_string_lossy().into_owned(),
            name: scene.name.clone(),
            content_hash: scene.content_hash,
            triangle_count: scene.triangles.len() as u32,
        },
        texels,
        triangle_uvs,
        sequence: vec![2, 0, 4, 1, 3],
        hierarchy,
        runs: RunData {
            map_count: 5,
            pixel_count,
            offsets,
            runs,
        },
        csms: Vec::new(),
        pixel_grid: Default::default(),
        cube_frame: Default::default(),
    }
}

/// The fields of a packed file's payload ([`cssm::FLAG_PACKED_RUNS`]: the run data as
/// [`PackedRuns`] after its two counts), in the order of the format's private `PackedFile`.
#[allow(clippy::type_complexity)]
pub fn packed_fields(
    file: &CssmFile,
) -> (
    &BakeParams,
    &SceneRef,
    &Vec<Texel>,
    &Vec<[[f32; 2]; 3]>,
    &Vec<u32>,
    &Hierarchy,
    u32,
    u32,
    PackedRuns,
    &Vec<cssm_formats::csm::CsmData>,
) {
    (
        &file.params,
        &file.scene,
        &file.texels,
        &file.triangle_uvs,
        &file.sequence,
        &file.hierarchy,
        file.runs.map_count,
        file.runs.pixel_count,
        PackedRuns::pack(&file.runs),
        &file.csms,
    )
}

/// `value` encoded as bincode 2 (serde, standard configuration): the raw payload of a `.cssm`
/// file, as the library's encoder writes it.
pub fn bincode_standard<T: serde::Serialize>(value: &T) -> Vec<u8> {
    bincode::serde::encode_to_vec(value, bincode::config::standard()).expect("bincode")
}
