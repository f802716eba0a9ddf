//! What a careless or hostile glTF file gets (issue 53, classes 2 to 5 and 8): refused in words
//! naming the file, the part and the fault, with no panic, or loaded correctly. Kept apart from
//! `gltf/tests.rs`, which show what a good file gives.

use std::path::Path;

use super::gltf::tests::{quad_buffer, quad_gltf, quad_json};
use super::tests::write;
use super::{LoadOptions, Scene};

/// `json` loaded as `bad.gltf` in a directory of its own: the error's text, or `None`.
fn load(json: &str) -> Result<Scene, String> {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &[("bad.gltf", json)]);
    Scene::load(&dir.path().join("bad.gltf")).map_err(|e| e.to_string())
}

fn refused(json: &str) -> String {
    let e = load(json).expect_err("the file is refused");
    assert!(e.contains("bad.gltf"), "{e}");
    assert!(!e.contains("panicked"), "{e}");
    e
}

/// Types the gltf crate's readers panic on (class 4): refused naming the accessor, its role and
/// what glTF allows there.
#[test]
fn accessors_of_the_wrong_type_or_stride_are_refused_naming_them() {
    let ok = quad_gltf();
    let e = refused(&ok.replace(
        r#""byteOffset": 0, "byteLength": 48}"#,
        r#""byteOffset": 0, "byteLength": 48, "byteStride": 4}"#,
    ));
    assert!(
        e.contains("accessor 0 (POSITION)")
            && e.contains("byteStride of 4, less than the 12 bytes of an element"),
        "{e}"
    );
    let e = refused(&ok.replace(
        r#""componentType": 5125, "count": 6"#,
        r#""componentType": 5126, "count": 6"#,
    ));
    assert!(
        e.contains("accessor 2 (indices): glTF allows only SCALAR of UNSIGNED_BYTE"),
        "{e}"
    );
    let e = refused(&ok.replace(
        r#""componentType": 5126, "count": 4, "type": "VEC2""#,
        r#""componentType": 5122, "count": 4, "type": "VEC2""#,
    ));
    assert!(e.contains("accessor 1 (TEXCOORD)"), "{e}");
    let e = refused(&ok.replace(r#""POSITION": 0"#, r#""POSITION": 9"#));
    assert!(
        e.contains("mesh 0 primitive 0 names accessor 9; the file has 3"),
        "{e}"
    );
}

/// Images the gltf crate's `source()` unwraps (class 3): a view without a MIME type loads (the
/// bytes say what they are), an image with no source is refused; images naming one view share
/// its bytes (class 5).
#[test]
fn images_without_a_mime_type_or_a_source() {
    let ok = quad_gltf();
    let with_images = |images: &str| ok.replace(r#""buffers""#, &format!("{images}, \"buffers\""));
    let s = load(&with_images(
        r#""images": [{"bufferView": 2}, {"bufferView": 2}]"#,
    ))
    .unwrap();
    assert!(!s.triangles.is_empty());
    let e = refused(&with_images(r#""images": [{"name": "empty"}]"#));
    assert!(
        e.contains("image 0 `empty` has neither a uri nor a bufferView"),
        "{e}"
    );
}

/// A tree: `root/outside.bin`, `root/scene/quad.bin`, `root/scene/escape.bin` (a link to
/// `../outside.bin`), `root/scene/sub/`.
fn tree() -> tempfile::TempDir {
    let root = tempfile::tempdir().unwrap();
    let scene = root.path().join("scene");
    std::fs::create_dir_all(scene.join("sub")).unwrap();
    std::fs::write(root.path().join("outside.bin"), quad_buffer()).unwrap();
    std::fs::write(scene.join("quad.bin"), quad_buffer()).unwrap();
    std::os::unix::fs::symlink("../outside.bin", scene.join("escape.bin")).unwrap();
    root
}

fn load_uri(root: &Path, uri: &str, options: LoadOptions) -> Result<Scene, String> {
    let gltf = root.join("scene/quads.gltf");
    std::fs::write(&gltf, quad_json(Some(uri))).unwrap();
    Scene::load_with(&gltf, options).map_err(|e| e.to_string())
}

/// Class 2: a buffer URI resolves inside the glTF file's directory only, unless the user
/// allows others; refused before a byte is read, so no error can quote the file.
#[test]
fn uris_leading_out_of_the_files_directory_are_refused() {
    let root = tree();
    let outside = root.path().join("outside.bin");
    let strict = LoadOptions::default();
    for uri in [
        "../outside.bin".to_string(),
        "%2E%2E/outside.bin".to_string(),
        "..%2Foutside.bin".to_string(),
        "sub/../../outside.bin".to_string(),
        outside.display().to_string(),
        "escape.bin".to_string(),
    ] {
        let e = load_uri(root.path(), &uri, strict).expect_err(&uri);
        assert!(
            e.contains("quads.gltf")
                && e.contains("buffer 0")
                && e.contains("names a file outside the glTF file's directory")
                && e.contains("--allow-outside-files"),
            "{uri}: {e}"
        );
    }
    let e = load_uri(root.path(), "file:///etc/hostname", strict).unwrap_err();
    assert!(e.contains("has the scheme file:"), "{e}");
    // Inside, however written; outside when allowed.
    for uri in ["quad.bin", "sub/../quad.bin", "./quad%2Ebin"] {
        load_uri(root.path(), uri, strict).expect(uri);
    }
    let allowed = LoadOptions {
        files_outside: true,
    };
    for uri in ["../outside.bin", "escape.bin"] {
        load_uri(root.path(), uri, allowed).expect(uri);
    }
}

/// Class 2, images: an image file outside is refused as a buffer is.
#[test]
fn image_uris_leading_out_are_refused() {
    let root = tree();
    let gltf = root.path().join("scene/quads.gltf");
    let json = quad_gltf().replace(
        r#""buffers""#,
        r#""images": [{"uri": "../outside.png"}], "buffers""#,
    );
    std::fs::write(&gltf, json).unwrap();
    let e = Scene::load(&gltf).unwrap_err().to_string();
    assert!(
        e.contains("image 0: the URI \"../outside.png\" names a file outside"),
        "{e}"
    );
}

/// Class 5: one mesh placed by many nodes is counted before anything is allocated for it.
#[test]
fn instancing_past_the_triangle_limit_is_refused_before_allocating() {
    use super::MAX_SCENE_TRIANGLES;
    // One mesh of 2^22 triangles (u8 indices, all 0: degenerate, so nothing would be kept),
    // placed by 5 nodes: 5 * 2^22 > 2^24.
    let per_mesh = 1usize << 22;
    assert!(5 * per_mesh > MAX_SCENE_TRIANGLES && 4 * per_mesh <= MAX_SCENE_TRIANGLES);
    let mut bin = Vec::new();
    for p in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        bin.extend(p.iter().flat_map(|c| c.to_le_bytes()));
    }
    bin.resize(36 + 3 * per_mesh, 0);
    let json = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0, 1, 2, 3, 4]}}],
  "nodes": [{{"mesh": 0}}, {{"mesh": 0}}, {{"mesh": 0}}, {{"mesh": 0}}, {{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "buffers": [{{"byteLength": {len}}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": {indices}}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5121, "count": {indices}, "type": "SCALAR"}}]}}"#,
        len = bin.len(),
        indices = 3 * per_mesh
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("many.glb");
    std::fs::write(&path, super::gltf::tests::glb(&json, &bin)).unwrap();
    let e = Scene::load(&path).unwrap_err().to_string();
    assert!(
        e.contains("many.glb")
            && e.contains(&format!("more than {MAX_SCENE_TRIANGLES} triangles"))
            && e.contains("once per node"),
        "{e}"
    );
}

/// Class 5: one buffer file named by many buffers was read once for each; the files' sizes in
/// all are limited before any is read (a sparse file here: nothing is allocated).
#[test]
fn buffer_files_past_the_limit_in_all_are_refused_before_reading() {
    use super::MAX_FILE_BYTES;
    let dir = tempfile::tempdir().unwrap();
    let big = std::fs::File::create(dir.path().join("big.bin")).unwrap();
    big.set_len(MAX_FILE_BYTES / 2 + 1).unwrap();
    let json = quad_json(Some("big.bin")).replace(
        r#""buffers": [{"uri": "big.bin", "byteLength": 104}]"#,
        r#""buffers": [{"uri": "big.bin", "byteLength": 104}, {"uri": "big.bin", "byteLength": 104}]"#,
    );
    assert!(json.contains(r#"{"uri": "big.bin", "byteLength": 104}, {"#));
    std::fs::write(dir.path().join("two.gltf"), json).unwrap();
    let e = Scene::load(&dir.path().join("two.gltf"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("buffer 1: the buffer files come to more than"),
        "{e}"
    );
}
