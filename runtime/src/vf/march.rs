//! Sparse shadow rays through the proxies' voxel grid (Chen et al. 2014 §3.1, Fig. 2 (c), (d);
//! `march.wgsl`): from each pixel of the G-buffer reduced `factor` times per side (the shared
//! filters' representative pixels), `rays` cosine-distributed directions around the normal
//! march the grid voxel by voxel (Amanatides and Woo); in each voxel a ray tests the discs of
//! its proxies (its range of the sorted proxies), and the first voxel with a disc it hits ends
//! it. The pixel's visible-voxel list is its rays' voxels ([`NO_VOXEL`] for a ray that leaves
//! the grid), which the visibility filter (Eq. 4) then unions across neighbours.
//! One invocation per ray, not per pixel: the pixels of a reduced image are too few to fill a
//! GPU (14,400 at 1280x720), their rays are not.
//!
//! CPU twin: [`march_cpu`]; test `tests/gpu/vf.rs::shadow_rays_match_cpu_twin`.

use glam::{IVec3, Mat3, UVec2, Vec3, Vec4};
use wgpu::util::DeviceExt;

use super::{light::ProxyLight, proxies::GridParams, proxies::ProxyGrid};
use crate::{
    common::{
        filters, layout,
        random::{hash_unit, pcg_hash},
    },
    frame::{FrameContext, FrameEncoder},
    shaders,
};

/// `vf/march.wgsl`: the sparse shadow rays through the proxies' voxels.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("vf shadow rays", "vf/march.wgsl");

/// The key of no voxel: a ray that left the grid.
pub const NO_VOXEL: u32 = u32::MAX;

/// `march.wgsl`'s `MarchParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MarchParams {
    /// The G-buffer's size.
    pub full_size: [u32; 2],
    /// The reduced size.
    pub low_size: [u32; 2],
    /// Reduction per side.
    pub factor: u32,
    /// Rays per pixel.
    pub rays: u32,
    /// Seed of the directions' rotation per pixel.
    pub seed: u32,
    /// Origins lifted by this much along the normal; nearer hits ignored.
    pub offset: f32,
    /// The discs' radii as the rays test them, times the proxies' own (which give each disc
    /// its share of the area and leave gaps between discs).
    pub disc_scale: f32,
    /// Padding.
    pub pad: u32,
}

/// What the shadow rays are: where from, how many, against which discs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayShape {
    /// Reduction per side of the G-buffer the rays start from.
    pub factor: u32,
    /// Rays per reduced pixel.
    pub rays: u32,
    /// Origins lifted by this much along the normal (world units); nearer hits ignored.
    pub offset: f32,
    /// The discs' radii as the rays test them, times the proxies' own.
    pub disc_scale: f32,
}

/// The shadow-ray pass and its per-pixel voxel lists.
pub struct SparseRays {
    /// The pass's parameters.
    pub params: MarchParams,
    /// Per reduced pixel, `rays` voxel keys.
    pub visible: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
}

impl SparseRays {
    /// `rays` rays per pixel of the context's G-buffer reduced `factor` times, through
    /// `grid`'s voxels and `light`'s discs (their radii times `disc_scale`), origins lifted by
    /// `offset`.
    pub fn new(ctx: &FrameContext, grid: &ProxyGrid, light: &ProxyLight, shape: RayShape) -> Self {
        let RayShape {
            factor,
            rays,
            offset,
            disc_scale,
        } = shape;
        let device = &ctx.device;
        let full = ctx.size();
        let low = filters::low_size(full, factor);
        let params = MarchParams {
            full_size: [full.0, full.1],
            low_size: [low.0, low.1],
            factor,
            rays,
            seed: 0,
            offset,
            disc_scale,
            pad: 0,
        };
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("shadow rays"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let visible = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("visible voxels"),
            size: 4 * u64::from(low.0 * low.1 * rays).max(1),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let bind_layout = layout::bind_group_layout(
            device,
            "shadow rays",
            &[
                layout::uniform(0, c),
                layout::uniform(1, c),
                layout::texture(2, d2, c),
                layout::texture(3, d2, c),
                layout::storage(4, true, c),
                layout::storage(5, true, c),
                layout::storage(6, true, c),
                layout::storage(7, true, c),
                layout::storage(8, false, c),
            ],
        );
        let views = [&ctx.gbuffer.position, &ctx.gbuffer.normal]
            .map(|t| t.create_view(&Default::default()));
        let bind_group = layout::bind_group(
            device,
            "shadow rays",
            &bind_layout,
            &[
                uniform.as_entire_binding(),
                grid.params.as_entire_binding(),
                wgpu::BindingResource::TextureView(&views[0]),
                wgpu::BindingResource::TextureView(&views[1]),
                light.position.as_entire_binding(),
                light.normal.as_entire_binding(),
                grid.sorted.as_entire_binding(),
                grid.cells.as_entire_binding(),
                visible.as_entire_binding(),
            ],
        );
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline(device, "shadow rays", &module, &[&bind_layout]);
        Self {
            params,
            visible,
            pipeline,
            bind_group,
        }
    }

    /// Records the rays (timed as "shadow rays").
    pub fn run(&self, frame: &mut FrameEncoder) {
        let mut pass = frame.compute_pass("shadow rays");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        // One invocation per ray, a row of the low-res image's rays per row of workgroups.
        let [width, height] = self.params.low_size;
        pass.dispatch_workgroups(shaders::groups_1d(width * self.params.rays), height, 1);
    }
}

/// What the twin reads, as the GPU has it: the grid, the discs (position and radius, normal),
/// the sorted pairs and the voxels' ranges.
pub struct MarchInputs<'a> {
    /// The grid.
    pub grid: GridParams,
    /// Per proxy xyz world position, w disc radius.
    pub position: &'a [Vec4],
    /// Per proxy xyz disc normal.
    pub normal: &'a [Vec4],
    /// (key, proxy) sorted by key.
    pub sorted: &'a [[u32; 2]],
    /// Per voxel `[start, end)`.
    pub ranges: &'a [[u32; 2]],
}

impl MarchInputs<'_> {
    /// `march.wgsl`: `hit_in`, discs of radius `scale` times their own.
    fn hit_in(&self, cell: u32, o: Vec3, d: Vec3, (t0, t1): (f32, f32), scale: f32) -> Option<f32> {
        let [start, end] = self.ranges[cell as usize];
        let mut best: Option<f32> = None;
        for pair in &self.sorted[start as usize..end as usize] {
            let (c, n) = (
                self.position[pair[1] as usize],
                self.normal[pair[1] as usize],
            );
            let n = n.truncate();
            let denom = d.dot(n);
            if denom.abs() < 1e-6 {
                continue;
            }
            let t = (c.truncate() - o).dot(n) / denom;
            if t <= t0 || t > t1 || best.is_some_and(|b| t >= b) {
                continue;
            }
            let p = o + t * d;
            let r = scale * c.w;
            if (p - c.truncate()).length_squared() <= r * r {
                best = Some(t);
            }
        }
        best
    }

    /// `march.wgsl`: `march`, the first voxel with a disc (of radius `disc_scale` times its
    /// own) the ray hits, no nearer than `offset`.
    pub fn march(&self, o: Vec3, d: Vec3, offset: f32, disc_scale: f32) -> u32 {
        let g = &self.grid;
        let lo = Vec3::from(g.lo);
        let dims_f = glam::UVec3::from(g.dims).as_vec3();
        let hi = lo + dims_f * g.cell;
        let inv = d.recip();
        let (ta, tb) = ((lo - o) * inv, (hi - o) * inv);
        let t_enter = ta.min(tb).max_element().max(0.0);
        let t_exit = ta.max(tb).min_element();
        if t_enter > t_exit {
            return NO_VOXEL;
        }
        let start = o + t_enter * d;
        let mut v = ((start - lo) / g.cell)
            .floor()
            .clamp(Vec3::ZERO, dims_f - 1.0)
            .as_ivec3();
        let step = IVec3::new(
            d.x.signum() as i32,
            d.y.signum() as i32,
            d.z.signum() as i32,
        );
        let step = IVec3::select(d.cmpeq(Vec3::ZERO), IVec3::ZERO, step);
        let up = Vec3::select(d.cmpgt(Vec3::ZERO), Vec3::ONE, Vec3::ZERO);
        let next_edge = lo + (v.as_vec3() + up) * g.cell;
        let nonzero = d.cmpne(Vec3::ZERO);
        let mut t_max = Vec3::select(nonzero, (next_edge - o) * inv, Vec3::splat(1e30));
        let t_delta = Vec3::select(nonzero, (g.cell * inv).abs(), Vec3::splat(1e30));
        let mut t = t_enter;
        let dims = glam::UVec3::from(g.dims).as_ivec3();
        for _ in 0..dims.element_sum() {
            let cell = (v.z * dims.x * dims.y + v.y * dims.x + v.x) as u32;
            let t_next = t_max.min_element().min(t_exit);
            if self
                .hit_in(cell, o, d, (t.max(offset), t_next), disc_scale)
                .is_some()
            {
                return cell;
            }
            if t_next >= t_exit {
                break;
            }
            t = t_next;
            if t_max.x <= t_max.y && t_max.x <= t_max.z {
                v.x += step.x;
                t_max.x += t_delta.x;
            } else if t_max.y <= t_max.z {
                v.y += step.y;
                t_max.y += t_delta.y;
            } else {
                v.z += step.z;
                t_max.z += t_delta.z;
            }
            if v.cmplt(IVec3::ZERO).any() || v.cmpge(dims).any() {
                break;
            }
        }
        NO_VOXEL
    }
}

/// `march.wgsl`: `basis`.
fn basis(n: Vec3) -> Mat3 {
    let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    Mat3::from_cols(
        Vec3::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x),
        Vec3::new(b, s + n.y * n.y * a, -n.y),
        n,
    )
}

/// CPU twin of the pass at low-res pixel `pixel` whose G-buffer position and normal are `p`
/// and `n`: its rays' voxel keys.
pub fn march_cpu(
    inputs: &MarchInputs,
    params: &MarchParams,
    pixel: UVec2,
    p: Vec4,
    n: Vec3,
) -> Vec<u32> {
    let rays = params.rays as usize;
    if p.w <= 0.0 {
        return vec![NO_VOXEL; rays];
    }
    let frame = basis(n);
    let key = pcg_hash(pixel.x ^ pcg_hash(pixel.y ^ pcg_hash(params.seed)));
    let (r1, r2) = (hash_unit(key), hash_unit(pcg_hash(key)));
    let o = p.truncate() + params.offset * n;
    (0..params.rays)
        .map(|k| {
            let u1 = (k as f32 + r1) / params.rays as f32;
            let u2 = (k as f32 * 0.618_034 + r2).fract();
            let (r, phi) = (u1.sqrt(), 2.0 * std::f32::consts::PI * u2);
            let d = frame * Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt());
            inputs.march(o, d, params.offset, params.disc_scale)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn march_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "MarchParams",
            size_of::<MarchParams>(),
            &[
                ("full_size", offset_of!(MarchParams, full_size)),
                ("low_size", offset_of!(MarchParams, low_size)),
                ("factor", offset_of!(MarchParams, factor)),
                ("rays", offset_of!(MarchParams, rays)),
                ("seed", offset_of!(MarchParams, seed)),
                ("offset", offset_of!(MarchParams, offset)),
                ("disc_scale", offset_of!(MarchParams, disc_scale)),
                ("pad", offset_of!(MarchParams, pad)),
            ],
        );
    }

    /// A ray through a wall of one disc per voxel stops in the first voxel it enters with a
    /// disc across its path, and a ray beside every disc leaves the grid.
    #[test]
    fn a_ray_stops_at_the_first_disc() {
        let grid = GridParams::new((Vec3::ZERO, Vec3::splat(4.0)), 4, 2);
        // Discs facing x at x = 1.5 and x = 2.5 on the row y = z = 0.5.
        let position = [Vec4::new(1.5, 0.5, 0.5, 0.4), Vec4::new(2.5, 0.5, 0.5, 0.4)];
        let normal = [Vec4::new(1.0, 0.0, 0.0, 0.0); 2];
        let keys = [
            grid.key(position[0].truncate()),
            grid.key(position[1].truncate()),
        ];
        let mut sorted = vec![[keys[0], 0], [keys[1], 1]];
        sorted.sort();
        let mut ranges = vec![[0u32; 2]; grid.cells() as usize];
        for (i, &[k, _]) in sorted.iter().enumerate() {
            ranges[k as usize] = [i as u32, i as u32 + 1];
        }
        let inputs = MarchInputs {
            grid,
            position: &position,
            normal: &normal,
            sorted: &sorted,
            ranges: &ranges,
        };
        assert_eq!(
            inputs.march(Vec3::new(0.1, 0.5, 0.5), Vec3::X, 0.0, 1.0),
            keys[0]
        );
        assert_eq!(
            inputs.march(Vec3::new(3.9, 0.5, 0.5), -Vec3::X, 0.0, 1.0),
            keys[1]
        );
        assert_eq!(
            inputs.march(Vec3::new(0.1, 2.5, 0.5), Vec3::X, 0.0, 1.0),
            NO_VOXEL
        );
        assert_eq!(
            inputs.march(Vec3::new(-1.0, 0.5, 0.5), Vec3::Y, 0.0, 1.0),
            NO_VOXEL
        );
    }
}
