//! glTF 2.0 loading (`.gltf` with its buffers, or `.glb`): every node of the default scene that
//! holds a mesh becomes an object, its triangles placed by the node's world transform; the
//! metallic-roughness materials become Lambertian plus normalised Phong ([`convert_material`]);
//! `KHR_lights_punctual` spot lights become the scene's spot lights ([`convert_light`]) and the
//! first perspective camera its camera. Buffers and images are read here (regular files only,
//! bounded, buffers hashed), and every range the file claims is checked against the bytes it
//! holds before the `gltf` crate's readers see it.

use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::Arc;

use glam::{Affine3A, Mat4, Vec3};

use super::toml::{CameraToml, LightKind, LightToml};
use super::validate::{check_camera, check_light};
mod checks;

use checks::{
    Buffers, Role, check_accessor, check_attribute_accessors, check_glb_header, uri_file,
};

use super::{
    Builder, Camera, DEFAULT_RESOLUTION, FileCounts, Hasher, MAX_FILE_BYTES, Material, NormalMap,
    NormalMapKind, ObjectKind, SceneError, SpotLight, TextureSource, read_bounded,
};

/// Extensions the loader understands; a file that requires any other is refused, as the glTF
/// specification asks (§3.12).
const SUPPORTED_EXTENSIONS: [&str; 2] = ["KHR_lights_punctual", "KHR_materials_emissive_strength"];

/// Deepest node hierarchy followed: deeper is a malformed (or hostile) file, not a scene.
const MAX_NODE_DEPTH: usize = 1024;

/// Vertical size of the image of a glTF camera that gives only its aspect ratio, pixels.
const CAMERA_HEIGHT: u32 = DEFAULT_RESOLUTION[1];

/// Widest cone of a converted spot light, degrees: the runtime's widest shadow map.
const MAX_CONE_DEG: f32 = super::MAX_SPOT_CUTOFF_DEG;

/// Specular reflectance at normal incidence of a glTF dielectric (glTF 2.0, Appendix B).
const DIELECTRIC_F0: f32 = 0.04;

/// What a glTF file brings besides its triangles.
#[derive(Default)]
pub(super) struct GltfExtras {
    /// The first perspective camera of the scene's nodes, if any.
    pub(super) camera: Option<Camera>,
    /// Its spot lights, and point lights turned into spot lights.
    pub(super) lights: Vec<SpotLight>,
}

/// How the triangles of a glTF file become objects.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum GltfObjects {
    /// One static object per node with a mesh (the scene's static part).
    PerNode,
    /// None: the caller makes the whole file one object (a rigid `[[objects]]` entry).
    Whole,
}

fn gltf_error(path: &Path, message: impl Into<String>) -> SceneError {
    SceneError::Gltf {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// The bytes of a `data:` URI and its MIME type, if it declares one.
type DataUri = (Vec<u8>, Option<String>);

/// The bytes of a `data:` URI (`data:[<mime>][;base64],<data>`) and its MIME type; `None` for
/// any other URI.
fn data_uri(uri: &str) -> Option<Result<DataUri, String>> {
    let rest = uri.strip_prefix("data:")?;
    let Some((header, data)) = rest.split_once(',') else {
        return Some(Err("a data URI without a comma".into()));
    };
    let (mime, base64) = match header.strip_suffix(";base64") {
        Some(mime) => (mime, true),
        None => (header, false),
    };
    let mime = (!mime.is_empty()).then(|| mime.to_string());
    let bytes = if base64 {
        use base64::Engine;
        match base64::engine::general_purpose::STANDARD.decode(data) {
            Ok(b) => b,
            Err(e) => return Some(Err(format!("a data URI's base64 does not decode: {e}"))),
        }
    } else {
        urlencoding::decode_binary(data.as_bytes()).into_owned()
    };
    Some(Ok((bytes, mime)))
}

/// The Phong exponent of a glTF roughness: the GGX width alpha = roughness^2 (glTF 2.0,
/// Appendix B) matches the Blinn-Phong exponent 2 / alpha^2 - 2 (Walter et al. 2007, §5.2), and
/// the lobe about the mirror direction is about four times narrower in exponent than the lobe
/// about the half vector (the angle to the mirror direction is twice the half vector's), so
/// Ns = (2 / alpha^2 - 2) / 4. Roughness 0 would be a perfect mirror: it is held at 0.05.
pub(super) fn phong_exponent(roughness: f32) -> f32 {
    let alpha = roughness.clamp(0.05, 1.0).powi(2);
    (2.0 / (alpha * alpha) - 2.0) / 4.0
}

/// The Lambertian plus normalised Phong material of a glTF metallic-roughness material with
/// base colour `base` (linear RGB), `metallic` and `roughness`: the diffuse albedo is the base
/// colour of the dielectric part less what its specular reflection takes,
/// `Kd = base (1 - metallic)(1 - 0.04)`, the specular albedo the Fresnel reflectance at normal
/// incidence, `Ks = 0.04 (1 - metallic) + base metallic`, so that `Kd + Ks <= 1`, and the
/// exponent [`phong_exponent`]. A lobe wider than Ns = 1 (roughness above about 0.7) scatters
/// about as a Lambertian surface does, and is folded into `Kd` (`Ks = 0`): the methods then
/// take no glossy path for it. Returns (Kd, Ks, Ns).
pub(super) fn convert_material(
    base: [f32; 3],
    metallic: f32,
    roughness: f32,
) -> ([f32; 3], [f32; 3], f32) {
    let (m, r) = (metallic.clamp(0.0, 1.0), roughness.clamp(0.0, 1.0));
    let kd = base.map(|b| b * (1.0 - m) * (1.0 - DIELECTRIC_F0));
    let ks = base.map(|b| DIELECTRIC_F0 * (1.0 - m) + b * m);
    let ns = phong_exponent(r);
    if ns < 1.0 {
        let folded = [0, 1, 2].map(|i| (kd[i] + ks[i]).min(1.0));
        (folded, [0.0; 3], 1.0)
    } else {
        (kd, ks, ns)
    }
}

/// The half-angle of the cone of constant intensity that sends the same flux as a glTF spot
/// light of cone angles `inner` and `outer` (radians), whose intensity falls from full at
/// `inner` to zero at `outer` as the square of `(cos t - cos outer) / (cos inner - cos outer)`
/// (the falloff of the KHR_lights_punctual reference implementation): a cone of half-angle `c`
/// subtends `2 pi (1 - cos c)`, so `1 - cos c` is the integral of the falloff over `cos t`.
pub(super) fn equivalent_cone(inner: f32, outer: f32) -> f32 {
    let outer = outer.clamp(1e-4, std::f32::consts::FRAC_PI_2);
    let inner = inner.clamp(0.0, outer);
    let (ci, co) = (inner.cos() as f64, outer.cos() as f64);
    // Full intensity over [cos inner, 1], the squared ramp over [cos outer, cos inner], whose
    // integral is a third of its width.
    let flux = (1.0 - ci) + (ci - co) / 3.0;
    (1.0 - flux).clamp(-1.0, 1.0).acos() as f32
}

/// A primitive's triangles from its indices (or `0..vertex_count`) and its mode; `None` for
/// points and lines.
fn primitive_triangles(mode: gltf::mesh::Mode, indices: &[u32]) -> Option<Vec<[u32; 3]>> {
    use gltf::mesh::Mode;
    let n = indices.len();
    Some(match mode {
        Mode::Triangles => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
        // Every other triangle of a strip is reversed to keep the winding (glTF §3.7.2.1).
        Mode::TriangleStrip => (2..n)
            .map(|i| {
                if i % 2 == 0 {
                    [indices[i - 2], indices[i - 1], indices[i]]
                } else {
                    [indices[i - 1], indices[i - 2], indices[i]]
                }
            })
            .collect(),
        Mode::TriangleFan => (2..n)
            .map(|i| [indices[i - 1], indices[i], indices[0]])
            .collect(),
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => return None,
    })
}

impl Builder {
    /// Loads the glTF file `path`, places every mesh node by `placement` after its own world
    /// transform, appends the triangles and, for [`GltfObjects::PerNode`], pushes one static
    /// object per node that kept triangles.
    pub(super) fn add_gltf(
        &mut self,
        path: &Path,
        placement: Affine3A,
        objects: GltfObjects,
        hasher: &mut Hasher,
    ) -> Result<GltfExtras, SceneError> {
        let bytes = read_bounded(path)?;
        hasher.add(path, &bytes);
        let dir = path.parent().unwrap_or(Path::new("."));
        let outside = self.options.files_outside;
        check_glb_header(&bytes).map_err(|e| gltf_error(path, e))?;
        // The crate's validation checks every index the JSON holds but one, which its own
        // check of POSITION's bounds indexes unchecked: that one first, then the crate's. A
        // panic on malformed input still becomes an error like any other.
        let parsed = std::panic::catch_unwind(|| {
            gltf::Gltf::from_slice_without_validation(&bytes)
                .map(|g| (g.document.into_json(), g.blob))
        })
        .map_err(|_| gltf_error(path, "the glTF parser failed on malformed input"))?;
        let (root, blob) = parsed.map_err(|e| gltf_error(path, e.to_string()))?;
        check_attribute_accessors(&root).map_err(|e| gltf_error(path, e))?;
        let document = std::panic::catch_unwind(|| gltf::Document::from_json(root))
            .map_err(|_| gltf_error(path, "the glTF parser failed on malformed input"))?
            .map_err(|e| gltf_error(path, e.to_string()))?;
        drop(bytes);

        if let Some(ext) = document
            .extensions_required()
            .find(|e| !SUPPORTED_EXTENSIONS.contains(e))
        {
            return Err(gltf_error(
                path,
                format!(
                    "the file requires the extension {ext}, which cssm does not support \
                     (supported: {})",
                    SUPPORTED_EXTENSIONS.join(", ")
                ),
            ));
        }
        let ignored: Vec<&str> = document
            .extensions_used()
            .filter(|e| !SUPPORTED_EXTENSIONS.contains(e))
            .collect();
        if !ignored.is_empty() {
            self.warnings.push(format!(
                "{}: glTF extensions ignored: {}",
                path.display(),
                ignored.join(", ")
            ));
        }

        // Buffers: the GLB's binary chunk, data URIs, or files next to the glTF.
        let mut blob = blob;
        // The buffer files' sizes in all, before any is read: one file named by many buffers
        // is read once per buffer.
        let mut file_bytes = 0u64;
        for buffer in document.buffers() {
            if let gltf::buffer::Source::Uri(uri) = buffer.source()
                && !uri.starts_with("data:")
                && let Ok(file) = uri_file(dir, uri, outside)
                && let Ok(metadata) = std::fs::metadata(&file)
            {
                file_bytes = file_bytes.saturating_add(metadata.len());
                if file_bytes > MAX_FILE_BYTES {
                    return Err(gltf_error(
                        path,
                        format!(
                            "buffer {}: the buffer files come to more than {MAX_FILE_BYTES} bytes \
                             in all, the most a glTF's buffers may hold",
                            buffer.index()
                        ),
                    ));
                }
            }
        }
        let mut data = Vec::new();
        for buffer in document.buffers() {
            let bytes = match buffer.source() {
                gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                    gltf_error(
                        path,
                        format!(
                            "buffer {} is the binary chunk, which the file lacks",
                            buffer.index()
                        ),
                    )
                })?,
                gltf::buffer::Source::Uri(uri) => match data_uri(uri) {
                    Some(decoded) => {
                        decoded
                            .map_err(|e| {
                                gltf_error(path, format!("buffer {}: {e}", buffer.index()))
                            })?
                            .0
                    }
                    None => {
                        let file = uri_file(dir, uri, outside).map_err(|e| {
                            gltf_error(path, format!("buffer {}: {e}", buffer.index()))
                        })?;
                        let bytes = read_bounded(&file)?;
                        hasher.add(&file, &bytes);
                        bytes
                    }
                },
            };
            if bytes.len() < buffer.length() {
                return Err(gltf_error(
                    path,
                    format!(
                        "buffer {} holds {} bytes, the file says {}",
                        buffer.index(),
                        bytes.len(),
                        buffer.length()
                    ),
                ));
            }
            data.push(bytes);
        }
        let buffers = Buffers { data };
        let total_bytes: usize = buffers.data.iter().map(Vec::len).sum();

        // Images, as texture sources, each made once; the bytes of a buffer view once however
        // many images name it (64 images of one 64 MiB view are 64 MiB, not 4 GiB).
        let mut view_bytes: HashMap<usize, Arc<[u8]>> = HashMap::new();
        let images = document
            .images()
            .map(|image| {
                let label = match image.name() {
                    Some(name) => format!("image {} `{name}`", image.index()),
                    None => format!("image {}", image.index()),
                };
                let embedded = |bytes: Arc<[u8]>, mime: Option<String>| TextureSource::Embedded {
                    origin: path.to_path_buf(),
                    label: label.clone(),
                    bytes,
                    mime,
                };
                // The gltf crate's `source()` unwraps what the JSON may lack: checked here.
                let json = &document.as_json().images[image.index()];
                if let Some(view) = json.buffer_view {
                    let view = document.views().nth(view.value()).ok_or_else(|| {
                        gltf_error(path, format!("{label}: its buffer view does not exist"))
                    })?;
                    let bytes = match view_bytes.get(&view.index()) {
                        Some(bytes) => bytes.clone(),
                        None => {
                            let bytes: Arc<[u8]> =
                                Arc::from(buffers.view(&view).ok_or_else(|| {
                                    gltf_error(
                                        path,
                                        format!("{label}: its buffer view reaches past its buffer"),
                                    )
                                })?);
                            view_bytes.insert(view.index(), bytes.clone());
                            bytes
                        }
                    };
                    // A view without the mimeType glTF requires: the image's own bytes say.
                    let mime = json.mime_type.as_ref().map(|m| m.0.clone());
                    return Ok(embedded(bytes, mime));
                }
                let Some(uri) = json.uri.as_deref() else {
                    return Err(gltf_error(
                        path,
                        format!("{label} has neither a uri nor a bufferView"),
                    ));
                };
                let mime_type = json.mime_type.as_ref().map(|m| m.0.clone());
                Ok(match data_uri(uri) {
                    Some(decoded) => {
                        let (bytes, mime) =
                            decoded.map_err(|e| gltf_error(path, format!("{label}: {e}")))?;
                        embedded(Arc::from(bytes), mime_type.or(mime))
                    }
                    None => TextureSource::File(
                        uri_file(dir, uri, outside)
                            .map_err(|e| gltf_error(path, format!("{label}: {e}")))?,
                    ),
                })
            })
            .collect::<Result<Vec<_>, SceneError>>()?;
        let texture = |info: Option<gltf::texture::Info>| {
            info.and_then(|i| images.get(i.texture().source().index()).cloned())
        };

        // Materials: all of the file's, in order, then the grey default for primitives
        // without one.
        let material_base = self.materials.len() as u32;
        let mut alpha_ignored = Vec::new();
        for m in document.materials() {
            let name = m.name().map_or_else(
                || format!("material {}", m.index().unwrap_or(0)),
                str::to_string,
            );
            let pbr = m.pbr_metallic_roughness();
            let [r, g, b, _] = pbr.base_color_factor();
            let (kd, ks, ns) =
                convert_material([r, g, b], pbr.metallic_factor(), pbr.roughness_factor());
            let strength = m.emissive_strength().unwrap_or(1.0);
            let emission = m.emissive_factor().map(|e| e * strength);
            let values = kd.iter().chain(&ks).chain([&ns]).chain(&emission);
            if !values.clone().all(|v| v.is_finite() && *v >= 0.0) {
                return Err(gltf_error(
                    path,
                    format!("material `{name}` has a negative or non-finite factor"),
                ));
            }
            if m.alpha_mode() != gltf::material::AlphaMode::Opaque {
                alpha_ignored.push(format!("`{name}`"));
            }
            let map_kd = texture(pbr.base_color_texture());
            let map_emission = texture(m.emissive_texture());
            let normal_map = match m.normal_texture() {
                Some(n) if !n.scale().is_finite() => {
                    return Err(gltf_error(
                        path,
                        format!("material `{name}` has a non-finite normalTexture scale"),
                    ));
                }
                Some(n) => images
                    .get(n.texture().source().index())
                    .cloned()
                    .map(|source| NormalMap {
                        source,
                        kind: NormalMapKind::Tangent { scale: n.scale() },
                    }),
                None => None,
            };
            let sources = [map_kd.as_ref(), map_emission.as_ref()];
            let sources = sources
                .into_iter()
                .chain([normal_map.as_ref().map(|n| &n.source)]);
            for t in sources.flatten() {
                if let Some(file) = t.file() {
                    self.warn_about_texture(path, &name, file);
                }
            }
            self.materials.push(Material {
                name,
                kd,
                ks,
                ns,
                map_kd,
                emission,
                map_emission,
                normal_map,
            });
        }
        if !alpha_ignored.is_empty() {
            self.warnings.push(format!(
                "{}: material(s) {} are transparent or masked; drawn opaque",
                path.display(),
                alpha_ignored.join(", ")
            ));
        }

        // The nodes of the default scene (else the first, else every root), depth first.
        let roots: Vec<gltf::Node> = match document.default_scene().or(document.scenes().next()) {
            Some(scene) => scene.nodes().collect(),
            None => {
                let children: HashSet<usize> = document
                    .nodes()
                    .flat_map(|n| n.children().map(|c| c.index()))
                    .collect();
                document
                    .nodes()
                    .filter(|n| !children.contains(&n.index()))
                    .collect()
            }
        };
        let mut stack: Vec<(gltf::Node, Mat4, usize)> = roots
            .into_iter()
            .rev()
            .map(|n| (n, Mat4::from(placement), 0))
            .collect();
        let mut visited = HashSet::new();
        let mut extras = GltfExtras::default();
        let mut counts = FileCounts::default();
        let first_triangle = self.triangles.len();
        let mut names = HashSet::new();
        let mut skipped = Vec::new();
        let mut no_material = false;
        while let Some((node, parent, depth)) = stack.pop() {
            if !visited.insert(node.index()) {
                return Err(gltf_error(
                    path,
                    format!(
                        "node {} is reached twice: the node hierarchy is not a forest",
                        node.index()
                    ),
                ));
            }
            if depth > MAX_NODE_DEPTH {
                return Err(gltf_error(
                    path,
                    format!("the node hierarchy is deeper than {MAX_NODE_DEPTH}"),
                ));
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            // A finite file can multiply out to infinity (a scale of 1e30 under another): the
            // node is named here, not found later as NaN in a transform or a camera.
            if !world.is_finite() {
                let name = node.name().map_or_else(String::new, |n| format!(" `{n}`"));
                return Err(gltf_error(
                    path,
                    format!(
                        "node {}{name}: its world transform (its own times its parents') \
                         is not finite",
                        node.index()
                    ),
                ));
            }
            for child in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((child, world, depth + 1));
            }
            let affine = Affine3A::from_mat4(world);
            if let Some(camera) = node.camera()
                && extras.camera.is_none()
            {
                extras.camera = self.convert_camera(path, &camera, affine)?;
            }
            if let Some(light) = node.light() {
                if let Some(l) = self.convert_light(path, &light, affine)? {
                    extras.lights.push(l);
                }
            }
            let Some(mesh) = node.mesh() else { continue };
            let start = self.triangles.len();
            for primitive in mesh.primitives() {
                let Some(positions_accessor) = primitive.get(&gltf::Semantic::Positions) else {
                    continue;
                };
                check_accessor(
                    path,
                    &buffers,
                    (&positions_accessor, Role::Positions),
                    total_bytes,
                )?;
                if let Some(indices) = primitive.indices() {
                    check_accessor(path, &buffers, (&indices, Role::Indices), total_bytes)?;
                }
                let material = primitive.material();
                let pbr = material.pbr_metallic_roughness();
                // One set of texture coordinates per primitive: the albedo texture's, else the
                // emission texture's, else the normal texture's, else the first.
                let set = pbr
                    .base_color_texture()
                    .or(material.emissive_texture())
                    .map(|i| i.tex_coord())
                    .or(material.normal_texture().map(|n| n.tex_coord()))
                    .unwrap_or(0);
                let uv_set = primitive
                    .get(&gltf::Semantic::TexCoords(set))
                    .map(|a| (set, a));
                if let Some((_, a)) = &uv_set {
                    check_accessor(path, &buffers, (a, Role::TexCoords), total_bytes)?;
                }
                let reader = primitive.reader(|b| buffers.data.get(b.index()).map(Vec::as_slice));
                let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    let positions: Vec<Vec3> = reader
                        .read_positions()
                        .map(|p| p.map(|p| affine.transform_point3(Vec3::from(p))).collect())
                        .unwrap_or_default();
                    let indices: Vec<u32> = match reader.read_indices() {
                        Some(i) => i.into_u32().collect(),
                        None => (0..positions.len() as u32).collect(),
                    };
                    let texcoords: Option<Vec<[f32; 2]>> = uv_set.and_then(|(set, _)| {
                        // glTF's v runs down the image, OBJ's (and the runtime's) up.
                        let uv = reader.read_tex_coords(set)?.into_f32();
                        Some(uv.map(|[u, v]| [u, 1.0 - v]).collect())
                    });
                    (positions, indices, texcoords)
                }))
                .map_err(|_| {
                    gltf_error(
                        path,
                        format!("mesh {}: the accessor reader failed", mesh.index()),
                    )
                })?;
                let (positions, indices, texcoords) = read;
                let Some(triangles) = primitive_triangles(primitive.mode(), &indices) else {
                    skipped.push(format!("mesh {} ({:?})", mesh.index(), primitive.mode()));
                    continue;
                };
                let material = match material.index() {
                    Some(i) => material_base + i as u32,
                    None => {
                        no_material = true;
                        self.default_material()
                    }
                };
                self.append_part(
                    path,
                    &positions,
                    texcoords.as_deref(),
                    triangles,
                    material,
                    &mut counts,
                )?;
            }
            if objects == GltfObjects::PerNode && self.triangles.len() > start {
                let base = node
                    .name()
                    .or(mesh.name())
                    .map_or_else(|| format!("node {}", node.index()), str::to_string);
                let name = if names.insert(base.clone()) {
                    base
                } else {
                    format!("{base} (node {})", node.index())
                };
                self.push_object(name, ObjectKind::Static, start, affine, path)?;
            }
        }
        if !skipped.is_empty() {
            self.warnings.push(format!(
                "{}: primitives of points or lines skipped: {}",
                path.display(),
                skipped.join(", ")
            ));
        }
        if no_material {
            self.warnings.push(format!(
                "{}: primitives without a material use the grey Lambertian `default` (Kd 0.5)",
                path.display()
            ));
        }
        self.finish_file(path, &counts, first_triangle)?;
        Ok(extras)
    }

    /// The camera of a glTF camera node placed by `world` (looking down its -z, +y up), or
    /// `None` with a warning for an orthographic one.
    fn convert_camera(
        &mut self,
        path: &Path,
        camera: &gltf::Camera,
        world: Affine3A,
    ) -> Result<Option<Camera>, SceneError> {
        let gltf::camera::Projection::Perspective(p) = camera.projection() else {
            self.warnings.push(format!(
                "{}: camera {} is orthographic, which cssm does not render; ignored",
                path.display(),
                camera.index()
            ));
            return Ok(None);
        };
        let resolution = match p.aspect_ratio() {
            Some(a) if a.is_finite() && a > 0.0 => [
                ((CAMERA_HEIGHT as f32 * a).round() as u32).clamp(1, 16384),
                CAMERA_HEIGHT,
            ],
            _ => DEFAULT_RESOLUTION,
        };
        let position = world.transform_point3(Vec3::ZERO);
        let c = CameraToml {
            position: position.to_array(),
            target: (position + world.transform_vector3(Vec3::NEG_Z)).to_array(),
            up: world.transform_vector3(Vec3::Y).to_array(),
            fov_y_deg: p.yfov().to_degrees(),
            resolution,
        };
        check_camera(&c, path).map(Some).map_err(|e| match e {
            SceneError::Invalid { path, message } => SceneError::Gltf {
                path,
                message: format!("camera {}: {message}", camera.index()),
            },
            other => other,
        })
    }

    /// The spot light of a `KHR_lights_punctual` light node placed by `world`: a spot light is
    /// its cone of equal flux ([`equivalent_cone`]); a point light, which the runtime's shadow
    /// maps cannot cover, becomes the widest spot pointing down its -y with a warning; a
    /// directional light is skipped with a warning. glTF gives intensities in candela and this
    /// project's scenes in W/sr: the number is kept (1 cd is 1 W/sr), as radiance is relative.
    fn convert_light(
        &mut self,
        path: &Path,
        light: &gltf::khr_lights_punctual::Light,
        world: Affine3A,
    ) -> Result<Option<SpotLight>, SceneError> {
        use gltf::khr_lights_punctual::Kind;
        let name = light.name().map_or_else(
            || format!("light {}", light.index()),
            |n| format!("light `{n}`"),
        );
        let (direction, cutoff) = match light.kind() {
            Kind::Directional => {
                self.warnings.push(format!(
                    "{}: {name} is directional, which cssm does not render; ignored",
                    path.display()
                ));
                return Ok(None);
            }
            Kind::Point => {
                self.warnings.push(format!(
                    "{}: {name} is a point light; cssm renders spot lights only, so it lights \
                     the cone of {MAX_CONE_DEG} degrees around its -y",
                    path.display()
                ));
                (Vec3::NEG_Y, MAX_CONE_DEG)
            }
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let cone = equivalent_cone(inner_cone_angle, outer_cone_angle).to_degrees();
                if cone > MAX_CONE_DEG {
                    self.warnings.push(format!(
                        "{}: {name}'s cone ({cone:.1} degrees) is narrowed to {MAX_CONE_DEG}, the \
                         widest shadow map",
                        path.display()
                    ));
                }
                (Vec3::NEG_Z, cone.min(MAX_CONE_DEG))
            }
        };
        let l = LightToml {
            kind: LightKind::Spot,
            position: world.transform_point3(Vec3::ZERO).to_array(),
            direction: world.transform_vector3(direction).to_array(),
            cutoff_deg: cutoff,
            intensity: light.color().map(|c| c * light.intensity()),
        };
        check_light(light.index(), &l, path)
            .map(Some)
            .map_err(|e| match e {
                SceneError::Invalid { path, message } => SceneError::Gltf {
                    path,
                    message: message.replacen("lights[", "KHR_lights_punctual lights[", 1),
                },
                other => other,
            })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use std::path::Path;

    use base64::Engine;
    use glam::Vec3;

    use super::{convert_material, equivalent_cone, phong_exponent, primitive_triangles};
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
}
