//! Scene description: a directory with `scene.toml` and OBJ/MTL meshes, or a plain directory of
//! OBJ files (see `docs/scene-format.md`).
//!
//! TODO(helper): `Scene::load`, error types, tests.

use std::path::PathBuf;

use glam::Vec3;

/// A material from the MTL (conventions in `docs/architecture.md`).
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
    /// Albedo texture (`map_Kd`), resolved to a path, if any.
    pub map_kd: Option<PathBuf>,
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

/// A loaded, triangulated, validated scene: one indexed triangle mesh in world space.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Scene name.
    pub name: String,
    /// Absolute (canonical) path of the scene directory.
    pub dir: PathBuf,
    /// Vertex positions, world space.
    pub positions: Vec<Vec3>,
    /// Optional per-vertex texture coordinates (same length as `positions`, or empty).
    pub texcoords: Vec<[f32; 2]>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Material index of every triangle.
    pub triangle_materials: Vec<u32>,
    /// Materials.
    pub materials: Vec<Material>,
    /// Camera.
    pub camera: Camera,
    /// Lights.
    pub lights: Vec<SpotLight>,
    /// BLAKE3 over every file the scene was built from, in a fixed order.
    pub content_hash: [u8; 32],
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

    /// Length of the bounding-box diagonal: the far plane of every depth cube map (§3.2.1).
    pub fn diameter(&self) -> f32 {
        let (lo, hi) = self.bounds();
        (hi - lo).length()
    }
}
