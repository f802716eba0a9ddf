//! Tests of glTF loading: a quad scene built in the test (as `.gltf` with a data URI, with an
//! external buffer, and as `.glb`), embedded and file textures, normal maps, malformed files and
//! the material and light conversions. The builders of the quad files are shared with
//! `gltf_refusals.rs`.

use std::path::Path;

use base64::Engine;
use glam::Vec3;

use super::lights::equivalent_cone;
use super::materials::{convert_material, phong_exponent};
use super::nodes::primitive_triangles;
use crate::scene::tests::{scene, write};
use crate::scene::{NormalMap, NormalMapKind, ObjectKind, Scene, SceneError, TextureSource};

/// One buffer of a test glTF: a unit quad in the xy plane (4 positions, 4 texture
/// coordinates, 6 indices), little-endian, 104 bytes.
pub(crate) fn quad_buffer() -> Vec<u8> {
    let positions: [[f32; 3]; 4] = [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
    let uvs: [[f32; 2]; 4] = [[0., 1.], [1., 1.], [1., 0.], [0., 0.]];
    let indices: [u32; 6] = [0, 1, 2, 0, 2, 3];
    let mut b = Vec::new();
    for v in positions.iter().flatten().chain(uvs.iter().flatten()) {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for i in indices {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}

/// A glTF document over [`quad_buffer`] with the buffer `uri` (`None`: the GLB's binary
/// chunk): node 0 holds the quad translated by (10, 0, 0) and, as its child, node 1 the
/// quad again moved up by 2; node 2 a camera at (0.5, 0.5, 3) looking down -z; node 3 a spot
/// light at (0.5, 0.5, 2) pointing down -z.
pub(crate) fn quad_json(uri: Option<&str>) -> String {
    let uri = uri.map_or(String::new(), |u| format!(r#""uri": "{u}", "#));
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
  "extensions": {{"KHR_lights_punctual": {{"lights": [
    {{"type": "spot", "color": [1, 0.5, 0.25], "intensity": 8,
      "spot": {{"innerConeAngle": 0.5, "outerConeAngle": 0.5}}}}]}}}},
  "scene": 0,
  "scenes": [{{"name": "quads", "nodes": [0, 2, 3]}}],
  "nodes": [
    {{"name": "floor", "mesh": 0, "translation": [10, 0, 0], "children": [1]}},
    {{"mesh": 0, "translation": [0, 2, 0]}},
    {{"camera": 0, "translation": [0.5, 0.5, 3]}},
    {{"translation": [0.5, 0.5, 2], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}}
  ],
  "cameras": [{{"type": "perspective",
    "perspective": {{"yfov": 0.7, "aspectRatio": 2.0, "znear": 0.1}}}}],
  "meshes": [{{"name": "quad", "primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}},
    "indices": 2, "material": 0}}]}}],
  "materials": [{{"name": "glow", "emissiveFactor": [1, 0.5, 0],
    "extensions": {{"KHR_materials_emissive_strength": {{"emissiveStrength": 4}}}},
    "pbrMetallicRoughness": {{"baseColorFactor": [0.8, 0.6, 0.4, 1], "metallicFactor": 0,
      "roughnessFactor": 1}}}}],
  "buffers": [{{{uri}"byteLength": 104}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
    {{"buffer": 0, "byteOffset": 80, "byteLength": 24}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
    {{"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"}}
  ]
}}"#
    )
}

/// The quad glTF with its buffer as a base64 data URI.
pub(crate) fn quad_gltf() -> String {
    let data = base64::engine::general_purpose::STANDARD.encode(quad_buffer());
    quad_json(Some(&format!(
        "data:application/octet-stream;base64,{data}"
    )))
}

/// A GLB container of `json` and the binary chunk `bin` (glTF 2.0 §4.4).
pub(crate) fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let pad = |mut b: Vec<u8>, with: u8| {
        while b.len() % 4 != 0 {
            b.push(with);
        }
        b
    };
    let json = pad(json.as_bytes().to_vec(), b' ');
    let bin = pad(bin.to_vec(), 0);
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-5
}

fn check_quads(s: &Scene) {
    assert_eq!(s.triangles.len(), 4);
    // Two static objects, one per mesh node, placed by their world transforms.
    assert_eq!(s.objects.len(), 2, "{:?}", s.objects);
    assert_eq!(s.objects[0].name, "floor");
    assert_eq!(s.objects[1].name, "quad");
    assert!(s.objects.iter().all(|o| o.kind == ObjectKind::Static));
    let corner = |o: usize| s.triangle(s.objects[o].triangles.start as usize)[1];
    assert!(close(corner(0), Vec3::new(11.0, 0.0, 0.0)), "{}", corner(0));
    assert!(close(corner(1), Vec3::new(11.0, 2.0, 0.0)), "{}", corner(1));
    assert!(close(
        s.objects[1].transform.translation.into(),
        Vec3::new(10.0, 2.0, 0.0)
    ));
    // v flipped: glTF's (1, 1) at the corner (1, 0) is the runtime's (1, 0).
    let [_, b, _] = s.triangles[0];
    assert_eq!(s.texcoords[b as usize], [1.0, 0.0]);
    // Rough dielectric: the specular lobe folded into the albedo; emission times strength.
    let m = &s.materials[s.triangle_materials[0] as usize];
    assert_eq!(m.name, "glow");
    let (kd, ks, ns) = convert_material([0.8, 0.6, 0.4], 0.0, 1.0);
    assert_eq!((m.kd, m.ks, m.ns), (kd, ks, ns));
    assert!((m.kd[0] - (0.8 * 0.96 + 0.04)).abs() < 1e-6, "{:?}", m.kd);
    assert_eq!(m.emission, [4.0, 2.0, 0.0]);
    // The camera looks down its -z; the aspect ratio sets the width.
    assert!(close(s.camera.position, Vec3::new(0.5, 0.5, 3.0)));
    assert!(close(s.camera.target, Vec3::new(0.5, 0.5, 2.0)));
    assert!((s.camera.fov_y_deg - 0.7f32.to_degrees()).abs() < 1e-4);
    assert_eq!(s.camera.resolution, [960, 480]);
    // The spot light: colour times intensity, a hard cone at its (equal) cone angles.
    assert_eq!(s.lights.len(), 1);
    let l = &s.lights[0];
    assert!(close(l.position, Vec3::new(0.5, 0.5, 2.0)));
    assert!(close(l.direction, Vec3::NEG_Z));
    assert!(
        (l.cutoff_deg - 0.5f32.to_degrees()).abs() < 1e-3,
        "{}",
        l.cutoff_deg
    );
    assert_eq!(l.intensity, [8.0, 4.0, 2.0]);
}

#[test]
fn a_gltf_file_is_a_scene() {
    let dir = scene(&[("quads.gltf", &quad_gltf())]);
    let path = dir.path().join("quads.gltf");
    let s = Scene::load(&path).unwrap();
    assert_eq!(s.name, "quads");
    assert_eq!(s.path, std::fs::canonicalize(&path).unwrap());
    check_quads(&s);
    // Nothing defaulted: the file brings its camera and its light.
    let w = s.warnings.join("\n");
    assert!(!w.contains("default"), "{w}");
    // The same scene from a directory of it.
    let d = Scene::load(dir.path()).unwrap();
    check_quads(&d);
    assert_eq!(d.content_hash, s.content_hash);
}

#[test]
fn a_glb_file_is_the_same_scene() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("quads.glb");
    std::fs::write(&path, glb(&quad_json(None), &quad_buffer())).unwrap();
    let s = Scene::load(&path).unwrap();
    check_quads(&s);
}

#[test]
fn a_glb_header_declaring_too_few_or_too_many_bytes_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("quads.glb");
    let good = glb(&quad_json(None), &quad_buffer());
    for declared in [0u32, 4, 11, good.len() as u32 + 1, u32::MAX] {
        let mut bytes = good.clone();
        bytes[8..12].copy_from_slice(&declared.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let e = Scene::load(&path).unwrap_err().to_string();
        assert!(
            e.contains("quads.glb") && e.contains(&format!("declares {declared} bytes")),
            "{e}"
        );
    }
    std::fs::write(&path, b"glTF\x02\0\0\0").unwrap();
    let e = Scene::load(&path).unwrap_err().to_string();
    assert!(e.contains("cut short: 8 bytes"), "{e}");
}

#[test]
fn an_external_buffer_is_read_and_hashed() {
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        &[("quads.gltf", &quad_json(Some("quad%20data.bin")))],
    );
    std::fs::write(dir.path().join("quad data.bin"), quad_buffer()).unwrap();
    let s = Scene::load(&dir.path().join("quads.gltf")).unwrap();
    check_quads(&s);
    assert_eq!(s.files.len(), 2);
    assert!(s.files[1].ends_with("quad data.bin"));
    let mut changed = quad_buffer();
    changed[4] ^= 1;
    std::fs::write(dir.path().join("quad data.bin"), changed).unwrap();
    let t = Scene::load(&dir.path().join("quads.gltf")).unwrap();
    assert_ne!(s.content_hash, t.content_hash);
    // A missing buffer file is an error naming it.
    std::fs::remove_file(dir.path().join("quad data.bin")).unwrap();
    let e = Scene::load(&dir.path().join("quads.gltf")).unwrap_err();
    assert!(e.to_string().contains("quad data.bin"), "{e}");
}

#[test]
fn a_scene_toml_names_gltf_meshes() {
    let toml = "mesh = \"quads.gltf\"\n\n[[objects]]\nname = \"box\"\nmesh = \"quads.glb\"\n\
                translation = [0.0, 0.0, 5.0]\n";
    let dir = scene(&[("scene.toml", toml), ("quads.gltf", &quad_gltf())]);
    std::fs::write(
        dir.path().join("quads.glb"),
        glb(&quad_json(None), &quad_buffer()),
    )
    .unwrap();
    let s = Scene::load(dir.path()).unwrap();
    assert_eq!(s.triangles.len(), 8);
    // The static nodes, then the rigid object: the whole file, placed after its nodes.
    assert_eq!(s.objects.len(), 3);
    assert_eq!(s.objects[2].name, "box");
    assert_eq!(s.objects[2].kind, ObjectKind::Rigid);
    assert_eq!(s.objects[2].triangles, 4..8);
    let p = s.triangle(4)[1];
    assert!(close(p, Vec3::new(11.0, 0.0, 5.0)), "{p}");
    // scene.toml names no camera or light: the static glTF's are used.
    assert!(close(s.camera.position, Vec3::new(0.5, 0.5, 3.0)));
    assert_eq!(s.lights.len(), 1);
    let w = s.warnings.join("\n");
    assert!(w.contains("the cameras and lights of"), "{w}");
}

#[test]
fn embedded_images_become_textures() {
    let png = base64::engine::general_purpose::STANDARD.encode(b"\x89PNG not really");
    let json = quad_gltf().replace(
        r#""pbrMetallicRoughness": {"#,
        r#""pbrMetallicRoughness": {"baseColorTexture": {"index": 0},"#,
    );
    let json = json.replacen(
        r#""buffers""#,
        &format!(
            r#""textures": [{{"source": 0}}], "images": [{{"name": "bricks",
                "uri": "data:image/png;base64,{png}"}}], "buffers""#
        ),
        1,
    );
    let dir = scene(&[("t.gltf", &json)]);
    let s = Scene::load(&dir.path().join("t.gltf")).unwrap();
    let m = &s.materials[0];
    match &m.map_kd {
        Some(TextureSource::Embedded {
            label, bytes, mime, ..
        }) => {
            assert_eq!(label, "image 0 `bricks`");
            assert_eq!(&bytes[..], b"\x89PNG not really");
            assert_eq!(mime.as_deref(), Some("image/png"));
        }
        other => panic!("{other:?}"),
    }
    assert!(m.map_emission.is_none());
    // Embedded textures are not input files; the glTF is.
    assert_eq!(s.input_files().len(), 1);
    // An image in a file next to the glTF is a file texture, with a warning when missing.
    let json = json.replace(&format!("data:image/png;base64,{png}"), "bricks.png");
    let dir = scene(&[("t.gltf", &json)]);
    let s = Scene::load(&dir.path().join("t.gltf")).unwrap();
    let file = s.path.parent().unwrap().join("bricks.png");
    assert_eq!(s.materials[0].map_kd, Some(TextureSource::File(file)));
    assert!(s.warnings.join("\n").contains("bricks.png not found"));
}

/// `normalTexture` becomes a tangent-space normal map with its scale (1 when the file
/// gives none); a missing image file is a warning, as for the albedo texture.
#[test]
fn normal_texture_becomes_a_tangent_space_normal_map() {
    let with_normal = |normal: &str| {
        let json = quad_gltf().replace(
            r#""pbrMetallicRoughness": {"#,
            &format!(r#""normalTexture": {normal}, "pbrMetallicRoughness": {{"#),
        );
        json.replacen(
            r#""buffers""#,
            r#""textures": [{"source": 0}], "images": [{"uri": "n.png"}], "buffers""#,
            1,
        )
    };
    let dir = scene(&[("t.gltf", &with_normal(r#"{"index": 0, "scale": 0.25}"#))]);
    let s = Scene::load(&dir.path().join("t.gltf")).unwrap();
    let file = s.path.parent().unwrap().join("n.png");
    let expected = NormalMap {
        source: TextureSource::File(file.clone()),
        kind: NormalMapKind::Tangent { scale: 0.25 },
    };
    assert_eq!(s.materials[0].normal_map, Some(expected));
    assert!(s.materials[0].map_kd.is_none());
    assert!(s.input_files().contains(&file));
    let w = s.warnings.join("\n");
    assert!(
        w.contains("material `glow`: texture") && w.contains("n.png not found"),
        "{w}"
    );
    let dir = scene(&[("t.gltf", &with_normal(r#"{"index": 0}"#))]);
    let s = Scene::load(&dir.path().join("t.gltf")).unwrap();
    let kind = s.materials[0].normal_map.as_ref().map(|n| n.kind);
    assert_eq!(kind, Some(NormalMapKind::Tangent { scale: 1.0 }));
}

/// Loads `json` as `bad.gltf` and returns the error's message.
fn error_of(json: &str) -> String {
    let dir = scene(&[("bad.gltf", json)]);
    let e = Scene::load(&dir.path().join("bad.gltf")).unwrap_err();
    let message = e.to_string();
    assert!(message.contains("bad.gltf"), "{message}");
    message
}

#[test]
fn malformed_files_are_errors_naming_the_problem() {
    let ok = quad_gltf();
    let e = error_of("{ not json");
    assert!(e.contains("glTF"), "{e}");
    // An extension the file requires and the loader lacks.
    let e = error_of(&ok.replacen(
        r#""extensionsUsed""#,
        r#""extensionsRequired": ["KHR_draco_mesh_compression"], "extensionsUsed""#,
        1,
    ));
    assert!(e.contains("KHR_draco_mesh_compression"), "{e}");
    // A buffer shorter than it claims.
    let e = error_of(&ok.replace(r#""byteLength": 104}"#, r#""byteLength": 200}"#));
    assert!(
        e.contains("buffer 0 holds 104 bytes, the file says 200"),
        "{e}"
    );
    // An accessor reaching past its view.
    let e = error_of(&ok.replace(
        r#""count": 6, "type": "SCALAR""#,
        r#""count": 7, "type": "SCALAR""#,
    ));
    assert!(e.contains("accessor 2") && e.contains("reach past"), "{e}");
    // A view reaching past its buffer.
    let e = error_of(&ok.replace(
        r#""byteOffset": 80, "byteLength": 24"#,
        r#""byteOffset": 80, "byteLength": 240"#,
    ));
    assert!(e.contains("past the end of buffer 0"), "{e}");
    // An index out of range.
    let mut buffer = quad_buffer();
    buffer[80..84].copy_from_slice(&9u32.to_le_bytes());
    let data = base64::engine::general_purpose::STANDARD.encode(&buffer);
    let e = error_of(&quad_json(Some(&format!(
        "data:application/octet-stream;base64,{data}"
    ))));
    assert!(e.contains("uses vertex 9, but there are only 4"), "{e}");
    // A node that is its own child.
    let e = error_of(&ok.replace(r#""translation": [0, 2, 0]"#, r#""children": [1]"#));
    assert!(e.contains("node"), "{e}");
    // Finite numbers whose product is not: the node is named (class 8 of issue 53; this
    // was a `Debug` dump of a NaN matrix when the renderer placed the object).
    let e = error_of(
        &ok.replace(
            r#""translation": [0, 2, 0]"#,
            r#""translation": [0, 2, 0], "scale": [1e30, 1, 1]"#,
        )
        .replace(
            r#""translation": [10, 0, 0]"#,
            r#""translation": [10, 0, 0], "scale": [1e30, 1, 1]"#,
        ),
    );
    assert!(
        e.contains("node 1: its world transform") && e.contains("is not finite"),
        "{e}"
    );
    assert!(!e.contains("Affine3A") && !e.contains("Mat4"), "{e}");
    // Bad base64.
    let e = error_of(&quad_json(Some("data:application/octet-stream;base64,@@@")));
    assert!(e.contains("base64"), "{e}");
    // A NaN position.
    let mut buffer = quad_buffer();
    buffer[0..4].copy_from_slice(&f32::NAN.to_le_bytes());
    let data = base64::engine::general_purpose::STANDARD.encode(&buffer);
    let dir = scene(&[(
        "bad.gltf",
        &quad_json(Some(&format!(
            "data:application/octet-stream;base64,{data}"
        ))),
    )]);
    let e = Scene::load(&dir.path().join("bad.gltf")).unwrap_err();
    assert!(
        matches!(e, SceneError::NonFiniteVertex { triangle: 0, .. }),
        "{e:?}"
    );
}

#[test]
fn file_scenes_and_their_errors() {
    // A file of another kind is refused with the kinds a scene may be.
    let dir = scene(&[("notes.txt", "hi")]);
    let e = Scene::load(&dir.path().join("notes.txt")).unwrap_err();
    assert!(matches!(e, SceneError::NotADirectory { .. }), "{e:?}");
    assert!(e.to_string().contains(".gltf or .glb"), "{e}");
    // One OBJ out of a directory of several.
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let dir = scene(&[("a.obj", tri), ("b.obj", tri)]);
    let s = Scene::load(&dir.path().join("b.obj")).unwrap();
    assert_eq!(s.triangles.len(), 1);
    assert_eq!(s.name, "b");
    assert_eq!(s.files.len(), 1);
    assert!(Path::new(&s.files[0]).ends_with("b.obj"));
    assert_eq!(Scene::load(dir.path()).unwrap().triangles.len(), 2);
}

#[test]
fn an_emissive_scene_gets_no_default_light() {
    let obj = "mtllib l.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nusemtl lamp\nf 1 2 3\n\
               usemtl wall\nf 1 2 4\n";
    let mtl = "newmtl lamp\nKd 0 0 0\nKe 17 12 4\nnewmtl wall\nKd 0.5 0.5 0.5\n";
    let dir = scene(&[("l.obj", obj), ("l.mtl", mtl)]);
    let s = Scene::load(dir.path()).unwrap();
    assert!(s.lights.is_empty(), "{:?}", s.lights);
    assert_eq!(s.materials[0].emission, [17.0, 12.0, 4.0]);
    let w = s.warnings.join("\n");
    assert!(w.contains("lit by its emissive material(s) `lamp`"), "{w}");
    // An emissive material no triangle uses lights nothing: the default light comes.
    let obj = obj.replace("usemtl lamp", "usemtl wall");
    let dir = scene(&[("l.obj", &obj), ("l.mtl", mtl)]);
    assert_eq!(Scene::load(dir.path()).unwrap().lights.len(), 1);
}

#[test]
fn conversions() {
    // Roughness 1: GGX alpha 1, Blinn-Phong exponent 0.
    assert_eq!(phong_exponent(1.0), 0.0);
    // Roughness 0.5: alpha 0.25, 2 / 0.0625 - 2 = 30, a quarter of it.
    assert!((phong_exponent(0.5) - 7.5).abs() < 1e-5);
    assert!(phong_exponent(0.0).is_finite());
    // A smooth metal keeps its colour as specular albedo.
    let (kd, ks, ns) = convert_material([0.9, 0.6, 0.3], 1.0, 0.3);
    assert_eq!(kd, [0.0; 3]);
    assert_eq!(ks, [0.9, 0.6, 0.3]);
    assert!(ns > 1.0);
    // Kd + Ks never exceeds one.
    for (m, r) in [(0.0, 0.2), (0.5, 0.5), (0.3, 1.0)] {
        let (kd, ks, _) = convert_material([1.0; 3], m, r);
        assert!(kd[0] + ks[0] <= 1.0 + 1e-6, "{m} {r}: {kd:?} {ks:?}");
    }
    // Equal cone angles: the hard cone itself; a soft edge sends less, a narrower cone.
    assert!((equivalent_cone(0.5, 0.5) - 0.5).abs() < 1e-5);
    let soft = equivalent_cone(0.0, 0.5);
    assert!(soft > 0.0 && soft < 0.5, "{soft}");
    // Strips alternate their winding; fans share the first vertex.
    use gltf::mesh::Mode;
    let i = [0, 1, 2, 3];
    assert_eq!(
        primitive_triangles(Mode::TriangleStrip, &i),
        Some(vec![[0, 1, 2], [2, 1, 3]])
    );
    assert_eq!(
        primitive_triangles(Mode::TriangleFan, &i),
        Some(vec![[1, 2, 0], [2, 3, 0]])
    );
    assert_eq!(primitive_triangles(Mode::Lines, &i), None);
}
