//! Scene description: a directory with `scene.toml` and OBJ/MTL or glTF meshes, a plain
//! directory of mesh files, or one mesh file (see `docs/scene-format.md`).
//!
//! [`Scene::load`] reads any of these, triangulates, merges everything into one indexed
//! world-space mesh, validates it, and hashes every file it read ([`Scene::content_hash`]).
//! The merged mesh remembers where it came from: [`Scene::objects`] lists the static part and
//! each rigid `[[objects]]` entry as a [`SceneObject`], a contiguous range of the merged
//! triangles with its object-to-world transform (the bake still treats all of it as static).

mod animation;
pub use animation::MAX_KEYFRAMES;
mod default_view;
mod gltf;
#[cfg(test)]
mod gltf_refusals;
mod load;
mod obj;
mod objects;
mod toml;
mod validate;

pub use load::LoadOptions;
use load::{Builder, FileCounts, bounds_of, fmt3};

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use glam::{Affine3A, Mat3, Vec3};

pub use self::animation::{Animation, Keyframe, Repeat, Spin, euler_rotation, turned_about};
pub use self::objects::{MAX_POSE_REACH, ObjectKind, STATIC_OBJECT_NAME, SceneObject, placement};
use self::toml::{SceneToml, mesh_path};
use validate::{check_camera, check_light, object_transform};

/// Where a texture's image comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum TextureSource {
    /// An image file (OBJ's `map_Kd`, a glTF image with a file URI).
    File(PathBuf),
    /// An image held inside a scene file: a glTF image in a buffer view or a data URI.
    Embedded {
        /// The file that holds it (the `.glb` or `.gltf`).
        origin: PathBuf,
        /// Which image of that file, for messages ("image 3 `bricks`").
        label: String,
        /// The encoded image (PNG, JPEG, ...).
        bytes: std::sync::Arc<[u8]>,
        /// Its MIME type as the file declares it, if it does.
        mime: Option<String>,
    },
}

impl TextureSource {
    /// The image file, for a [`TextureSource::File`].
    pub fn file(&self) -> Option<&Path> {
        match self {
            TextureSource::File(p) => Some(p),
            TextureSource::Embedded { .. } => None,
        }
    }

    /// The file to name in a message about this texture: the image file, or the scene file
    /// that embeds it.
    pub fn origin(&self) -> &Path {
        match self {
            TextureSource::File(p) => p,
            TextureSource::Embedded { origin, .. } => origin,
        }
    }
}

impl std::fmt::Display for TextureSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TextureSource::File(p) => write!(f, "{}", p.display()),
            TextureSource::Embedded { origin, label, .. } => {
                write!(f, "{} ({label})", origin.display())
            }
        }
    }
}

/// A material from the MTL or the glTF file (conventions in `docs/architecture.md`).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Material name from the MTL (or "default").
    pub name: String,
    /// Lambertian albedo, linear RGB (BRDF Kd/pi).
    pub kd: [f32; 3],
    /// Specular albedo of the normalised Phong lobe.
    pub ks: [f32; 3],
    /// Phong exponent.
    pub ns: f32,
    /// Albedo texture (`map_Kd`, glTF `baseColorTexture`), multiplying `kd`, if any.
    pub map_kd: Option<TextureSource>,
    /// Emitted radiance, linear RGB, from the front side only: the side the triangle's winding
    /// normal faces (MTL `Ke`; glTF `emissiveFactor` times `KHR_materials_emissive_strength`).
    /// Zero for a surface that only reflects.
    pub emission: [f32; 3],
    /// Emission texture (`map_Ke`, glTF `emissiveTexture`), multiplying `emission`, if any.
    pub map_emission: Option<TextureSource>,
    /// Surface detail that tilts the shading normal (MTL `bump`/`map_Bump`, `norm`; glTF
    /// `normalTexture`), if any: the high-frequency detail of the CSSM paper's Fig. 1 (right).
    pub normal_map: Option<NormalMap>,
}

/// A texture that perturbs the shading normal of a material (`docs/scene-format.md`).
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMap {
    /// The image.
    pub source: TextureSource,
    /// How its texels describe the surface.
    pub kind: NormalMapKind,
}

/// What the texels of a [`NormalMap`] hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NormalMapKind {
    /// A height map (MTL `bump`, `map_Bump`): the grey level `g` in `[0, 1]` (the mean of the
    /// channels, read as stored, not sRGB-decoded) is a height of `multiplier * g / 512` in
    /// units of the texture's side (UV 0 to 1): a white texel next to a black one at
    /// `multiplier` 1 is a 45-degree step on a 512-texel texture. The runtime turns it into a
    /// tangent-space normal map on load; the convention depends neither on the scene's size
    /// nor on the image's resolution.
    Height {
        /// MTL `-bm` (1 without it); negative values turn bumps into dents.
        multiplier: f32,
    },
    /// A tangent-space normal map (MTL `norm`, glTF `normalTexture`): RGB `c` in `[0, 1]`,
    /// read as stored (not sRGB-decoded), is the unit normal `2c - 1` in the frame (tangent
    /// along +u, bitangent along +v, geometric normal), the OpenGL / glTF convention.
    Tangent {
        /// glTF `normalTexture.scale` (MTL `-bm` for `norm`; 1 without it): multiplies the
        /// normal's tangent components before it is normalised.
        scale: f32,
    },
}

impl Material {
    /// The grey Lambertian (Kd 0.5) that triangles without a material get, named `name`.
    ///
    /// ```
    /// let m = cssm_formats::Material::grey("default");
    /// assert_eq!((m.kd, m.ks, m.emission), ([0.5; 3], [0.0; 3], [0.0; 3]));
    /// ```
    pub fn grey(name: &str) -> Material {
        Material {
            name: name.into(),
            kd: [0.5; 3],
            ks: [0.0; 3],
            ns: 1.0,
            map_kd: None,
            emission: [0.0; 3],
            map_emission: None,
            normal_map: None,
        }
    }

    /// Whether the material emits light.
    pub fn emits(&self) -> bool {
        self.emission.iter().any(|&e| e > 0.0)
    }

    /// The image of [`Material::normal_map`], if any.
    pub fn normal_source(&self) -> Option<&TextureSource> {
        self.normal_map.as_ref().map(|n| &n.source)
    }
}

/// Look-at pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub position: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Up vector.
    pub up: Vec3,
    /// Full vertical field of view, degrees.
    pub fov_y_deg: f32,
    /// Image width and height in pixels.
    pub resolution: [u32; 2],
}

/// Widest cone of a spot light the GPU methods render, degrees (half-angle): one perspective
/// shadow map covers it. A scene file may name a wider cone (the path tracer takes it); the
/// lights the tool makes itself (the default light, a converted glTF light) stay within it.
pub const MAX_SPOT_CUTOFF_DEG: f32 = 80.0;

/// Spot light: constant radiant intensity inside the cone, zero outside.
#[derive(Clone, Debug, PartialEq)]
pub struct SpotLight {
    /// Position.
    pub position: Vec3,
    /// Unit direction of the cone axis.
    pub direction: Vec3,
    /// Cone half-angle, degrees.
    pub cutoff_deg: f32,
    /// Radiant intensity, W/sr, linear RGB.
    pub intensity: [f32; 3],
}

/// A loaded, triangulated, validated scene: one indexed triangle mesh in world space, and the
/// objects it was merged from.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Scene name.
    pub name: String,
    /// Absolute (canonical) path the scene was loaded from: its directory, or its mesh file when
    /// the scene is one `.obj`, `.gltf` or `.glb` file.
    pub path: PathBuf,
    /// Vertex positions, world space.
    pub positions: Vec<Vec3>,
    /// Optional per-vertex texture coordinates (same length as `positions`, or empty).
    pub texcoords: Vec<[f32; 2]>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Material index of every triangle.
    pub triangle_materials: Vec<u32>,
    /// The objects the merged mesh was built from, in load order: the static part first, then
    /// the `[[objects]]` entries in file order. Invariants ([`Scene::check_objects`]): the
    /// triangle ranges are non-empty, disjoint, in increasing order and together cover
    /// `0..triangles.len()` exactly once, so [`Scene::object_of`] finds every triangle's object.
    /// A scene without `[[objects]]` is one [`ObjectKind::Static`] object over all triangles.
    /// Not part of [`Scene::content_hash`], which covers the files only.
    pub objects: Vec<SceneObject>,
    /// Materials.
    pub materials: Vec<Material>,
    /// Camera.
    pub camera: Camera,
    /// Lights.
    pub lights: Vec<SpotLight>,
    /// BLAKE3 over every file the scene was built from, in a fixed order.
    pub content_hash: [u8; 32],
    /// Every file the scene was read from (`scene.toml`, OBJ, MTL, glTF and its buffers), in
    /// read order; with the
    /// materials' textures these are [`Scene::input_files`].
    pub files: Vec<PathBuf>,
    /// Non-fatal things the user should hear about (defaults chosen, missing MTL, ...).
    pub warnings: Vec<String>,
}

impl Scene {
    /// Corners of triangle `t`.
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Axis-aligned bounds (min, max) of all vertices.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        )
    }

    /// A bare scene of raw triangles for tests and generated geometry: one grey Lambertian
    /// material (Kd 0.5), one static object, a camera on +z looking at the origin, no lights, no
    /// files (a zero content hash). Nothing is validated: the caller's triangles are taken as
    /// they are.
    ///
    /// ```
    /// use glam::Vec3;
    /// let scene = cssm_formats::Scene::from_triangles(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]);
    /// assert_eq!(scene.object_of(0), 0);
    /// ```
    pub fn from_triangles(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Scene {
        let count = triangles.len();
        Scene {
            name: "test".into(),
            path: PathBuf::from("/nonexistent"),
            positions,
            texcoords: Vec::new(),
            triangles,
            triangle_materials: vec![0; count],
            objects: vec![SceneObject::whole_static(count)],
            materials: vec![Material::grey("default")],
            camera: Camera {
                position: Vec3::new(0.0, 0.0, 5.0),
                target: Vec3::ZERO,
                up: Vec3::Y,
                fov_y_deg: 40.0,
                resolution: [64, 48],
            },
            lights: Vec::new(),
            content_hash: [0; 32],
            files: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// Every file the scene reads: [`Scene::files`] and the materials' textures. A command
    /// never writes onto one of them.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let textures = self.materials.iter().flat_map(|m| {
            [
                m.map_kd.as_ref(),
                m.map_emission.as_ref(),
                m.normal_source(),
            ]
        });
        let textures = textures.filter_map(|t| t?.file().map(Path::to_path_buf));
        self.files.iter().cloned().chain(textures).collect()
    }

    /// Length of the bounding-box diagonal: the far plane of every depth cube map (§3.2.1).
    pub fn diameter(&self) -> f32 {
        let (lo, hi) = self.bounds();
        (hi - lo).length()
    }
}

/// Largest OBJ, MTL, glTF or buffer file the loader reads: 2 GiB.
pub const MAX_FILE_BYTES: u64 = 2 << 30;

/// Most triangles a scene holds, all files and every placement of a glTF mesh counted: some
/// 2 GB of scene, BVH and atlas tables before any bake.
pub const MAX_SCENE_TRIANGLES: usize = 1 << 24;

/// Largest `scene.toml` the loader reads: 8 MiB, some 100,000 keyframes. A TOML document
/// parsed takes about 50 times its text, so this bounds the parse at a few hundred MB where
/// [`MAX_FILE_BYTES`] would allow 100 GB.
pub const MAX_SCENE_TOML_BYTES: u64 = 8 << 20;

/// Default vertical field of view of the camera chosen when there is no `scene.toml`, degrees.
pub const DEFAULT_FOV_Y_DEG: f32 = 40.0;
/// Default image resolution chosen when there is no `scene.toml`.
pub const DEFAULT_RESOLUTION: [u32; 2] = [640, 480];
/// Cone half-angle of the default spot light, degrees.
pub const DEFAULT_CUTOFF_DEG: f32 = 60.0;

/// Why a scene could not be loaded. Every message names the file (or directory) and the problem;
/// no error is chained as a `source`, so printing the chain never repeats a message.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene directory does not exist.
    #[error("scene directory {} does not exist", .dir.display())]
    DirNotFound {
        /// The directory as given.
        dir: PathBuf,
    },
    /// The scene path exists but is neither a directory nor a mesh file.
    #[error("{} is neither a directory nor a mesh file (a scene is a directory with scene.toml \
             and/or mesh files, or one .obj, .gltf or .glb file)", .path.display())]
    NotADirectory {
        /// The path as given.
        path: PathBuf,
    },
    /// The directory has neither `scene.toml` nor any mesh file.
    #[error("{} contains no .obj, .gltf or .glb file (and no scene.toml)", .dir.display())]
    NoObj {
        /// The scene directory.
        dir: PathBuf,
    },
    /// Reading a file failed.
    #[error("{}: {error}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        error: std::io::Error,
    },
    /// A file is larger than its limit ([`MAX_FILE_BYTES`], [`MAX_SCENE_TOML_BYTES`]).
    #[error("{}: file is {size} bytes, larger than the limit of {limit} bytes", .path.display())]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Its size.
        size: u64,
        /// The limit.
        limit: u64,
    },
    /// `scene.toml` is not valid TOML or does not match the schema (unknown key, wrong type,
    /// missing field); the message carries the line and column.
    #[error("{}: {message}", .path.display())]
    Toml {
        /// The `scene.toml`.
        path: PathBuf,
        /// The parser's message, with line, column and the offending key.
        message: String,
    },
    /// A value in `scene.toml` is out of range or inconsistent (zero light direction, bad field
    /// of view, missing mesh file, ...).
    #[error("{}: {message}", .path.display())]
    Invalid {
        /// The `scene.toml` (or mesh) concerned.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The OBJ parser refused the file.
    #[error("{}: parse error: {message}", .path.display())]
    ObjParse {
        /// The OBJ file.
        path: PathBuf,
        /// The parser's message.
        message: String,
    },
    /// The MTL file exists but could not be parsed, or holds non-finite values.
    #[error("{}: material library error: {message}", .path.display())]
    Mtl {
        /// The MTL file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The glTF file is malformed, refers to data it does not hold, or needs an extension the
    /// loader does not support.
    #[error("{}: glTF: {message}", .path.display())]
    Gltf {
        /// The `.gltf` or `.glb` file (or the buffer file it names).
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A triangle uses a vertex with a NaN or infinite coordinate.
    #[error("{}: triangle {triangle} has a NaN/infinite vertex", .path.display())]
    NonFiniteVertex {
        /// The OBJ file.
        path: PathBuf,
        /// Index of the triangle in the file (0-based, after triangulation).
        triangle: usize,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("{}: triangle {triangle} uses vertex {index}, but there are only {vertex_count}", .path.display())]
    IndexOutOfRange {
        /// The OBJ file.
        path: PathBuf,
        /// Index of the triangle in the file (0-based, after triangulation).
        triangle: usize,
        /// The bad vertex index.
        index: u32,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// The OBJ file has no faces.
    #[error("{}: no triangles", .path.display())]
    NoTriangles {
        /// The OBJ file.
        path: PathBuf,
    },
    /// Every triangle of the OBJ file has zero area.
    #[error("{}: all {count} triangles are degenerate (zero area)", .path.display())]
    AllDegenerate {
        /// The OBJ file.
        path: PathBuf,
        /// Number of triangles.
        count: usize,
    },
}

/// Lower-case hexadecimal form of a 32-byte hash (64 characters).
pub fn hash_hex(hash: &[u8; 32]) -> String {
    use std::fmt::Write;
    hash.iter().fold(String::with_capacity(64), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

// ---------------------------------------------------------------------------------------------
// Loading

/// Files read so far, in order, fed into the content hash as (name, bytes).
struct Hasher {
    dir: PathBuf,
    hasher: blake3::Hasher,
    files: Vec<PathBuf>,
}

impl Hasher {
    fn add(&mut self, path: &Path, bytes: &[u8]) {
        self.files.push(path.to_path_buf());
        // Name relative to the scene directory, so that moving the directory keeps the hash.
        let name = path.strip_prefix(&self.dir).unwrap_or(path);
        let name = name.to_string_lossy();
        self.hasher.update(&(name.len() as u64).to_le_bytes());
        self.hasher.update(name.as_bytes());
        self.hasher.update(&(bytes.len() as u64).to_le_bytes());
        self.hasher.update(bytes);
    }
}

fn read_bounded(path: &Path) -> Result<Vec<u8>, SceneError> {
    read_at_most(path, MAX_FILE_BYTES)
}

fn read_at_most(path: &Path, limit: u64) -> Result<Vec<u8>, SceneError> {
    // A regular file only (a FIFO would hang the open, /dev/zero never end), at most `limit`
    // bytes of it.
    crate::files::read_bounded(path, limit).map_err(|error| {
        if error.kind() == std::io::ErrorKind::FileTooLarge {
            let size = std::fs::metadata(path).map_or(limit + 1, |m| m.len());
            SceneError::TooLarge {
                path: path.to_path_buf(),
                size,
                limit,
            }
        } else {
            SceneError::Io {
                path: path.to_path_buf(),
                error,
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(super) const QUAD_OBJ: &str = "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                            vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl white\nf 1/1 2/2 3/3 4/4\n";
    pub(super) const QUAD_MTL: &str =
        "newmtl white\nKd 0.8 0.7 0.6\nKs 0.1 0.1 0.1\nNs 20\nmap_Kd wood.png\n";
    pub(super) const SCENE_TOML: &str = r#"name = "quad"
mesh = "quad.obj"

[camera]
position   = [0.5, 0.5, 3.0]
target     = [0.5, 0.5, 0.0]
up         = [0.0, 1.0, 0.0]
fov_y_deg  = 40.0
resolution = [320, 240]

[[lights]]
type       = "spot"
position   = [0.5, 0.5, 2.0]
direction  = [0.0, 0.0, -2.0]
cutoff_deg = 45.0
intensity  = [10.0, 10.0, 10.0]
"#;

    pub(super) fn write(dir: &Path, files: &[(&str, &str)]) {
        for (name, text) in files {
            std::fs::write(dir.join(name), text).unwrap();
        }
    }

    pub(super) fn scene(files: &[(&str, &str)]) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), files);
        dir
    }

    pub(super) fn err(files: &[(&str, &str)]) -> String {
        let dir = scene(files);
        Scene::load(dir.path()).unwrap_err().to_string()
    }

    #[test]
    fn loads_scene_toml_with_obj_and_mtl() {
        let dir = scene(&[
            ("scene.toml", SCENE_TOML),
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", QUAD_MTL),
        ]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.name, "quad");
        assert!(s.path.is_absolute());
        assert_eq!(s.path, std::fs::canonicalize(dir.path()).unwrap());
        assert_eq!(s.triangles.len(), 2);
        assert_eq!(s.positions.len(), 4);
        assert_eq!(s.texcoords.len(), 4);
        assert_eq!(s.triangle_materials, vec![0, 0]);
        assert_eq!(s.materials.len(), 1);
        let m = &s.materials[0];
        assert_eq!(m.name, "white");
        assert_eq!(m.kd, [0.8, 0.7, 0.6]);
        assert_eq!(m.ks, [0.1, 0.1, 0.1]);
        assert_eq!(m.ns, 20.0);
        assert_eq!(m.map_kd, Some(TextureSource::File(s.path.join("wood.png"))));
        assert_eq!(s.camera.resolution, [320, 240]);
        assert_eq!(s.camera.fov_y_deg, 40.0);
        assert_eq!(s.lights.len(), 1);
        assert_eq!(s.lights[0].direction, Vec3::NEG_Z);
        assert_eq!(s.lights[0].cutoff_deg, 45.0);
        // Only the missing texture is worth a warning.
        assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
        assert!(s.warnings[0].contains("wood.png"));
        for t in 0..s.triangles.len() {
            let [a, b, c] = s.triangle(t);
            assert!((b - a).cross(c - a).length() > 0.0);
        }
        assert!((s.diameter() - 2f32.sqrt()).abs() < 1e-6);
    }

    #[test]
    fn missing_dir_and_dir_without_obj() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nope");
        let e = Scene::load(&missing).unwrap_err();
        assert!(matches!(e, SceneError::DirNotFound { .. }));
        assert!(e.to_string().contains("does not exist"), "{e}");
        assert!(e.to_string().contains("nope"), "{e}");

        write(dir.path(), &[("readme.txt", "hi")]);
        let e = Scene::load(dir.path()).unwrap_err();
        assert!(matches!(e, SceneError::NoObj { .. }), "{e:?}");
        assert!(
            e.to_string()
                .contains("contains no .obj, .gltf or .glb file"),
            "{e}"
        );

        let e = Scene::load(&dir.path().join("readme.txt")).unwrap_err();
        assert!(matches!(e, SceneError::NotADirectory { .. }), "{e:?}");
    }

    #[test]
    fn obj_without_mtl_gets_grey_default_and_warnings() {
        let dir = scene(&[("quad.obj", QUAD_OBJ)]); // names quad.mtl, which is missing
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.materials.len(), 1);
        assert_eq!(s.materials[0].name, "default");
        assert_eq!(s.materials[0].kd, [0.5; 3]);
        assert_eq!(s.materials[0].ks, [0.0; 3]);
        assert_eq!(s.triangle_materials, vec![0, 0]);
        let w = s.warnings.join("\n");
        assert!(w.contains("quad.mtl") && w.contains("not found"), "{w}");
        assert!(w.contains("no material"), "{w}");
        // Defaults chosen without scene.toml are announced.
        assert!(w.contains("no scene.toml"), "{w}");
        assert!(w.contains("default camera"), "{w}");
        assert!(w.contains("default light"), "{w}");
        let dirname = s.path.file_name().unwrap().to_string_lossy().into_owned();
        assert_eq!(s.name, dirname);

        // OBJ with no mtllib at all.
        let dir = scene(&[("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.materials[0].name, "default");
        assert!(s.texcoords.is_empty());
    }

    #[test]
    fn default_camera_and_light_frame_the_box() {
        let obj = "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nv -1 2 -1\nv 1 2 -1\nv 1 2 1\n\
                   f 1 2 3\nf 1 3 4\nf 5 6 7\n";
        let dir = scene(&[("box.obj", obj)]);
        let s = Scene::load(dir.path()).unwrap();
        let centre = Vec3::new(0.0, 1.0, 0.0);
        assert_eq!(s.camera.target, centre);
        // Open on every side: seen from +z, the first side of the default camera's order.
        assert!(s.camera.position.z > 1.0 && s.camera.position.x == 0.0);
        assert_eq!(s.camera.fov_y_deg, DEFAULT_FOV_Y_DEG);
        assert_eq!(s.camera.resolution, DEFAULT_RESOLUTION);
        // The bounding sphere fits the view cone.
        let radius = 0.5 * s.diameter();
        let d = (s.camera.position - centre).length();
        assert!(radius / d <= (20f32).to_radians().sin() + 1e-6);
        let l = &s.lights[0];
        assert_eq!(l.direction, Vec3::NEG_Y);
        assert!(l.position.y < 2.0 && l.position.y > 1.9, "{:?}", l.position);
        assert_eq!((l.position.x, l.position.z), (0.0, 0.0));
        assert!(l.intensity[0] > 0.0);
    }

    #[test]
    fn multiple_objs_are_merged_in_name_order() {
        let a = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let b = "v 5 0 0\nv 6 0 0\nv 5 1 0\nf 1 2 3\n";
        let dir = scene(&[("b.obj", b), ("a.obj", a)]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.triangles, vec![[0, 1, 2], [3, 4, 5]]);
        assert_eq!(s.positions[3], Vec3::new(5.0, 0.0, 0.0));
        // One shared default material.
        assert_eq!(s.materials.len(), 1);
        assert_eq!(s.triangle_materials, vec![0, 0]);
    }

    #[test]
    fn objects_are_transformed_and_merged() {
        let toml = format!(
            "{SCENE_TOML}\n[[objects]]\nname = \"bunny\"\nmesh = \"tri.obj\"\n\
             translation = [10.0, 0.0, 0.0]\nrotation_deg = [0.0, 0.0, 90.0]\nscale = 2.0\n"
        );
        let dir = scene(&[
            ("scene.toml", &toml),
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", QUAD_MTL),
            ("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
        ]);
        let s = Scene::load(dir.path()).unwrap();
        assert_eq!(s.triangles.len(), 3);
        // (1,0,0) scaled by 2, rotated 90° about z -> (0,2,0), translated -> (10,2,0).
        assert!((s.positions[5] - Vec3::new(10.0, 2.0, 0.0)).length() < 1e-5);
        assert!((s.positions[6] - Vec3::new(8.0, 0.0, 0.0)).length() < 1e-5);
        // tri.obj has no texcoords, so the merged scene has none.
        assert!(s.texcoords.is_empty());
        assert_eq!(s.triangle_materials, vec![0, 0, 1]);
        assert_eq!(s.materials[1].name, "default");
    }

    #[test]
    fn content_hash_tracks_every_byte() {
        let files = [
            ("scene.toml", SCENE_TOML),
            ("quad.obj", QUAD_OBJ),
            ("quad.mtl", QUAD_MTL),
        ];
        let d1 = scene(&files);
        let d2 = scene(&files);
        let h1 = Scene::load(d1.path()).unwrap().content_hash;
        assert_eq!(h1, Scene::load(d1.path()).unwrap().content_hash);
        // Same content elsewhere: same hash.
        assert_eq!(h1, Scene::load(d2.path()).unwrap().content_hash);
        // One byte of the OBJ.
        write(
            d2.path(),
            &[("quad.obj", &QUAD_OBJ.replace("v 1 1 0", "v 1 1 1"))],
        );
        let h2 = Scene::load(d2.path()).unwrap().content_hash;
        assert_ne!(h1, h2);
        // One byte of the MTL.
        let d3 = scene(&files);
        write(
            d3.path(),
            &[("quad.mtl", &QUAD_MTL.replace("Ns 20", "Ns 21"))],
        );
        assert_ne!(h1, Scene::load(d3.path()).unwrap().content_hash);
        // One byte of scene.toml.
        let d4 = scene(&files);
        write(
            d4.path(),
            &[("scene.toml", &SCENE_TOML.replace("320", "321"))],
        );
        assert_ne!(h1, Scene::load(d4.path()).unwrap().content_hash);
        assert_eq!(hash_hex(&h1).len(), 64);
        assert_eq!(&hash_hex(&[0xab; 32])[..4], "abab");
    }
}
