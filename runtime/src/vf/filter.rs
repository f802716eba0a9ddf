//! The visibility filter (Chen et al. 2014 §3.2, Eq. 4; `filter.wgsl`): sparse shadow rays
//! miss voxels a pixel sees, and a voxel stands for many VPLs, so a missed voxel is a visible
//! jump in the light. Each pixel of the marching resolution therefore takes the union of the
//! visible-voxel lists of its `(2m+1) x (2m+1)` neighbours on the same surface: a neighbour
//! counts when its distance from the eye is within `depth` times the pixel's of it
//! (`delta_d`) and its normal's cosine with the pixel's is at least `normal` (`delta_n`). The
//! paper filters 7 x 7 (m = 3).
//!
//! The union is a bit mask over the grid's voxels per pixel (so the grid is limited to
//! [`MAX_FILTER_VOXELS`] voxels), written out as a list in increasing key order, which the
//! gathering merges across the four neighbours it weighs (Eq. 5).
//!
//! CPU twin: [`filter_cpu`]; test `tests/gpu/vf.rs::visibility_filter_matches_cpu_twin`.

use glam::{Vec3, Vec4};
use wgpu::util::DeviceExt;

use super::march::{NO_VOXEL, SparseRays};
use crate::{
    RuntimeError,
    common::{filters, layout},
    frame::{FrameContext, FrameEncoder},
    shaders,
};

/// `vf/filter.wgsl`: the visibility filter, the union of the neighbours' voxel lists.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("vf visibility filter", "vf/filter.wgsl");

/// Most voxels of a grid the filter's masks cover: 32³, 4 KiB of mask per pixel.
pub const MAX_FILTER_VOXELS: u32 = 32 * 32 * 32;

/// Most neighbours on each side (m of Eq. 4).
pub const MAX_FILTER_RADIUS: u32 = 8;

/// The filter's window and surface tests.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterShape {
    /// m: the window is `(2m+1) x (2m+1)` pixels; 0 keeps each pixel's own list.
    pub radius: u32,
    /// `delta_d`: largest difference of distance from the eye, relative to the pixel's.
    pub depth: f32,
    /// `delta_n`: smallest cosine between the normals.
    pub normal: f32,
}

/// `filter.wgsl`'s `FilterParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FilterParams {
    /// The marching resolution.
    pub low_size: [u32; 2],
    /// The G-buffer's.
    pub full_size: [u32; 2],
    /// Reduction per side.
    pub factor: u32,
    /// Rays per pixel.
    pub rays: u32,
    /// m.
    pub radius: u32,
    /// `u32` words of a voxel mask.
    pub words: u32,
    /// Most voxels of a filtered list.
    pub capacity: u32,
    /// `delta_d`'s relative tolerance.
    pub depth: f32,
    /// `delta_n`'s smallest cosine.
    pub normal: f32,
    /// Padding.
    pub pad: u32,
}

impl FilterParams {
    /// The parameters for `rays`' pixels over a grid of `voxels`.
    ///
    /// # Errors
    /// A grid of more than [`MAX_FILTER_VOXELS`], a radius above [`MAX_FILTER_RADIUS`].
    pub fn new(rays: &SparseRays, voxels: u32, shape: &FilterShape) -> Result<Self, RuntimeError> {
        if voxels > MAX_FILTER_VOXELS {
            return Err(RuntimeError::Unsupported(format!(
                "a visibility filter over {voxels} voxels: at most {MAX_FILTER_VOXELS} (32³)"
            )));
        }
        if shape.radius > MAX_FILTER_RADIUS {
            return Err(RuntimeError::Unsupported(format!(
                "visibility filter radius {}: at most {MAX_FILTER_RADIUS}",
                shape.radius
            )));
        }
        let m = rays.params;
        let window = (2 * shape.radius + 1).pow(2);
        Ok(Self {
            low_size: m.low_size,
            full_size: m.full_size,
            factor: m.factor,
            rays: m.rays,
            radius: shape.radius,
            words: voxels.div_ceil(32),
            capacity: voxels.min(window * m.rays),
            depth: shape.depth,
            normal: shape.normal,
            pad: 0,
        })
    }

    /// Marching pixels.
    pub fn pixels(&self) -> u32 {
        self.low_size[0] * self.low_size[1]
    }
}

/// The filter pass and its lists.
pub struct VisibilityFilter {
    /// The pass's parameters.
    pub params: FilterParams,
    /// Per marching pixel `capacity + 1` entries: the count, then the voxels in increasing
    /// key order.
    pub lists: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
}

impl VisibilityFilter {
    /// The filter of `rays`' lists over a grid of `voxels`.
    ///
    /// # Errors
    /// Those of [`FilterParams::new`]; buffers above the device's storage binding size.
    pub fn new(
        ctx: &FrameContext,
        rays: &SparseRays,
        voxels: u32,
        shape: &FilterShape,
    ) -> Result<Self, RuntimeError> {
        let device = &ctx.device;
        let params = FilterParams::new(rays, voxels, shape)?;
        let pixels = u64::from(params.pixels()).max(1);
        let mask_bytes = 4 * pixels * u64::from(params.words);
        let list_bytes = 4 * pixels * u64::from(params.capacity + 1);
        let limit = device.limits().max_storage_buffer_binding_size;
        for (what, bytes) in [("masks", mask_bytes), ("lists", list_bytes)] {
            if bytes > limit {
                return Err(RuntimeError::Unsupported(format!(
                    "the visibility filter's {what} need {bytes} bytes, the device binds at \
                     most {limit}: fewer voxels, rays or marching pixels"
                )));
            }
        }
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("visibility filter"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let buffer = |label, size| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let mask = buffer("visibility masks", mask_bytes);
        let lists = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("visibility lists"),
            size: list_bytes,
            // COPY_DST: a test writes lists of its own.
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let bind_layout = layout::bind_group_layout(
            device,
            "visibility filter",
            &[
                layout::uniform(0, c),
                layout::uniform(1, c),
                layout::texture(2, d2, c),
                layout::texture(3, d2, c),
                layout::storage(4, true, c),
                layout::storage(5, false, c),
                layout::storage(6, false, c),
            ],
        );
        let views = [&ctx.gbuffer.position, &ctx.gbuffer.normal]
            .map(|t| t.create_view(&Default::default()));
        let bind_group = layout::bind_group(
            device,
            "visibility filter",
            &bind_layout,
            &[
                uniform.as_entire_binding(),
                ctx.view.as_entire_binding(),
                wgpu::BindingResource::TextureView(&views[0]),
                wgpu::BindingResource::TextureView(&views[1]),
                rays.visible.as_entire_binding(),
                mask.as_entire_binding(),
                lists.as_entire_binding(),
            ],
        );
        let module = SHADER.create(device);
        let pipeline =
            layout::compute_pipeline(device, "visibility filter", &module, &[&bind_layout]);
        Ok(Self {
            params,
            lists,
            pipeline,
            bind_group,
        })
    }

    /// Records the filter (timed as "visibility filter").
    pub fn run(&self, frame: &mut FrameEncoder) {
        let mut pass = frame.compute_pass("visibility filter");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        let (x, y) = shaders::groups_2d((self.params.low_size[0], self.params.low_size[1]));
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// CPU twin of the pass: per marching pixel, its filtered list in increasing key order, from
/// the rays' `visible` keys, the G-buffer's rows (`position` with w > 0 where covered,
/// `normal`) and the eye.
pub fn filter_cpu(
    params: &FilterParams,
    visible: &[u32],
    position: &[Vec4],
    normal: &[Vec4],
    eye: Vec3,
) -> Vec<Vec<u32>> {
    let [lw, lh] = params.low_size;
    let full = (params.full_size[0], params.full_size[1]);
    let guide = |x: u32, y: u32| {
        let (fx, fy) = filters::representative((x, y), params.factor, full);
        let i = (fy * full.0 + fx) as usize;
        (position[i], normal[i].truncate())
    };
    let m = params.radius as i32;
    let mut out = Vec::with_capacity((lw * lh) as usize);
    for y in 0..lh {
        for x in 0..lw {
            let (p, n) = guide(x, y);
            if p.w <= 0.0 {
                out.push(Vec::new());
                continue;
            }
            let d = eye.distance(p.truncate());
            let mut union = std::collections::BTreeSet::new();
            for j in -m..=m {
                for i in -m..=m {
                    let (tx, ty) = (x as i32 + i, y as i32 + j);
                    if tx < 0 || ty < 0 || tx >= lw as i32 || ty >= lh as i32 {
                        continue;
                    }
                    let (tp, tn) = guide(tx as u32, ty as u32);
                    if tp.w <= 0.0 {
                        continue;
                    }
                    let same_depth = (eye.distance(tp.truncate()) - d).abs() <= params.depth * d;
                    let same_surface = same_depth && tn.dot(n) >= params.normal;
                    if !same_surface && (i, j) != (0, 0) {
                        continue;
                    }
                    let base = ((ty as u32 * lw + tx as u32) * params.rays) as usize;
                    union.extend(
                        visible[base..base + params.rays as usize]
                            .iter()
                            .filter(|&&k| k != NO_VOXEL),
                    );
                }
            }
            out.push(union.into_iter().take(params.capacity as usize).collect());
        }
    }
    out
}

/// The GPU's lists ([`VisibilityFilter::lists`] as read back) as per-pixel lists.
pub fn unpack_lists(params: &FilterParams, lists: &[u32]) -> Vec<Vec<u32>> {
    let stride = (params.capacity + 1) as usize;
    lists
        .chunks(stride)
        .take(params.pixels() as usize)
        .map(|c| c[1..1 + (c[0] as usize).min(stride - 1)].to_vec())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filter_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "FilterParams",
            size_of::<FilterParams>(),
            &[
                ("low_size", offset_of!(FilterParams, low_size)),
                ("full_size", offset_of!(FilterParams, full_size)),
                ("factor", offset_of!(FilterParams, factor)),
                ("rays", offset_of!(FilterParams, rays)),
                ("radius", offset_of!(FilterParams, radius)),
                ("words", offset_of!(FilterParams, words)),
                ("capacity", offset_of!(FilterParams, capacity)),
                ("depth", offset_of!(FilterParams, depth)),
                ("normal", offset_of!(FilterParams, normal)),
                ("pad", offset_of!(FilterParams, pad)),
            ],
        );
    }

    /// Three pixels in a row on one plane, the middle one on another: the union skips the
    /// pixel of the other surface and keeps each voxel once, in order.
    #[test]
    fn the_union_keeps_one_surface() {
        let params = FilterParams {
            low_size: [3, 1],
            full_size: [3, 1],
            factor: 1,
            rays: 2,
            radius: 1,
            words: 1,
            capacity: 6,
            depth: 0.1,
            normal: 0.9,
            pad: 0,
        };
        let position = [Vec4::new(0.0, 0.0, 1.0, 1.0); 3];
        let up = Vec4::new(0.0, 0.0, 1.0, 0.0);
        let normal = [up, Vec4::new(1.0, 0.0, 0.0, 0.0), up];
        let visible = [5, NO_VOXEL, 7, 9, 5, 2];
        let lists = filter_cpu(&params, &visible, &position, &normal, Vec3::ZERO);
        assert_eq!(lists, vec![vec![5], vec![7, 9], vec![2, 5]]);
        let packed = [
            1, 5, 0, 0, 0, 0, 0, 2, 7, 9, 0, 0, 0, 0, 2, 2, 5, 0, 0, 0, 0,
        ];
        assert_eq!(unpack_lists(&params, &packed), lists);
    }
}
