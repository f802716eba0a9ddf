//! Checks of the values `scene.toml` gives before any mesh is loaded: the camera, the lights and
//! the object transforms must be finite and in range; each becomes its scene type or an error
//! naming the file and the value.

use std::path::Path;

use glam::{Mat3, Vec3};

use super::toml::{CameraToml, LightKind, LightToml, ObjectToml};
use super::{Camera, SceneError, SpotLight, fmt3};

fn vec3(v: [f32; 3]) -> Vec3 {
    Vec3::from(v)
}

pub(super) fn check_camera(c: &CameraToml, path: &Path) -> Result<Camera, SceneError> {
    let bad = |message: String| SceneError::Invalid {
        path: path.to_path_buf(),
        message: format!("[camera]: {message}"),
    };
    let (position, target, up) = (vec3(c.position), vec3(c.target), vec3(c.up));
    if !(position.is_finite() && target.is_finite() && up.is_finite()) {
        return Err(bad("position, target and up must be finite".into()));
    }
    let view = target - position;
    if view.length_squared() == 0.0 {
        return Err(bad("position and target are the same point".into()));
    }
    if up.length_squared() == 0.0 || view.normalize().cross(up.normalize()).length() < 1e-6 {
        return Err(bad("up is zero or parallel to the viewing direction".into()));
    }
    if !(c.fov_y_deg > 0.0 && c.fov_y_deg < 180.0) {
        return Err(bad(format!(
            "fov_y_deg {} must be in (0, 180)",
            c.fov_y_deg
        )));
    }
    let [w, h] = c.resolution;
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err(bad(format!(
            "resolution [{w}, {h}] must be between 1 and 16384 in each axis"
        )));
    }
    Ok(Camera {
        position,
        target,
        up: up.normalize(),
        fov_y_deg: c.fov_y_deg,
        resolution: c.resolution,
    })
}

pub(super) fn check_light(i: usize, l: &LightToml, path: &Path) -> Result<SpotLight, SceneError> {
    let LightKind::Spot = l.kind;
    let bad = |message: String| SceneError::Invalid {
        path: path.to_path_buf(),
        message: format!("lights[{i}]: {message}"),
    };
    let position = vec3(l.position);
    let direction = vec3(l.direction);
    if !position.is_finite() {
        return Err(bad("position must be finite".into()));
    }
    if !direction.is_finite() || direction.length_squared() == 0.0 {
        return Err(bad(format!(
            "direction {} must be a finite non-zero vector",
            fmt3(direction)
        )));
    }
    if !(l.cutoff_deg > 0.0 && l.cutoff_deg < 180.0) {
        return Err(bad(format!(
            "cutoff_deg {} must be in (0, 180)",
            l.cutoff_deg
        )));
    }
    if !l.intensity.iter().all(|v| v.is_finite() && *v >= 0.0) {
        return Err(bad("intensity must be finite and non-negative".into()));
    }
    Ok(SpotLight {
        position,
        direction: direction.normalize(),
        cutoff_deg: l.cutoff_deg,
        intensity: l.intensity,
    })
}

pub(super) fn object_transform(o: &ObjectToml, path: &Path) -> Result<(Mat3, Vec3), SceneError> {
    let bad = |message: String| SceneError::Invalid {
        path: path.to_path_buf(),
        message: format!("object `{}`: {message}", o.name),
    };
    let t = vec3(o.translation);
    let r = vec3(o.rotation_deg);
    if !(t.is_finite() && r.is_finite()) {
        return Err(bad("translation and rotation_deg must be finite".into()));
    }
    if !(o.scale.is_finite() && o.scale > 0.0) {
        return Err(bad(format!("scale {} must be finite and > 0", o.scale)));
    }
    let placed = super::placement(t, r, o.scale);
    Ok((placed.matrix3.into(), t))
}

#[cfg(test)]
mod tests {
    use crate::scene::tests::{QUAD_OBJ, SCENE_TOML, err};

    #[test]
    fn invalid_lights_and_camera() {
        let toml = SCENE_TOML.replace("[0.0, 0.0, -2.0]", "[0.0, 0.0, 0.0]");
        let e = err(&[("scene.toml", &toml), ("quad.obj", QUAD_OBJ)]);
        assert!(e.contains("scene.toml") && e.contains("lights[0]"), "{e}");
        assert!(e.contains("direction"), "{e}");
        let toml = SCENE_TOML.replace("fov_y_deg  = 40.0", "fov_y_deg  = 0.0");
        let e = err(&[("scene.toml", &toml), ("quad.obj", QUAD_OBJ)]);
        assert!(e.contains("fov_y_deg"), "{e}");
        let toml = SCENE_TOML.replace("cutoff_deg = 45.0", "");
        let e = err(&[("scene.toml", &toml), ("quad.obj", QUAD_OBJ)]);
        assert!(e.contains("cutoff_deg"), "{e}");
    }
}
