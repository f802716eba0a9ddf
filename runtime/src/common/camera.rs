//! The scene camera as matrices, and the primary ray through a pixel centre that the CPU
//! references trace (the rasteriser samples the same centres).

use cssm_formats::{Camera, Scene};
use glam::{Mat4, Vec3, Vec4};

use crate::gpu_types::GpuView;

/// A view of a scene at a given image size.
#[derive(Clone, Copy, Debug)]
pub struct View {
    /// World to clip space (wgpu conventions: depth 0 at the near plane).
    pub view_proj: Mat4,
    /// Eye position.
    pub eye: Vec3,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl View {
    /// The scene's camera at `width` x `height` (the aspect follows the image). Near and far
    /// planes bracket the scene's bounds.
    pub fn of_scene(scene: &Scene, width: u32, height: u32) -> Self {
        Self::new(&scene.camera, scene.bounds(), width, height)
    }

    /// `camera` looking at a scene whose bounds are `lo`..`hi`, at `width` x `height`.
    pub fn new(c: &Camera, (lo, hi): (Vec3, Vec3), width: u32, height: u32) -> Self {
        let diameter = (hi - lo).length();
        let reach = (0.5 * (lo + hi) - c.position).length() + diameter;
        let near = (diameter * 1e-3).max(reach * 1e-5);
        let view = glam::camera::rh::view::look_at_mat4(c.position, c.target, c.up);
        let proj = glam::camera::rh::proj::directx::perspective(
            c.fov_y_deg.to_radians(),
            width as f32 / height as f32,
            near,
            reach * 1.01,
        );
        Self {
            view_proj: proj * view,
            eye: c.position,
            width,
            height,
        }
    }

    /// Unit direction of the ray from the eye through the centre of pixel (`x`, `y`), row 0 at
    /// the top.
    pub fn primary_ray(&self, x: u32, y: u32) -> Vec3 {
        let ndc_x = (x as f32 + 0.5) / self.width as f32 * 2.0 - 1.0;
        let ndc_y = 1.0 - (y as f32 + 0.5) / self.height as f32 * 2.0;
        let inv = self.view_proj.inverse();
        let unproject = |z: f32| {
            let p: Vec4 = inv * Vec4::new(ndc_x, ndc_y, z, 1.0);
            p.truncate() / p.w
        };
        (unproject(1.0) - unproject(0.0)).normalize()
    }

    /// The GPU form, with `light_count` lights and tone-mapping `exposure`.
    pub fn gpu(&self, light_count: u32, exposure: f32) -> GpuView {
        GpuView {
            view_proj: self.view_proj.to_cols_array_2d(),
            eye: self.eye.to_array(),
            light_count,
            size: [self.width, self.height],
            exposure,
            _pad: 0,
        }
    }
}
