//! The `scene.toml` schema (see `docs/scene-format.md`): the serde types the file is parsed into
//! (unknown keys are errors), and the resolution of the mesh paths it names.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::SceneError;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneToml {
    pub(super) name: Option<String>,
    pub(super) mesh: String,
    pub(super) camera: Option<CameraToml>,
    #[serde(default)]
    pub(super) lights: Vec<LightToml>,
    #[serde(default)]
    pub(super) objects: Vec<ObjectToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraToml {
    pub(super) position: [f32; 3],
    pub(super) target: [f32; 3],
    pub(super) up: [f32; 3],
    pub(super) fov_y_deg: f32,
    pub(super) resolution: [u32; 2],
}

#[derive(Deserialize)]
pub(super) enum LightKind {
    #[serde(rename = "spot")]
    Spot,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightToml {
    #[serde(rename = "type")]
    pub(super) kind: LightKind,
    pub(super) position: [f32; 3],
    pub(super) direction: [f32; 3],
    pub(super) cutoff_deg: f32,
    pub(super) intensity: [f32; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ObjectToml {
    pub(super) name: String,
    pub(super) mesh: String,
    #[serde(default)]
    pub(super) translation: [f32; 3],
    #[serde(default)]
    pub(super) rotation_deg: [f32; 3],
    #[serde(default = "one")]
    pub(super) scale: f32,
    /// `[objects.animation]`: keyframes and/or a spin (`animation.rs`).
    pub(super) animation: Option<super::animation::AnimationToml>,
}

fn one() -> f32 {
    1.0
}

/// Resolves a mesh path relative to `scene.toml`; it must be an existing file.
pub(super) fn mesh_path(
    dir: &Path,
    toml_path: &Path,
    what: &str,
    mesh: &str,
) -> Result<PathBuf, SceneError> {
    let p = dir.join(mesh);
    let problem = match std::fs::metadata(&p) {
        Ok(m) => match crate::files::kind_of(&m) {
            None => return Ok(p),
            Some(kind) => format!("is {kind}, not a mesh file"),
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => "does not exist".to_string(),
        Err(e) => format!("cannot be read: {e}"),
    };
    Err(SceneError::Invalid {
        path: toml_path.to_path_buf(),
        message: format!("{what} `{mesh}`: {} {problem}", p.display()),
    })
}

#[cfg(test)]
mod tests {
    use crate::scene::tests::{QUAD_OBJ, SCENE_TOML, err};

    #[test]
    fn unknown_key_names_key_and_line() {
        let toml = SCENE_TOML.replace("fov_y_deg  = 40.0", "fov_y_deg  = 40.0\nfoo = 1");
        let e = err(&[("scene.toml", &toml), ("quad.obj", QUAD_OBJ)]);
        assert!(e.contains("scene.toml"), "{e}");
        assert!(e.contains("foo"), "{e}");
        assert!(e.contains("line 9"), "{e}");
        let toml = format!("bar = true\n{SCENE_TOML}");
        let e = err(&[("scene.toml", &toml), ("quad.obj", QUAD_OBJ)]);
        assert!(e.contains("bar") && e.contains("line 1"), "{e}");
        // Unknown light type.
        let toml = SCENE_TOML.replace("\"spot\"", "\"point\"");
        let e = err(&[("scene.toml", &toml), ("quad.obj", QUAD_OBJ)]);
        assert!(e.contains("point") && e.contains("line 12"), "{e}");
    }

    #[test]
    fn scene_toml_naming_missing_mesh() {
        let e = err(&[("scene.toml", SCENE_TOML)]);
        assert!(e.contains("scene.toml") && e.contains("quad.obj"), "{e}");
    }
}
