//! glTF materials and textures: the images as texture sources (embedded bytes or files), and
//! the metallic-roughness materials as Lambertian plus normalised Phong with their emission
//! and normal maps (glTF 2.0, Appendix B).

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use super::checks::{Buffers, uri_file};
use super::gltf_error;
use super::read::data_uri;
use crate::scene::{Builder, Material, NormalMap, NormalMapKind, SceneError, TextureSource};

/// Specular reflectance at normal incidence of a glTF dielectric (glTF 2.0, Appendix B).
const DIELECTRIC_F0: f32 = 0.04;

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

/// The images of `document` as texture sources, in order: the bytes of a buffer view or a
/// `data:` URI, or a file named relative to `dir` (outside it only where `outside` allows).
pub(super) fn read_images(
    path: &Path,
    dir: &Path,
    outside: bool,
    document: &gltf::Document,
    buffers: &Buffers,
) -> Result<Vec<TextureSource>, SceneError> {
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
                        let bytes: Arc<[u8]> = Arc::from(buffers.view(&view).ok_or_else(|| {
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
    Ok(images)
}

impl Builder {
    /// Appends every material of `document`, in order, with its textures from `images`, and
    /// returns the index the first of them takes.
    pub(super) fn add_gltf_materials(
        &mut self,
        path: &Path,
        document: &gltf::Document,
        images: &[TextureSource],
    ) -> Result<u32, SceneError> {
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
        Ok(material_base)
    }
}
