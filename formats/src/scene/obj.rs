//! OBJ/MTL loading via tobj: one OBJ file (triangulated, with its MTL libraries read, bounded and
//! hashed here) is checked triangle by triangle (indices, NaN/infinite vertices, degenerate and
//! empty meshes) and appended to the scene's [`Builder`].

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};

use super::{
    Builder, Hasher, Material, NormalMap, NormalMapKind, SceneError, TextureSource, read_bounded,
};

/// An MTL library the OBJ asked for: its path and its bytes (or why they could not be read).
type MtlRead = (PathBuf, Result<Vec<u8>, SceneError>);

/// OBJ files up to this size get the line of a parse error found ([`first_failing_line`]
/// parses the file about log2(lines) more times).
const LOCATE_ERRORS_BELOW_BYTES: usize = 256 << 20;

/// The line (1-based) and text of the first line of an OBJ that tobj refuses, which tobj does
/// not say: the shortest prefix of whole lines that fails to parse ends with it (a line that
/// fails to parse fails every prefix holding it; a face indexing past the vertices fails as
/// soon as the prefix ends after it). MTL libraries are not read for the search.
fn first_failing_line(bytes: &[u8], options: &tobj::LoadOptions) -> Option<(usize, String)> {
    if bytes.len() > LOCATE_ERRORS_BELOW_BYTES {
        return None;
    }
    let ends: Vec<usize> = bytes
        .iter()
        .enumerate()
        .filter(|&(_, &b)| b == b'\n')
        .map(|(i, _)| i + 1)
        .chain((bytes.last() != Some(&b'\n')).then_some(bytes.len()))
        .collect();
    let fails = |lines: usize| {
        let prefix = &bytes[..ends[lines - 1]];
        std::panic::catch_unwind(|| {
            tobj::load_obj_buf(&mut &prefix[..], options, |_| {
                Ok((Vec::new(), Default::default()))
            })
            .is_err()
        })
        .unwrap_or(true)
    };
    // The smallest failing prefix, if the whole file fails without its MTL files.
    let (mut lo, mut hi) = (1, ends.len());
    if hi == 0 || !fails(hi) {
        return None;
    }
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if fails(mid) { hi = mid } else { lo = mid + 1 }
    }
    let start = if lo == 1 { 0 } else { ends[lo - 2] };
    let text = String::from_utf8_lossy(&bytes[start..ends[lo - 1]]);
    let text: String = text.trim_end().chars().take(80).collect();
    Some((lo, text.replace(char::is_control, "\u{fffd}")))
}

impl Builder {
    /// Warns when the texture file `texture` of material `material` (named in `path`) is
    /// missing or not a regular file: the material then renders without it.
    pub(super) fn warn_about_texture(&mut self, path: &Path, material: &str, texture: &Path) {
        let problem = match std::fs::metadata(texture) {
            Ok(meta) => crate::files::kind_of(&meta).map(|kind| format!("is {kind}")),
            Err(_) => Some("not found".to_string()),
        };
        if let Some(problem) = problem {
            self.warnings.push(format!(
                "{}: material `{material}`: texture {} {problem}",
                path.display(),
                texture.display()
            ));
        }
    }

    /// Loads one OBJ file (with its MTL libraries), transforms it by `transform` and appends it.
    pub(super) fn add_obj(
        &mut self,
        path: &Path,
        transform: Option<(Mat3, Vec3)>,
        hasher: &mut Hasher,
    ) -> Result<(), SceneError> {
        let bytes = read_bounded(path)?;
        hasher.add(path, &bytes);
        let obj_dir = path.parent().unwrap_or(Path::new("."));

        // MTL libraries: read them ourselves to bound their size and hash them.
        let mtl_files: RefCell<Vec<MtlRead>> = RefCell::default();
        let mtl_errors: RefCell<Vec<SceneError>> = RefCell::default();
        let mtl_warnings: RefCell<Vec<String>> = RefCell::default();
        let nameless_mtllib = std::cell::Cell::new(false);
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: true,
            ..Default::default()
        };
        // tobj has a few panicking paths on malformed input: turn a panic into a parse error.
        let loaded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            tobj::load_obj_buf(&mut &bytes[..], &options, |mtl: &Path| {
                // `mtllib` with no name: like a missing library (joined to the OBJ's folder it
                // would name the folder itself).
                if mtl.as_os_str().is_empty() {
                    nameless_mtllib.set(true);
                    return Err(tobj::LoadError::OpenFileFailed);
                }
                let mtl_path = obj_dir.join(mtl);
                match read_bounded(&mtl_path) {
                    Ok(mtl_bytes) => {
                        let parsed = normalise_mtl(&mtl_bytes).and_then(|(text, warnings)| {
                            mtl_warnings.borrow_mut().extend(
                                warnings
                                    .into_iter()
                                    .map(|w| format!("{}: {w}", mtl_path.display())),
                            );
                            tobj::load_mtl_buf(&mut text.as_bytes()).map_err(|e| e.to_string())
                        });
                        let parsed = match parsed {
                            Ok(p) => Ok(p),
                            Err(message) => {
                                mtl_errors.borrow_mut().push(SceneError::Mtl {
                                    path: mtl_path.clone(),
                                    message,
                                });
                                Err(tobj::LoadError::MaterialParseError)
                            }
                        };
                        mtl_files.borrow_mut().push((mtl_path, Ok(mtl_bytes)));
                        parsed
                    }
                    Err(e) => {
                        mtl_files.borrow_mut().push((mtl_path, Err(e)));
                        Err(tobj::LoadError::OpenFileFailed)
                    }
                }
            })
        }))
        .map_err(|_| SceneError::ObjParse {
            path: path.to_path_buf(),
            message: "the OBJ/MTL parser failed on malformed input".into(),
        })?;
        if let Some(e) = mtl_errors.borrow_mut().drain(..).next() {
            return Err(e);
        }
        let (models, materials) = loaded.map_err(|e| SceneError::ObjParse {
            path: path.to_path_buf(),
            message: match first_failing_line(&bytes, &options) {
                Some((line, text)) => format!("line {line}: {e}: `{text}`"),
                None => e.to_string(),
            },
        })?;
        self.warnings.append(&mut mtl_warnings.borrow_mut());
        if nameless_mtllib.get() {
            self.warnings.push(format!(
                "{}: an `mtllib` line names no file; its materials become the grey Lambertian \
                 `default` (Kd 0.5)",
                path.display()
            ));
        }
        for (mtl_path, result) in mtl_files.into_inner() {
            match result {
                Ok(mtl_bytes) => hasher.add(&mtl_path, &mtl_bytes),
                Err(SceneError::Io { error, .. })
                    if error.kind() == std::io::ErrorKind::NotFound =>
                {
                    self.warnings.push(format!(
                        "{}: material library {} not found; its materials become the grey \
                         Lambertian `default` (Kd 0.5)",
                        path.display(),
                        mtl_path.display()
                    ));
                }
                Err(e) => return Err(e),
            }
        }

        // Materials of this file.
        let materials = materials.unwrap_or_default();
        let material_base = self.materials.len() as u32;
        for m in &materials {
            let kd = m.diffuse.unwrap_or([0.5; 3]);
            let ks = m.specular.unwrap_or([0.0; 3]);
            let ns = m.shininess.unwrap_or(1.0);
            let emission = m.emissive.unwrap_or([0.0; 3]);
            if !kd
                .iter()
                .chain(&ks)
                .chain([&ns])
                .chain(&emission)
                .all(|v| v.is_finite() && *v >= 0.0)
            {
                return Err(SceneError::Mtl {
                    path: path.to_path_buf(),
                    message: format!(
                        "material `{}` has a negative or non-finite Kd, Ks, Ns or Ke",
                        m.name
                    ),
                });
            }
            let mut texture = |name: Option<&String>| {
                let t = obj_dir.join(name?);
                self.warn_about_texture(path, &m.name, &t);
                Some(TextureSource::File(t))
            };
            let map_kd = texture(m.diffuse_texture.as_ref());
            let map_emission = texture(m.unknown_param.get("map_Ke"));
            // `normalise_mtl` rewrote the bump and normal-map statements as
            // `<BUMP_KEY|NORM_KEY> <multiplier> <file>`; the last one of a material wins.
            let detail = |key: &str| {
                let value = m.unknown_param.get(key)?;
                let (multiplier, file) = value.split_once(' ')?;
                Some((multiplier.parse::<f32>().ok()?, file.to_string()))
            };
            let normal_map = match (detail(NORM_KEY), detail(BUMP_KEY)) {
                (Some((scale, file)), _) => texture(Some(&file)).map(|source| NormalMap {
                    source,
                    kind: NormalMapKind::Tangent { scale },
                }),
                (None, Some((multiplier, file))) => texture(Some(&file)).map(|source| NormalMap {
                    source,
                    kind: NormalMapKind::Height { multiplier },
                }),
                (None, None) => None,
            };
            self.materials.push(Material {
                name: m.name.clone(),
                kd,
                ks,
                ns,
                map_kd,
                emission,
                map_emission,
                normal_map,
            });
        }

        // Geometry.
        let first_triangle = self.triangles.len();
        let mut counts = super::FileCounts::default();
        let mut without_material: Vec<String> = Vec::new();
        for model in &models {
            let mesh = &model.mesh;
            if mesh.indices.len() % 3 != 0 {
                // tobj triangulates, so this cannot happen; refuse rather than guess.
                return Err(SceneError::ObjParse {
                    path: path.to_path_buf(),
                    message: format!(
                        "object `{}` has a face of fewer than 3 vertices",
                        model.name
                    ),
                });
            }
            let material = match mesh.material_id {
                Some(id) if id < materials.len() => material_base + id as u32,
                _ => {
                    if !mesh.indices.is_empty() {
                        without_material.push(model.name.clone());
                    }
                    u32::MAX // resolved below
                }
            };
            let positions: Vec<Vec3> = mesh
                .positions
                .chunks_exact(3)
                .map(|p| {
                    let p = Vec3::new(p[0], p[1], p[2]);
                    match transform {
                        Some((m, t)) => m * p + t,
                        None => p,
                    }
                })
                .collect();
            let texcoords: Vec<[f32; 2]> = mesh
                .texcoords
                .chunks_exact(2)
                .map(|t| [t[0], t[1]])
                .collect();
            let has_uv = texcoords.len() == positions.len() && !positions.is_empty();
            let triangles = mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]);
            self.append_part(
                path,
                &positions,
                has_uv.then_some(&texcoords[..]),
                triangles,
                material,
                &mut counts,
            )?;
        }
        self.finish_file(path, &counts, first_triangle)?;
        if self.triangle_materials[first_triangle..].contains(&u32::MAX) {
            let default = self.default_material();
            for m in &mut self.triangle_materials[first_triangle..] {
                if *m == u32::MAX {
                    *m = default;
                }
            }
            let names: Vec<String> = without_material
                .iter()
                .map(|n| {
                    if n.is_empty() {
                        "(unnamed)".into()
                    } else {
                        format!("`{n}`")
                    }
                })
                .collect();
            self.warnings.push(format!(
                "{}: object(s) {} have no material; using the grey Lambertian `default` (Kd 0.5)",
                path.display(),
                names.join(", ")
            ));
        }
        Ok(())
    }
}

/// The key `normalise_mtl` files a height map under (`bump`, `map_Bump` in any case).
const BUMP_KEY: &str = "cssm_bump";
/// The key `normalise_mtl` files a tangent-space normal map under (`norm`, `map_norm`).
const NORM_KEY: &str = "cssm_norm";

/// Options of an MTL texture statement and how many values each takes (at most; `-o`, `-s`
/// and `-t` take one to three numbers), from the MTL specification.
const TEXTURE_OPTIONS: &[(&str, usize)] = &[
    ("-blendu", 1),
    ("-blendv", 1),
    ("-bm", 1),
    ("-boost", 1),
    ("-cc", 1),
    ("-clamp", 1),
    ("-imfchan", 1),
    ("-mm", 2),
    ("-o", 3),
    ("-s", 3),
    ("-t", 3),
    ("-texres", 1),
    ("-type", 1),
];

/// A parsed MTL texture statement (`[options] file`).
#[derive(Debug)]
struct TextureStatement {
    /// The `-bm` multiplier (1 without it); only bump statements use it.
    multiplier: f32,
    /// The file name: the words after the options, spaces kept as single spaces.
    file: String,
    /// The options that change the texture lookup (`-s`, `-o`, `-t` away from their identity
    /// values, `-clamp on`), as written. The renderer (GPU and CPU twins) samples every
    /// texture with the mesh's UVs, repeating; these are skipped, and the caller warns rather
    /// than let the texture silently land elsewhere than the exporter meant.
    ignored: Vec<String>,
}

/// Parses the arguments of a texture statement (`map_Kd`, `map_Ke`, bump, normal map):
/// `[options] file`. Options that do not change the lookup are skipped silently; those that
/// do are listed in `ignored`.
fn texture_statement(values: &[&str]) -> Result<TextureStatement, String> {
    let mut multiplier = 1.0f32;
    let mut ignored = Vec::new();
    let mut i = 0;
    while i < values.len() {
        let Some(&(option, count)) = TEXTURE_OPTIONS
            .iter()
            .find(|(o, _)| o.eq_ignore_ascii_case(values[i]))
        else {
            break;
        };
        i += 1;
        if option == "-bm" {
            multiplier = match values.get(i).map(|v| v.parse::<f32>()) {
                Some(Ok(v)) if v.is_finite() => v,
                _ => return Err("`-bm` needs a finite number".into()),
            };
            i += 1;
            continue;
        }
        // The option's values: `count` words, fewer for `-o`, `-s`, `-t` when a non-number
        // (the file) follows sooner. No word is kept back for the file: `map_Kd -s 2 2 1` is
        // a statement without a file (an error), not a texture named `1`.
        let numeric = count == 3;
        let first = i;
        let mut taken = 0;
        while taken < count && i < values.len() {
            if numeric && taken > 0 && values[i].parse::<f32>().is_err() {
                break;
            }
            i += 1;
            taken += 1;
        }
        if taken == 0 {
            return Err(format!("`{option}` needs a value"));
        }
        let given = &values[first..i];
        // Identity values (`-s 1 1 1`, `-o 0 0 0`, as some exporters always write) change
        // nothing: no warning for them.
        let is = |identity: f32| given.iter().all(|v| v.parse::<f32>() == Ok(identity));
        let changes_lookup = match option {
            "-s" => !is(1.0),
            "-o" | "-t" => !is(0.0),
            "-clamp" => !given[0].eq_ignore_ascii_case("off"),
            _ => false,
        };
        if changes_lookup {
            ignored.push(format!("{option} {}", given.join(" ")));
        }
    }
    if i >= values.len() {
        return Err("names no texture file".into());
    }
    Ok(TextureStatement {
        multiplier,
        file: values[i..].join(" "),
        ignored,
    })
}

/// Makes an MTL acceptable to tobj: a colour statement (`Ka`, `Kd`, `Ks`, `Ke`) with a single
/// value means grey (MTL spec) but panics tobj, so it is expanded to three values; one with two
/// values is an error naming the line. Texture statements are parsed here (options skipped,
/// errors naming the line) and written back with the bare file name: `map_Kd` and `map_Ke`
/// (any case, as exporters write them) as `map_Kd`/`map_Ke <file>`, which tobj reads
/// case-sensitively and with no option parsing of its own; bump statements (`bump`,
/// `map_Bump`) and normal-map statements (`norm`, `map_norm`) as
/// `cssm_bump`/`cssm_norm <multiplier> <file>`, which tobj keeps as unknown parameters.
/// Returns the text and warnings (`line N: ...`) for options the renderer cannot apply.
fn normalise_mtl(bytes: &[u8]) -> Result<(String, Vec<String>), String> {
    let text = std::str::from_utf8(bytes).map_err(|_| "not valid UTF-8".to_string())?;
    let mut out = String::with_capacity(text.len() + 64);
    let mut warnings = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let key = words.next();
        let values: Vec<&str> = words.collect();
        let texture_key = key.and_then(|k| {
            [
                ("map_kd", "map_Kd"),
                ("map_ke", "map_Ke"),
                ("bump", BUMP_KEY),
                ("map_bump", BUMP_KEY),
                ("norm", NORM_KEY),
                ("map_norm", NORM_KEY),
            ]
            .iter()
            .find(|(spelling, _)| k.eq_ignore_ascii_case(spelling))
            .map(|&(_, key)| (k, key))
        });
        match (key, texture_key) {
            (_, Some((k, key))) => {
                let statement =
                    texture_statement(&values).map_err(|e| format!("line {}: `{k}` {e}", i + 1))?;
                for option in &statement.ignored {
                    warnings.push(format!(
                        "line {}: `{k}` option `{option}` ignored (the renderer does not scale, \
                         offset, perturb or clamp texture lookups); {} is used as is",
                        i + 1,
                        statement.file
                    ));
                }
                if key == BUMP_KEY || key == NORM_KEY {
                    out.push_str(&format!(
                        "{key} {} {}",
                        statement.multiplier, statement.file
                    ));
                } else {
                    out.push_str(&format!("{key} {}", statement.file));
                }
            }
            (Some(k @ ("Ka" | "Kd" | "Ks" | "Ke")), None) if values.len() < 3 => match values[..] {
                [v] => out.push_str(&format!("{k} {v} {v} {v}")),
                _ => {
                    return Err(format!(
                        "line {}: `{k}` needs 1 or 3 values, got {}",
                        i + 1,
                        values.len()
                    ));
                }
            },
            _ => out.push_str(line),
        }
        out.push('\n');
    }
    Ok((out, warnings))
}

#[cfg(test)]
mod tests {
    use crate::scene::tests::{QUAD_OBJ, err, scene};
    use crate::scene::{NormalMapKind, Scene, SceneError};

    #[test]
    fn nan_vertex_is_an_error() {
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 nan\nf 1 2 3\nf 1 2 4\n";
        let dir = scene(&[("bad.obj", obj)]);
        let e = Scene::load(dir.path()).unwrap_err();
        assert!(
            matches!(e, SceneError::NonFiniteVertex { triangle: 1, .. }),
            "{e:?}"
        );
        let msg = e.to_string();
        assert!(
            msg.contains("bad.obj") && msg.contains("triangle 1"),
            "{msg}"
        );
        // An unused infinite vertex is harmless and dropped.
        let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv inf 0 0\nf 1 2 3\n";
        let dir = scene(&[("ok.obj", obj)]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.positions.len(), 3);
        assert!(s.bounds().1.is_finite());
    }

    #[test]
    fn empty_and_degenerate_objs() {
        let e = err(&[("empty.obj", "# nothing\nv 0 0 0\n")]);
        assert!(e.contains("empty.obj") && e.contains("no triangles"), "{e}");

        let obj = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n";
        let e = err(&[("flat.obj", obj)]);
        assert!(e.contains("flat.obj") && e.contains("degenerate"), "{e}");

        // Some degenerate: dropped with a warning.
        let obj = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n";
        let dir = scene(&[("some.obj", obj)]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.triangles.len(), 1);
        assert_eq!(s.positions.len(), 3);
        let w = s.warnings.join("\n");
        assert!(w.contains("dropped 1 degenerate"), "{w}");
    }

    /// An `mtllib` line with no name is a missing library (a warning), not the OBJ's folder
    /// read as one (found by fuzzing: "it is a directory, not a file").
    #[test]
    fn a_nameless_mtllib_is_a_warning() {
        let obj = QUAD_OBJ.replace("mtllib quad.mtl", "mtllib");
        let dir = scene(&[("quad.obj", &obj)]);
        let s = Scene::load(dir.path()).unwrap();
        let w = s.warnings.join("\n");
        assert!(w.contains("an `mtllib` line names no file"), "{w}");
        assert_eq!(s.triangles.len(), 2);
    }

    /// The bump statements of the MTL (`bump`, `map_Bump`, any case, with `-bm` and other
    /// options) give a height map, `norm` a tangent-space normal map; a missing file is the
    /// same warning as a missing `map_Kd`; a malformed statement is an error naming the line.
    #[test]
    fn bump_and_normal_maps_from_the_mtl() {
        let material = |mtl: &str| {
            let dir = scene(&[("quad.obj", QUAD_OBJ), ("quad.mtl", mtl)]);
            let s = Scene::load(dir.path()).unwrap();
            let m = s.materials[0].normal_map.clone().expect("a normal map");
            let file = m.source.file().unwrap().strip_prefix(&s.path).unwrap();
            (file.to_string_lossy().into_owned(), m.kind, s.warnings)
        };
        let height = |multiplier| NormalMapKind::Height { multiplier };
        for (statement, file, kind) in [
            ("bump kamen-bump.png", "kamen-bump.png", height(1.0)),
            ("map_Bump kamen-bump.png", "kamen-bump.png", height(1.0)),
            ("  map_bump kamen-bump.png", "kamen-bump.png", height(1.0)),
            ("MAP_BUMP -bm 0.5 b.png", "b.png", height(0.5)),
            ("Bump -bm -2 b.png", "b.png", height(-2.0)),
            (
                "bump -s 2 2 1 -bm 0.25 -clamp on b c.png",
                "b c.png",
                height(0.25),
            ),
            ("bump -o 0.5 -mm 0 1 b.png", "b.png", height(1.0)),
            ("norm n.png", "n.png", NormalMapKind::Tangent { scale: 1.0 }),
            (
                "norm -bm 0.5 n.png",
                "n.png",
                NormalMapKind::Tangent { scale: 0.5 },
            ),
        ] {
            let (got_file, got_kind, warnings) = material(&format!("newmtl white\n{statement}\n"));
            assert_eq!((got_file.as_str(), got_kind), (file, kind), "{statement}");
            // The file does not exist: the warning of a missing `map_Kd`.
            let w = warnings.join("\n");
            assert!(w.contains("material `white`: texture"), "{w}");
            assert!(w.contains(&format!("{file} not found")), "{statement}: {w}");
        }
        // Sibenik's pair (`map_bump` and `bump` of one file): one height map, one warning.
        let (file, kind, warnings) = material(
            "newmtl white\nmap_Kd wood.png\nmap_bump kamen-bump.png\nbump kamen-bump.png\n",
        );
        assert_eq!((file.as_str(), kind), ("kamen-bump.png", height(1.0)));
        assert_eq!(
            warnings
                .iter()
                .filter(|w| w.contains("kamen-bump.png"))
                .count(),
            1,
            "{warnings:?}"
        );
        // A normal map wins over a height map.
        let (file, kind, _) = material("newmtl white\nnorm n.png\nbump b.png\n");
        assert_eq!(
            (file.as_str(), kind),
            ("n.png", NormalMapKind::Tangent { scale: 1.0 })
        );
        // An existing file: no warning.
        let dir = scene(&[
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", "newmtl white\nbump b.png\n"),
            ("b.png", "not checked here"),
        ]);
        let s = Scene::load(dir.path()).unwrap();
        assert!(
            !s.warnings.join("\n").contains("texture"),
            "{:?}",
            s.warnings
        );
        assert!(s.input_files().contains(&s.path.join("b.png")));
        // Malformed statements name the line.
        for (statement, problem) in [
            ("bump -bm", "`-bm` needs a finite number"),
            ("bump -bm x b.png", "`-bm` needs a finite number"),
            ("bump -bm nan b.png", "`-bm` needs a finite number"),
            ("map_Bump -bm 2", "names no texture file"),
            ("norm", "names no texture file"),
        ] {
            let e = err(&[
                ("quad.obj", QUAD_OBJ),
                (
                    "quad.mtl",
                    &format!("newmtl white\nKd 1 1 1\n{statement}\n"),
                ),
            ]);
            assert!(
                e.contains("quad.mtl") && e.contains("line 3"),
                "{statement}: {e}"
            );
            assert!(e.contains(problem), "{statement}: {e}");
        }
    }

    /// `map_Kd` and `map_Ke` go through the option parsing of the bump statements: any case,
    /// options skipped (a warning naming the file, line and option for those that change the
    /// lookup), a statement with no file an error naming the line.
    #[test]
    fn diffuse_and_emission_maps_take_options() {
        let load = |mtl: &str| {
            let dir = scene(&[("quad.obj", QUAD_OBJ), ("quad.mtl", mtl)]);
            let s = Scene::load(dir.path()).unwrap();
            let name = |t: &Option<crate::scene::TextureSource>| {
                let file = t.as_ref()?.file()?.strip_prefix(&s.path).ok()?;
                Some(file.to_string_lossy().into_owned())
            };
            let m = &s.materials[0];
            (name(&m.map_kd), name(&m.map_emission), s.warnings.clone())
        };
        let lookup_warning = |w: &[String], key: &str, option: &str, file: &str| {
            w.iter().any(|w| {
                w.contains("quad.mtl: line 2:")
                    && w.contains(&format!("`{key}` option `{option}` ignored"))
                    && w.contains(&format!("{file} is used as is"))
            })
        };
        for (statement, file, ignored) in [
            ("map_Kd wood.png", "wood.png", None),
            ("MAP_KD wood.png", "wood.png", None),
            ("  Map_Kd  wood.png", "wood.png", None),
            ("map_Kd -s 2 2 1 wood.png", "wood.png", Some("-s 2 2 1")),
            ("map_Kd -o 0.5 wood.png", "wood.png", Some("-o 0.5")),
            (
                "map_Kd -clamp on my wood.png",
                "my wood.png",
                Some("-clamp on"),
            ),
            // Identity values and options that do not move the lookup: no warning.
            (
                "map_Kd -s 1 1 1 -o 0 0 0 -blendu off -clamp off -mm 0 1 wood.png",
                "wood.png",
                None,
            ),
        ] {
            let (kd, ke, w) = load(&format!("newmtl white\n{statement}\n"));
            assert_eq!((kd.as_deref(), ke), (Some(file), None), "{statement}");
            match ignored {
                Some(option) => {
                    assert!(
                        lookup_warning(
                            &w,
                            statement.split_whitespace().next().unwrap(),
                            option,
                            file
                        ),
                        "{statement}: {w:?}"
                    )
                }
                None => assert!(
                    !w.iter().any(|w| w.contains("ignored")),
                    "{statement}: {w:?}"
                ),
            }
            // The file does not exist: the usual missing-texture warning, with its real name.
            assert!(
                w.iter().any(|w| w.contains(&format!("{file} not found"))),
                "{statement}: {w:?}"
            );
        }
        for statement in ["map_Ke glow.png", "MAP_KE -s 2 glow.png"] {
            let (kd, ke, w) = load(&format!("newmtl white\n{statement}\n"));
            assert_eq!((kd, ke.as_deref()), (None, Some("glow.png")), "{statement}");
            assert_eq!(
                lookup_warning(
                    &w,
                    statement.split_whitespace().next().unwrap(),
                    "-s 2",
                    "glow.png"
                ),
                statement.contains("-s"),
                "{statement}: {w:?}"
            );
        }
        // Bump statements warn the same way.
        let (_, _, w) = load("newmtl white\nbump -o 0.1 0.2 b.png\n");
        assert!(lookup_warning(&w, "bump", "-o 0.1 0.2", "b.png"), "{w:?}");
        // A statement with only options names the line.
        for (statement, problem) in [
            ("map_Kd -s 2 2 1", "names no texture file"),
            ("MAP_KD", "names no texture file"),
            ("map_Ke -clamp on", "names no texture file"),
            ("map_Kd -blendu", "`-blendu` needs a value"),
        ] {
            let e = err(&[
                ("quad.obj", QUAD_OBJ),
                (
                    "quad.mtl",
                    &format!("newmtl white\nKd 1 1 1\n{statement}\n"),
                ),
            ]);
            assert!(
                e.contains("quad.mtl") && e.contains("line 3"),
                "{statement}: {e}"
            );
            assert!(e.contains(problem), "{statement}: {e}");
        }
    }

    #[test]
    fn parse_errors_name_the_file() {
        let e = err(&[("broken.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")]);
        assert!(e.contains("broken.obj"), "{e}");
        assert!(
            e.contains("line 4: face vertex index out of bounds: `f 1 2 9`"),
            "{e}"
        );
        let e = err(&[("broken.obj", "v 0 zero 0\n")]);
        assert!(e.contains("broken.obj") && e.contains("parse error"), "{e}");
        assert!(e.contains("line 1"), "{e}");
        let e = err(&[(
            "broken.obj",
            "# a quad\nv 0 0 0\nv 1 0 0\n\nvn 0 0\nv 0 1 0\nf 1 2 3",
        )]);
        assert!(e.contains("line 5: normal parse error: `vn 0 0`"), "{e}");
        // A malformed MTL colour that would panic tobj.
        let e = err(&[
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", "newmtl white\nKd 0.5 0.5\n"),
        ]);
        assert!(e.contains("quad.mtl") && e.contains("line 2"), "{e}");
        // A single-value colour is grey (MTL spec).
        let dir = scene(&[
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", "newmtl white\nKd 0.25\n"),
        ]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.materials[0].kd, [0.25; 3]);
    }
}
