//! OBJ/MTL loading via tobj: one OBJ file (triangulated, with its MTL libraries read, bounded and
//! hashed here) is checked triangle by triangle (indices, NaN/infinite vertices, degenerate and
//! empty meshes) and appended to the scene's [`Builder`].

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};

use super::{Builder, Hasher, Material, SceneError, TextureSource, read_bounded};

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
                        let parsed = normalise_mtl(&mtl_bytes).and_then(|text| {
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
            self.materials.push(Material {
                name: m.name.clone(),
                kd,
                ks,
                ns,
                map_kd,
                emission,
                map_emission,
            });
        }

        // Geometry.
        let vertex_base = self.positions.len();
        let mut positions: Vec<Vec3> = Vec::new();
        let mut texcoords: Vec<[f32; 2]> = Vec::new();
        let mut triangles: Vec<[u32; 3]> = Vec::new();
        let mut tri_materials: Vec<u32> = Vec::new();
        let mut without_material: Vec<String> = Vec::new();
        let mut file_triangle = 0usize;
        let mut degenerate = 0usize;
        let mut total = 0usize;
        for model in &models {
            let mesh = &model.mesh;
            let n = mesh.positions.len() / 3;
            let has_uv = mesh.texcoords.len() == 2 * n && n > 0;
            if !has_uv && !mesh.indices.is_empty() {
                self.all_have_texcoords = false;
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
            // Vertices of this model are compacted: only those used by kept triangles survive.
            let mut remap = vec![u32::MAX; n];
            for tri in mesh.indices.chunks(3) {
                let t = file_triangle;
                file_triangle += 1;
                if tri.len() < 3 {
                    // tobj triangulates, so this cannot happen; refuse rather than guess.
                    return Err(SceneError::ObjParse {
                        path: path.to_path_buf(),
                        message: format!("face {t} has fewer than 3 vertices"),
                    });
                }
                total += 1;
                let mut corners = [Vec3::ZERO; 3];
                for (c, &i) in corners.iter_mut().zip(tri) {
                    if i as usize >= n {
                        return Err(SceneError::IndexOutOfRange {
                            path: path.to_path_buf(),
                            triangle: t,
                            index: i,
                            vertex_count: n,
                        });
                    }
                    let i = i as usize;
                    let p = Vec3::new(
                        mesh.positions[3 * i],
                        mesh.positions[3 * i + 1],
                        mesh.positions[3 * i + 2],
                    );
                    let p = match transform {
                        Some((m, t)) => m * p + t,
                        None => p,
                    };
                    if !p.is_finite() {
                        return Err(SceneError::NonFiniteVertex {
                            path: path.to_path_buf(),
                            triangle: t,
                        });
                    }
                    *c = p;
                }
                // Area test in f64, so that tiny but valid triangles are not lost to underflow.
                let [a, b, c] = corners.map(|v| v.as_dvec3());
                let cross = (b - a).cross(c - a).length_squared();
                if cross.is_nan() || cross <= 0.0 {
                    degenerate += 1;
                    continue;
                }
                let mut out = [0u32; 3];
                for ((o, &i), p) in out.iter_mut().zip(tri).zip(corners) {
                    let i = i as usize;
                    if remap[i] == u32::MAX {
                        let global = vertex_base + positions.len();
                        if global >= u32::MAX as usize {
                            return Err(SceneError::Invalid {
                                path: path.to_path_buf(),
                                message: "scene has more than 2^32 - 1 vertices".into(),
                            });
                        }
                        remap[i] = global as u32;
                        positions.push(p);
                        texcoords.push(if has_uv {
                            [mesh.texcoords[2 * i], mesh.texcoords[2 * i + 1]]
                        } else {
                            [0.0; 2]
                        });
                    }
                    *o = remap[i];
                }
                triangles.push(out);
                tri_materials.push(material);
            }
        }
        if total == 0 {
            return Err(SceneError::NoTriangles {
                path: path.to_path_buf(),
            });
        }
        if triangles.is_empty() {
            return Err(SceneError::AllDegenerate {
                path: path.to_path_buf(),
                count: total,
            });
        }
        if degenerate > 0 {
            self.warnings.push(format!(
                "{}: dropped {degenerate} degenerate (zero-area) triangle(s) of {total}",
                path.display()
            ));
        }
        if tri_materials.contains(&u32::MAX) {
            let default = self.default_material();
            for m in &mut tri_materials {
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
        self.positions.extend(positions);
        self.texcoords.extend(texcoords);
        self.triangles.extend(triangles);
        self.triangle_materials.extend(tri_materials);
        Ok(())
    }
}

/// Makes an MTL acceptable to tobj: a colour statement (`Ka`, `Kd`, `Ks`, `Ke`) with a single
/// value means grey (MTL spec) but panics tobj, so it is expanded to three values; one with two
/// values is an error naming the line.
fn normalise_mtl(bytes: &[u8]) -> Result<String, String> {
    let text = std::str::from_utf8(bytes).map_err(|_| "not valid UTF-8".to_string())?;
    let mut out = String::with_capacity(text.len() + 64);
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let key = words.next();
        let values: Vec<&str> = words.collect();
        match key {
            Some(k @ ("Ka" | "Kd" | "Ks" | "Ke")) if values.len() < 3 => match values[..] {
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
    Ok(out)
}

#[cfg(test)]
mod tests {
    use crate::scene::tests::{QUAD_OBJ, err, scene};
    use crate::scene::{Scene, SceneError};

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
