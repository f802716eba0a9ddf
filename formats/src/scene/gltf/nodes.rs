//! The node walk of a glTF file: the nodes of its default scene depth first, each placed by
//! its world transform (its own times its parents'), the triangles of its mesh primitives
//! appended (strips and fans turned into triangle lists), one static object per mesh node, and
//! the cameras and lights found on the nodes handed to `lights.rs`.

use std::collections::HashSet;
use std::path::Path;

use glam::{Affine3A, Mat4, Vec3};

use super::checks::{Buffers, Role, check_accessor};
use super::{GltfExtras, GltfObjects, gltf_error};
use crate::scene::{Builder, FileCounts, ObjectKind, SceneError};

/// Deepest node hierarchy followed: deeper is a malformed (or hostile) file, not a scene.
const MAX_NODE_DEPTH: usize = 1024;

/// A primitive's triangles from its indices (or `0..vertex_count`) and its mode; `None` for
/// points and lines.
pub(super) fn primitive_triangles(
    mode: gltf::mesh::Mode,
    indices: &[u32],
) -> Option<Vec<[u32; 3]>> {
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
    /// Walks the nodes of `document`, placing each by `placement` after its own world
    /// transform, and appends the triangles of its mesh primitives (their materials counted
    /// from `material_base`, the buffers' bytes in `buffers`); for [`GltfObjects::PerNode`],
    /// pushes one static object per node that kept triangles. Returns the camera and lights
    /// found on the nodes.
    pub(super) fn add_gltf_nodes(
        &mut self,
        path: &Path,
        document: &gltf::Document,
        placement: Affine3A,
        objects: GltfObjects,
        buffers: &Buffers,
        material_base: u32,
    ) -> Result<GltfExtras, SceneError> {
        let total_bytes: usize = buffers.data.iter().map(Vec::len).sum();

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
                    buffers,
                    (&positions_accessor, Role::Positions),
                    total_bytes,
                )?;
                if let Some(indices) = primitive.indices() {
                    check_accessor(path, buffers, (&indices, Role::Indices), total_bytes)?;
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
                    check_accessor(path, buffers, (a, Role::TexCoords), total_bytes)?;
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
}
