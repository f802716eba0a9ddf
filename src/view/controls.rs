//! The window's camera and light controls: pure functions of the current camera or light and
//! the mouse or key motion, so that they are tested without a window.
//!
//! The camera orbits about the point it looks at (`Camera::target`, which the scene's camera
//! aims at what it frames; the pivot moves with the camera when it flies); the wheel dollies
//! towards it; the fly keys move camera and pivot together. Steps scale with the scene's
//! size. The light is the scene's first spot light: a right drag turns its direction about
//! the camera's axes, a shift + right drag moves it in the view plane.

use cssm::formats::{Camera, Scene, scene::SpotLight};
use glam::{Quat, Vec3};

/// Radians per pixel of mouse motion.
const RADIANS_PER_PIXEL: f32 = 0.005;

/// The camera's forward, right and up unit vectors.
fn frame(camera: &Camera) -> (Vec3, Vec3, Vec3) {
    let forward = (camera.target - camera.position).normalize_or(Vec3::NEG_Z);
    let right = forward.cross(camera.up).normalize_or(Vec3::X);
    (forward, right, right.cross(forward))
}

/// The scene's diagonal: what steps scale with.
fn scene_size(scene: &Scene) -> f32 {
    let (lo, hi) = scene.bounds();
    (hi - lo).length().max(1e-3)
}

/// `camera` turned about its target by a mouse motion of `dx`, `dy` pixels: a drag to the
/// right turns it about the up axis, a drag down about its right axis; never over the pole
/// (a view straight along `up` has no right axis).
pub fn orbit(camera: &Camera, dx: f32, dy: f32) -> Camera {
    let up = camera.up.normalize_or(Vec3::Y);
    let offset = camera.position - camera.target;
    let yaw = Quat::from_axis_angle(up, -dx * RADIANS_PER_PIXEL);
    let mut turned = yaw * offset;
    let (_, right, _) = frame(camera);
    let pitched = Quat::from_axis_angle(yaw * right, -dy * RADIANS_PER_PIXEL) * turned;
    if pitched.normalize_or_zero().dot(up).abs() < 0.99 {
        turned = pitched;
    }
    Camera {
        position: camera.target + turned,
        ..camera.clone()
    }
}

/// `camera` moved towards its target (`lines` > 0, a wheel turned forward) or away: 10% of
/// the distance per line; never onto the target.
pub fn dolly(camera: &Camera, lines: f32, scene: &Scene) -> Camera {
    let offset = camera.position - camera.target;
    let distance = (offset.length() * 0.9f32.powf(lines)).max(scene_size(scene) * 1e-3);
    Camera {
        position: camera.target + offset.normalize_or(Vec3::Z) * distance,
        ..camera.clone()
    }
}

/// `camera` and its target moved by one key press: `forward`, `right` and `up` steps of 2%
/// of the scene's diagonal each.
pub fn fly(camera: &Camera, forward: f32, right: f32, up: f32, scene: &Scene) -> Camera {
    let (f, r, u) = frame(camera);
    let step = (f * forward + r * right + u * up) * scene_size(scene) * 0.02;
    Camera {
        position: camera.position + step,
        target: camera.target + step,
        ..camera.clone()
    }
}

/// `light` aimed elsewhere by a mouse motion: its direction turned about the camera's up and
/// right axes, so that the spot follows the drag on the screen.
pub fn aim_light(light: &SpotLight, camera: &Camera, dx: f32, dy: f32) -> SpotLight {
    let (_, right, up) = frame(camera);
    let turn = Quat::from_axis_angle(right, -dy * RADIANS_PER_PIXEL)
        * Quat::from_axis_angle(up, -dx * RADIANS_PER_PIXEL);
    SpotLight {
        direction: (turn * light.direction).normalize_or(light.direction),
        ..light.clone()
    }
}

/// `light` moved in the view plane by a mouse motion: 0.1% of the scene's diagonal per pixel.
pub fn move_light(
    light: &SpotLight,
    camera: &Camera,
    dx: f32,
    dy: f32,
    scene: &Scene,
) -> SpotLight {
    let (_, right, up) = frame(camera);
    let step = (right * dx - up * dy) * scene_size(scene) * 1e-3;
    SpotLight {
        position: light.position + step,
        ..light.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            position: Vec3::new(0.0, 1.0, 3.0),
            target: Vec3::new(0.0, 1.0, 0.0),
            up: Vec3::Y,
            fov_y_deg: 40.0,
            resolution: [64, 48],
        }
    }

    #[test]
    fn orbit_keeps_the_distance_and_the_target_and_stops_at_the_pole() {
        let c = camera();
        let o = orbit(&c, 100.0, 40.0);
        assert_eq!(o.target, c.target);
        assert!(((o.position - o.target).length() - 3.0).abs() < 1e-4);
        assert!((o.position - c.position).length() > 0.1, "it moved");
        // A drag far past the pole leaves the pitch where it was.
        let mut p = c.clone();
        for _ in 0..100 {
            p = orbit(&p, 0.0, 50.0);
        }
        let dir = (p.position - p.target).normalize();
        assert!(dir.dot(Vec3::Y).abs() < 0.99, "{dir}");
    }

    #[test]
    fn aiming_turns_the_light_and_keeps_it_a_unit_direction() {
        let light = SpotLight {
            position: Vec3::new(0.0, 1.9, 0.0),
            direction: Vec3::NEG_Y,
            cutoff_deg: 45.0,
            intensity: [1.0; 3],
        };
        let turned = aim_light(&light, &camera(), 0.0, -100.0);
        assert!((turned.direction.length() - 1.0).abs() < 1e-5);
        // 100 pixels are 0.5 radians.
        assert!((turned.direction.dot(light.direction) - 0.5f32.cos()).abs() < 1e-4);
        assert_eq!(turned.position, light.position);
    }
}
