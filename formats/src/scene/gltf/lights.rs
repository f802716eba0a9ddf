//! glTF cameras and `KHR_lights_punctual` lights as this project's: the first perspective
//! camera, and spot lights as their cones of equal flux (point lights as the widest spot).

use std::path::Path;

use glam::{Affine3A, Vec3};

use crate::scene::toml::{CameraToml, LightKind, LightToml};
use crate::scene::validate::{check_camera, check_light};
use crate::scene::{Builder, Camera, DEFAULT_RESOLUTION, SceneError, SpotLight};

/// Vertical size of the image of a glTF camera that gives only its aspect ratio, pixels.
const CAMERA_HEIGHT: u32 = DEFAULT_RESOLUTION[1];

/// Widest cone of a converted spot light, degrees: the runtime's widest shadow map.
const MAX_CONE_DEG: f32 = crate::scene::MAX_SPOT_CUTOFF_DEG;

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

impl Builder {
    /// The camera of a glTF camera node placed by `world` (looking down its -z, +y up), or
    /// `None` with a warning for an orthographic one.
    pub(super) fn convert_camera(
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
    pub(super) fn convert_light(
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
