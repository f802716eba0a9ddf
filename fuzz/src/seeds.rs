//! The seeds: inputs for each target that need no bake, from which the corpora start and which
//! `tests/fuzzed.rs` replays.

use super::*;

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
