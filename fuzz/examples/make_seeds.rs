//! Fills the seed corpora `fuzz/corpus/<target>/` (gitignored):
//!
//! - every target: [`cssm_fuzz::seeds`] (built-in scenes, hand-written inputs, a tiny hand-made
//!   CSSM in both codings);
//! - `cssm_file`, `cssm_header`, `cssm_payload`: each `.cssm` file given, whole, as its header
//!   (and a few bytes more), and as its raw payload (the zstd frame after the header
//!   decompressed, behind a flag byte);
//! - `scene_toml`, `obj_mtl`: each scene directory given (default: `scenes/*/`): its
//!   `scene.toml`, and each OBJ with the first MTL it names (`mtllib` renamed `scene.mtl`).
//!
//! On the way it checks that the payloads of the real files re-encode (bincode) to their own
//! bytes.
//!
//! ```text
//! cargo run --manifest-path fuzz/Cargo.toml --example make_seeds -- [FILE.cssm | SCENE_DIR]...
//! ```

use std::path::{Path, PathBuf};

use cssm_formats::cssm::{self, FLAG_PACKED_RUNS, HEADER_LEN};
use cssm_fuzz::{TARGETS, bincode_standard, join_obj_mtl, packed_fields, seeds};

fn main() {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR"));
    let corpus = fuzz.join("corpus");
    let write = |target: &str, name: &str, bytes: &[u8]| {
        let dir = corpus.join(target);
        std::fs::create_dir_all(&dir).expect("make the corpus directory");
        std::fs::write(dir.join(name), bytes).expect("write a seed");
        println!("{target}/{name}: {} bytes", bytes.len());
    };

    for target in TARGETS {
        for (name, bytes) in seeds(target) {
            write(target, &format!("seed-{name}"), &bytes);
        }
    }

    let mut args: Vec<PathBuf> = std::env::args_os().skip(1).map(PathBuf::from).collect();
    if !args.iter().any(|a| a.is_dir()) {
        let scenes = fuzz.join("../scenes");
        let mut dirs: Vec<PathBuf> = std::fs::read_dir(&scenes)
            .expect("scenes/")
            .map(|e| e.expect("scenes/ entry").path())
            .filter(|p| p.is_dir())
            .collect();
        dirs.sort();
        args.extend(dirs);
    }
    for arg in &args {
        let stem = arg
            .file_stem()
            .expect("a file name")
            .to_string_lossy()
            .into_owned();
        if arg.is_dir() {
            scene_seeds(arg, &stem, &write);
            continue;
        }
        let bytes = std::fs::read(arg).expect("read a .cssm file");
        let file = cssm::decode(&bytes).expect("a valid .cssm file");
        write("cssm_file", &format!("{stem}.cssm"), &bytes);
        write("cssm_header", &format!("{stem}-head"), &bytes[..HEADER_LEN]);
        write(
            "cssm_header",
            &format!("{stem}-head64"),
            &bytes[..HEADER_LEN + 16],
        );
        let flags = u32::from_le_bytes(bytes[12..16].try_into().expect("4 bytes"));
        let raw = zstd::decode_all(&bytes[HEADER_LEN..]).expect("zstd payload");
        let ours = if flags & FLAG_PACKED_RUNS != 0 {
            bincode_standard(&packed_fields(&file))
        } else {
            bincode_standard(&file)
        };
        assert!(
            ours == raw,
            "{}: the payload does not re-encode to its own bytes",
            arg.display()
        );
        let mut payload = vec![flags as u8];
        payload.extend_from_slice(&raw);
        write("cssm_payload", &stem, &payload);
    }
    cssm_fuzz::remove_scratch();
}

/// The seeds of one scene directory.
fn scene_seeds(dir: &Path, stem: &str, write: &impl Fn(&str, &str, &[u8])) {
    if let Ok(toml) = std::fs::read(dir.join("scene.toml")) {
        write("scene_toml", stem, &toml);
    }
    let mut objs: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("a scene directory")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj")))
        .collect();
    objs.sort();
    for obj in objs {
        let text = std::fs::read_to_string(&obj).expect("an OBJ");
        let mut mtl = None;
        let mut out = String::new();
        for line in text.lines() {
            match line.strip_prefix("mtllib ") {
                Some(name) if mtl.is_none() => {
                    mtl = std::fs::read(dir.join(name.trim())).ok();
                    out.push_str("mtllib scene.mtl\n");
                }
                _ => {
                    out.push_str(line);
                    out.push('\n');
                }
            }
        }
        let name = format!(
            "{stem}-{}",
            obj.file_stem().expect("a name").to_string_lossy()
        );
        write(
            "obj_mtl",
            &name,
            &join_obj_mtl(out.as_bytes(), mtl.as_deref()),
        );
    }
}
