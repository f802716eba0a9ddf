//! Loading a scene: the [`Builder`] that merges its mesh files (OBJ in `obj.rs`, glTF in
//! `gltf/`) into one mesh with its materials and objects, and [`Scene::load`], which finds
//! the files, reads `scene.toml` and chooses what no file gives.

use super::*;

/// The mesh being assembled: all files merged.
#[derive(Default)]
pub(super) struct Builder {
    pub(super) positions: Vec<Vec3>,
    pub(super) texcoords: Vec<[f32; 2]>,
    pub(super) all_have_texcoords: bool,
    pub(super) triangles: Vec<[u32; 3]>,
    pub(super) triangle_materials: Vec<u32>,
    pub(super) materials: Vec<Material>,
    pub(super) default_material: Option<u32>,
    pub(super) objects: Vec<SceneObject>,
    pub(super) warnings: Vec<String>,
    pub(super) options: LoadOptions,
    /// Triangles placed so far, degenerate ones included ([`MAX_SCENE_TRIANGLES`]).
    pub(super) placed_triangles: usize,
}

/// What [`Scene::load_with`] lets the files it reads do.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Let a glTF file's buffer and image URIs name files outside the glTF's own directory (an
    /// absolute path, a `..` leading out, a link pointing out). Off, such a URI is an error
    /// naming it: a scene file downloaded with a model cannot make the tool read files
    /// elsewhere, nor quote their bytes back in an error.
    pub files_outside: bool,
}

impl Builder {
    pub(super) fn new() -> Self {
        Builder {
            all_have_texcoords: true,
            ..Default::default()
        }
    }

    pub(super) fn default_material(&mut self) -> u32 {
        *self.default_material.get_or_insert_with(|| {
            self.materials.push(Material::grey("default"));
            (self.materials.len() - 1) as u32
        })
    }

    /// Records the triangles appended since triangle `start` as one object.
    pub(super) fn push_object(
        &mut self,
        name: String,
        kind: ObjectKind,
        start: usize,
        transform: Affine3A,
        path: &Path,
    ) -> Result<(), SceneError> {
        let end = u32::try_from(self.triangles.len()).map_err(|_| SceneError::Invalid {
            path: path.to_path_buf(),
            message: "scene has more than 2^32 - 1 triangles".into(),
        })?;
        self.objects.push(SceneObject {
            name,
            kind,
            triangles: start as u32..end,
            transform,
            animation: None,
        });
        Ok(())
    }
}

/// Counts over one mesh file's triangles as [`Builder::append_part`] takes them, for the file's
/// errors and warnings ([`Builder::finish_file`]).
#[derive(Default)]
pub(super) struct FileCounts {
    /// Triangles seen so far, kept or not: the next triangle's number in the file's messages.
    pub(super) seen: usize,
    /// Triangles dropped for zero area.
    pub(super) degenerate: usize,
}

impl Builder {
    /// Appends one part of a mesh file: the triangles `triangles` over the part's own vertices
    /// `positions` (world space; a vertex no kept triangle uses may be anything) with optional
    /// per-vertex `texcoords`, all of material `material` ([`u32::MAX`]: the file's default,
    /// resolved by the caller). Triangles of zero area are dropped and counted; a triangle with
    /// an index past `positions` or a non-finite corner is an error naming its number in the
    /// file. Only the vertices kept triangles use are appended.
    pub(super) fn append_part(
        &mut self,
        path: &Path,
        positions: &[Vec3],
        texcoords: Option<&[[f32; 2]]>,
        triangles: impl IntoIterator<Item = [u32; 3]>,
        material: u32,
        counts: &mut FileCounts,
    ) -> Result<(), SceneError> {
        let n = positions.len();
        let texcoords = texcoords.filter(|t| t.len() == n);
        let triangles = triangles.into_iter();
        // Before allocating: a small file can place one mesh many times (glTF instancing).
        let adding = triangles.size_hint().0;
        if self.placed_triangles.saturating_add(adding) > MAX_SCENE_TRIANGLES {
            return Err(SceneError::Invalid {
                path: path.to_path_buf(),
                message: format!(
                    "the scene would hold more than {MAX_SCENE_TRIANGLES} triangles ({} so far, \
                     {adding} more here; a glTF places each mesh once per node that names it)",
                    self.placed_triangles
                ),
            });
        }
        self.placed_triangles += adding;
        let mut remap = vec![u32::MAX; n];
        let mut any = false;
        for tri in triangles {
            let t = counts.seen;
            counts.seen += 1;
            any = true;
            let mut corners = [Vec3::ZERO; 3];
            for (c, &i) in corners.iter_mut().zip(&tri) {
                let Some(&p) = positions.get(i as usize) else {
                    return Err(SceneError::IndexOutOfRange {
                        path: path.to_path_buf(),
                        triangle: t,
                        index: i,
                        vertex_count: n,
                    });
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
                counts.degenerate += 1;
                continue;
            }
            let mut out = [0u32; 3];
            for (o, &i) in out.iter_mut().zip(&tri) {
                let i = i as usize;
                if remap[i] == u32::MAX {
                    let global = self.positions.len();
                    if global >= u32::MAX as usize {
                        return Err(SceneError::Invalid {
                            path: path.to_path_buf(),
                            message: "scene has more than 2^32 - 1 vertices".into(),
                        });
                    }
                    remap[i] = global as u32;
                    self.positions.push(positions[i]);
                    self.texcoords.push(texcoords.map_or([0.0; 2], |uv| uv[i]));
                }
                *o = remap[i];
            }
            self.triangles.push(out);
            self.triangle_materials.push(material);
        }
        if any && texcoords.is_none() {
            self.all_have_texcoords = false;
        }
        Ok(())
    }

    /// Ends a mesh file whose triangles began at `first_triangle`: an error if it had none or
    /// only degenerate ones, a warning if some were dropped.
    pub(super) fn finish_file(
        &mut self,
        path: &Path,
        counts: &FileCounts,
        first_triangle: usize,
    ) -> Result<(), SceneError> {
        if counts.seen == 0 {
            return Err(SceneError::NoTriangles {
                path: path.to_path_buf(),
            });
        }
        if self.triangles.len() == first_triangle {
            return Err(SceneError::AllDegenerate {
                path: path.to_path_buf(),
                count: counts.seen,
            });
        }
        if counts.degenerate > 0 {
            self.warnings.push(format!(
                "{}: dropped {} degenerate (zero-area) triangle(s) of {}",
                path.display(),
                counts.degenerate,
                counts.seen
            ));
        }
        Ok(())
    }
}

pub(super) fn fmt3(v: Vec3) -> String {
    format!("[{}, {}, {}]", v.x, v.y, v.z)
}

pub(super) fn bounds_of(positions: &[Vec3]) -> (Vec3, Vec3) {
    positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    )
}

/// The mesh formats a scene reads, by file extension.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum MeshFormat {
    Obj,
    Gltf,
}

impl MeshFormat {
    /// The format of `path` by its extension (`.obj`; `.gltf` or `.glb`), any case.
    pub(super) fn of(path: &Path) -> Option<MeshFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(MeshFormat::Obj),
            "gltf" | "glb" => Some(MeshFormat::Gltf),
            _ => None,
        }
    }
}

impl Builder {
    /// Loads the static part from `files`: the OBJs first, merged into one static object, then
    /// each glTF file with one static object per mesh node. The glTF files' first camera and
    /// their lights go into `extras`.
    pub(super) fn add_static(
        &mut self,
        files: &[PathBuf],
        hasher: &mut Hasher,
        extras: &mut gltf::GltfExtras,
    ) -> Result<(), SceneError> {
        let objs: Vec<&PathBuf> = files
            .iter()
            .filter(|p| MeshFormat::of(p) == Some(MeshFormat::Obj))
            .collect();
        for p in &objs {
            self.add_obj(p, None, hasher)?;
        }
        if let Some(first) = objs.first() {
            self.push_object(
                STATIC_OBJECT_NAME.into(),
                ObjectKind::Static,
                0,
                Affine3A::IDENTITY,
                first,
            )?;
        }
        for p in files
            .iter()
            .filter(|p| MeshFormat::of(p) == Some(MeshFormat::Gltf))
        {
            let found = self.add_gltf(p, Affine3A::IDENTITY, gltf::GltfObjects::PerNode, hasher)?;
            if extras.camera.is_none() {
                extras.camera = found.camera;
            }
            extras.lights.extend(found.lights);
        }
        Ok(())
    }

    /// Loads the rigid object `name` from the mesh file `path`, placed by `transform`.
    pub(super) fn add_rigid(
        &mut self,
        name: &str,
        path: &Path,
        (m, t): (Mat3, Vec3),
        animation: Option<animation::Animation>,
        hasher: &mut Hasher,
    ) -> Result<(), SceneError> {
        let start = self.triangles.len();
        let transform = Affine3A::from_mat3_translation(m, t);
        if MeshFormat::of(path) == Some(MeshFormat::Gltf) {
            let found = self.add_gltf(path, transform, gltf::GltfObjects::Whole, hasher)?;
            if found.camera.is_some() || !found.lights.is_empty() {
                self.warnings.push(format!(
                    "object `{name}`: the cameras and lights of {} are ignored (an object's \
                     file gives only its triangles)",
                    path.display()
                ));
            }
        } else {
            self.add_obj(path, Some((m, t)), hasher)?;
        }
        self.push_object(name.into(), ObjectKind::Rigid, start, transform, path)?;
        if let Some(object) = self.objects.last_mut() {
            object.animation = animation;
        }
        Ok(())
    }
}

impl Scene {
    /// Loads the scene at `path`: a directory with `scene.toml` and the meshes it names; a
    /// directory without one, every `.obj`, `.gltf` and `.glb` in it (sorted by file name; the
    /// OBJs first); or one such mesh file. What no file gives, a camera or a light, is chosen
    /// (see `docs/scene-format.md`). Degenerate triangles are dropped with a warning;
    /// everything else that is wrong is an error naming the file. [`Scene::objects`] gets one
    /// static object for the OBJs of the static part, one static object per mesh node of each
    /// glTF file of it, and one rigid object per `[[objects]]` entry, over the triangles each
    /// kept.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        Scene::load_with(path, LoadOptions::default())
    }

    /// [`Scene::load`] with `options`.
    ///
    /// # Errors
    /// As [`Scene::load`].
    pub fn load_with(path: &Path, options: LoadOptions) -> Result<Scene, SceneError> {
        let path = match std::fs::canonicalize(path) {
            Ok(d) => d,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(SceneError::DirNotFound {
                    dir: path.to_path_buf(),
                });
            }
            Err(error) => {
                return Err(SceneError::Io {
                    path: path.to_path_buf(),
                    error,
                });
            }
        };
        let is_dir = path.is_dir();
        let mesh_file = path.is_file() && MeshFormat::of(&path).is_some();
        if !(is_dir || mesh_file) {
            return Err(SceneError::NotADirectory { path });
        }
        let dir = if is_dir {
            path.clone()
        } else {
            path.parent().unwrap_or(Path::new("/")).to_path_buf()
        };
        let mut hasher = Hasher {
            dir: dir.clone(),
            hasher: blake3::Hasher::new(),
            files: Vec::new(),
        };
        let mut b = Builder::new();
        b.options = options;
        let mut extras = gltf::GltfExtras::default();
        let toml_path = dir.join("scene.toml");
        // A directory's (or file's) name with control characters (a terminal escape, say) is
        // shown with them replaced; scene.toml's `name` with one is refused below.
        let default_name = if is_dir {
            path.file_name()
        } else {
            path.file_stem()
        };
        let default_name = default_name
            .map(|n| n.to_string_lossy().replace(char::is_control, "\u{fffd}"))
            .unwrap_or_else(|| "scene".into());

        let (name, camera, lights) = if !is_dir {
            b.add_static(std::slice::from_ref(&path), &mut hasher, &mut extras)?;
            (default_name, None, Vec::new())
        } else if toml_path.exists() {
            let bytes = read_at_most(&toml_path, MAX_SCENE_TOML_BYTES)?;
            hasher.add(&toml_path, &bytes);
            let text = String::from_utf8(bytes).map_err(|_| SceneError::Toml {
                path: toml_path.clone(),
                message: "not valid UTF-8".into(),
            })?;
            let desc: SceneToml = ::toml::from_str(&text).map_err(|e| SceneError::Toml {
                path: toml_path.clone(),
                message: e.to_string().trim_end().to_string(),
            })?;
            // Check the small things before loading any mesh.
            if let Some(c) = desc
                .name
                .as_deref()
                .and_then(|n| n.chars().find(|c| c.is_control()))
            {
                return Err(SceneError::Toml {
                    path: toml_path.clone(),
                    message: format!(
                        "`name` holds the control character U+{:04X}; scene names are printed \
                         and become file names",
                        c as u32
                    ),
                });
            }
            let camera = desc
                .camera
                .as_ref()
                .map(|c| check_camera(c, &toml_path))
                .transpose()?;
            let lights = desc
                .lights
                .iter()
                .enumerate()
                .map(|(i, l)| check_light(i, l, &toml_path))
                .collect::<Result<Vec<_>, _>>()?;
            let transforms = desc
                .objects
                .iter()
                .map(|o| object_transform(o, &toml_path))
                .collect::<Result<Vec<_>, _>>()?;
            let animations = desc
                .objects
                .iter()
                .map(|o| {
                    o.animation
                        .as_ref()
                        .map(|a| {
                            let pose = (o.translation.into(), o.rotation_deg.into(), o.scale);
                            animation::check_animation(a, &o.name, pose, &toml_path)
                        })
                        .transpose()
                })
                .collect::<Result<Vec<_>, _>>()?;
            let mut names = HashSet::new();
            for o in &desc.objects {
                if !names.insert(o.name.as_str()) {
                    return Err(SceneError::Invalid {
                        path: toml_path.clone(),
                        message: format!("two objects are named `{}`", o.name),
                    });
                }
            }
            let main = mesh_path(&dir, &toml_path, "mesh", &desc.mesh)?;
            b.add_static(&[main], &mut hasher, &mut extras)?;
            for ((o, t), a) in desc.objects.iter().zip(transforms).zip(animations) {
                let p = mesh_path(
                    &dir,
                    &toml_path,
                    &format!("object `{}`: mesh", o.name),
                    &o.mesh,
                )?;
                b.add_rigid(&o.name, &p, t, a, &mut hasher)?;
            }
            (desc.name.unwrap_or(default_name), camera, lights)
        } else {
            let mut meshes = Vec::new();
            let entries = std::fs::read_dir(&dir).map_err(|error| SceneError::Io {
                path: dir.clone(),
                error,
            })?;
            for entry in entries {
                let entry = entry.map_err(|error| SceneError::Io {
                    path: dir.clone(),
                    error,
                })?;
                let p = entry.path();
                if MeshFormat::of(&p).is_some() && p.is_file() {
                    meshes.push(p);
                }
            }
            meshes.sort_by(|a, b| a.file_name().cmp(&b.file_name()));
            if meshes.is_empty() {
                return Err(SceneError::NoObj { dir });
            }
            let names: Vec<String> = meshes
                .iter()
                .map(|p| {
                    p.file_name()
                        .unwrap_or_default()
                        .to_string_lossy()
                        .into_owned()
                })
                .collect();
            b.warnings.push(format!(
                "{}: no scene.toml; loading every mesh file: {}",
                dir.display(),
                names.join(", ")
            ));
            b.add_static(&meshes, &mut hasher, &mut extras)?;
            (default_name, None, Vec::new())
        };
        let camera = camera.or(extras.camera);
        let lights = if lights.is_empty() {
            extras.lights
        } else {
            lights
        };

        let (lo, hi) = bounds_of(&b.positions);
        if !(lo.is_finite() && hi.is_finite() && (hi - lo).length().is_finite()) {
            return Err(SceneError::Invalid {
                path: dir.clone(),
                message: "scene bounds are not finite (coordinates too large)".into(),
            });
        }
        let camera = camera.unwrap_or_else(|| {
            let (c, placement) = default_view::default_camera(&b.positions, &b.triangles, lo, hi);
            let place = match placement {
                default_view::Placement::Outside(side, open) => format!(
                    "outside the scene's open side {} ({:.0}% of the rays from the \
                     bounding box's centre leave through it)",
                    side.describe(),
                    100.0 * open
                ),
                default_view::Placement::Inside => {
                    "inside: the scene is closed on every side".to_string()
                }
            };
            b.warnings.push(format!(
                "default camera {place}: position {}, looking at {}, up {}, fov_y_deg {}, \
                 resolution {}x{} (set [camera] in scene.toml to choose)",
                fmt3(c.position),
                fmt3(c.target),
                fmt3(c.up),
                c.fov_y_deg,
                c.resolution[0],
                c.resolution[1]
            ));
            c
        });
        let mut used = vec![false; b.materials.len()];
        for &m in &b.triangle_materials {
            used[m as usize] = true;
        }
        let emitters: Vec<String> = b
            .materials
            .iter()
            .zip(used)
            .filter(|&(m, used)| used && m.emits())
            .map(|(m, _)| format!("`{}`", m.name))
            .collect();
        let lights = if lights.is_empty() && !emitters.is_empty() {
            b.warnings.push(format!(
                "no light given: the scene is lit by its emissive material(s) {}",
                emitters.join(", ")
            ));
            lights
        } else if lights.is_empty() {
            let (l, place) =
                default_view::default_light(&b.positions, &b.triangles, lo, hi, &camera);
            b.warnings.push(format!(
                "default light {place}: spot at {}, direction {}, cutoff_deg {}, intensity {} W/sr",
                fmt3(l.position),
                fmt3(l.direction),
                l.cutoff_deg,
                l.intensity[0]
            ));
            vec![l]
        } else {
            lights
        };
        let texcoords = if b.all_have_texcoords {
            b.texcoords
        } else {
            Vec::new()
        };
        let scene = Scene {
            name,
            path,
            positions: b.positions,
            texcoords,
            triangles: b.triangles,
            triangle_materials: b.triangle_materials,
            objects: b.objects,
            materials: b.materials,
            camera,
            lights,
            content_hash: *hasher.hasher.finalize().as_bytes(),
            files: hasher.files,
            warnings: b.warnings,
        };
        debug_assert_eq!(scene.check_objects(), Ok(()));
        Ok(scene)
    }
}
