//! Conservative GPU voxelisation of the scene into a voxel-fragment list (`voxelize.wgsl`), the
//! shared first step of the voxel techniques: the sparse voxel octree of voxel cone tracing
//! (Crassin et al. 2011 §4.2.1 builds it from the fragments of every voxel a triangle touches),
//! and the voxel grids of SSIL's visibility and of visibility filtering.
//!
//! The grid is a cube around the scene ([`VoxelGrid::of_scene`]). Every voxel a triangle
//! touches, by the separating-axis test of Akenine-Möller (2001, [`triangle_box_overlap`]),
//! gets one [`VoxelFragment`]: its voxel, the triangle's albedo at the voxel centre (Kd times
//! the texture), its normal, its index. Objects are voxelised where their motion puts them.
//! The order of the fragments is the GPU's (an atomic counter); their set is deterministic.
//!
//! CPU twin: [`voxelize_cpu`], the same test over every voxel of each triangle's bounds (the
//! GPU culls to the voxels near the triangle's plane first); test
//! `tests/gpu/voxelize.rs::gpu_voxelisation_matches_brute_force`.

use glam::{Vec3, Vec4};
use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::layout,
    frame::FrameEncoder,
    gpu_types::GpuMaterial,
    load::{AlbedoTexture, SceneGpu},
    shaders,
};

/// `common/voxelize.wgsl`, conservative voxelisation into a voxel-fragment list.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("voxelize", "common/voxelize.wgsl");

/// Largest grid resolution (10 bits per coordinate in a fragment).
pub const MAX_RESOLUTION: u32 = 1024;

/// Columns per tile side: one invocation voxelises one triangle over one tile of its footprint.
pub const TILE: u32 = 16;

/// A cubic grid of `resolution`³ voxels of side `voxel` from `origin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelGrid {
    /// The corner of voxel (0, 0, 0).
    pub origin: Vec3,
    /// Side of a voxel.
    pub voxel: f32,
    /// Voxels per side.
    pub resolution: u32,
}

impl VoxelGrid {
    /// The cube of `resolution`³ voxels around the bounds `lo`..`hi`: the largest extent plus
    /// one voxel, centred, so that the walls of a box lie inside voxels rather than on their
    /// faces.
    pub fn of_scene((lo, hi): (Vec3, Vec3), resolution: u32) -> Self {
        let extent = (hi - lo).max_element().max(f32::MIN_POSITIVE);
        let voxel = extent / (resolution.max(2) - 1) as f32;
        let side = voxel * resolution as f32;
        Self {
            origin: 0.5 * (lo + hi) - Vec3::splat(0.5 * side),
            voxel,
            resolution,
        }
    }

    /// The centre of voxel `cell`.
    pub fn centre(&self, cell: [u32; 3]) -> Vec3 {
        self.origin + (Vec3::new(cell[0] as f32, cell[1] as f32, cell[2] as f32) + 0.5) * self.voxel
    }

    /// Refuses a resolution outside 1 to [`MAX_RESOLUTION`] and a grid that is not finite.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] naming the value.
    pub fn check(&self) -> Result<(), RuntimeError> {
        if !(1..=MAX_RESOLUTION).contains(&self.resolution) {
            return Err(RuntimeError::Unsupported(format!(
                "voxel resolution {} is out of range 1..={MAX_RESOLUTION}",
                self.resolution
            )));
        }
        if !(self.origin.is_finite() && self.voxel.is_finite() && self.voxel > 0.0) {
            return Err(RuntimeError::Unsupported(
                "the voxel grid of a scene with non-finite bounds".into(),
            ));
        }
        Ok(())
    }
}

/// One voxel a triangle touches (`voxelize.wgsl`: `VoxelFragment`).
#[repr(C)]
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    bytemuck::Pod,
    bytemuck::Zeroable,
)]
pub struct VoxelFragment {
    /// `x | y << 10 | z << 20`.
    pub coord: u32,
    /// The albedo, `pack4x8unorm(albedo, 1)`.
    pub albedo: u32,
    /// The unit normal, `pack4x8snorm(normal, 0)`.
    pub normal: u32,
    /// The triangle.
    pub triangle: u32,
}

impl VoxelFragment {
    /// The voxel.
    pub fn cell(&self) -> [u32; 3] {
        [
            self.coord & 1023,
            (self.coord >> 10) & 1023,
            self.coord >> 20,
        ]
    }
}

/// WGSL's `pack4x8unorm`: `floor(0.5 + 255 clamp(e, 0, 1))` per component, x in the low byte.
pub fn pack4x8unorm(v: Vec4) -> u32 {
    v.to_array().iter().enumerate().fold(0, |bits, (i, &e)| {
        bits | (((0.5 + 255.0 * e.clamp(0.0, 1.0)).floor() as u32) << (8 * i))
    })
}

/// WGSL's `pack4x8snorm`: `floor(0.5 + 127 clamp(e, -1, 1))` per component as a byte.
pub fn pack4x8snorm(v: Vec4) -> u32 {
    v.to_array().iter().enumerate().fold(0, |bits, (i, &e)| {
        let q = (0.5 + 127.0 * e.clamp(-1.0, 1.0)).floor() as i32;
        bits | (((q as u32) & 0xff) << (8 * i))
    })
}

fn separates(axis: Vec3, v: [Vec3; 3], h: f32) -> bool {
    let p = v.map(|c| axis.dot(c));
    let r = h * (axis.x.abs() + axis.y.abs() + axis.z.abs());
    p[0].min(p[1]).min(p[2]) > r || p[0].max(p[1]).max(p[2]) < -r
}

/// Whether the triangle `v` (corners relative to a box's centre) touches the cube of half side
/// `h` around the origin: Akenine-Möller's separating-axis test (the 9 edge cross products, the
/// box's 3 axes, the triangle's plane); touching counts. `voxelize.wgsl`'s test, operation for
/// operation.
pub fn triangle_box_overlap(v: [Vec3; 3], h: f32) -> bool {
    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    for e in e {
        let axes = [
            Vec3::new(0.0, -e.z, e.y),
            Vec3::new(e.z, 0.0, -e.x),
            Vec3::new(-e.y, e.x, 0.0),
        ];
        if axes.iter().any(|&a| separates(a, v, h)) {
            return false;
        }
    }
    let lo = v[0].min(v[1]).min(v[2]);
    let hi = v[0].max(v[1]).max(v[2]);
    if lo.cmpgt(Vec3::splat(h)).any() || hi.cmplt(Vec3::splat(-h)).any() {
        return false;
    }
    !separates(e[0].cross(e[1]), v, h)
}

/// Barycentric coordinates of `p`'s projection onto the plane of (`a`, `b`, `c`), clamped to the
/// triangle and renormalised (`voxelize.wgsl`: `barycentric`).
pub fn clamped_barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let w = Vec3::from(crate::direct::cpu::barycentric(p, a, b, c)).max(Vec3::ZERO);
    w / (w.x + w.y + w.z)
}

/// A triangle as the voxeliser sees it: corners where the object's motion puts them, texture
/// coordinates, material.
#[derive(Clone, Copy, Debug)]
pub struct CpuTriangle {
    /// Corners in world space.
    pub corners: [Vec3; 3],
    /// Texture coordinates of the corners.
    pub uv: [[f32; 2]; 3],
    /// Index into the materials.
    pub material: u32,
}

/// The CPU twin: every voxel of each triangle's bounds tested (no culling), the fragments in
/// sorted order.
pub fn voxelize_cpu(
    triangles: &[CpuTriangle],
    grid: &VoxelGrid,
    materials: &[GpuMaterial],
    textures: &[AlbedoTexture],
) -> Vec<VoxelFragment> {
    let r = grid.resolution as i32;
    let to_grid = 1.0 / grid.voxel;
    let mut out = Vec::new();
    for (t, tri) in triangles.iter().enumerate() {
        let [a, b, c] = tri.corners;
        let n = (b - a).cross(c - a);
        if n.dot(n) == 0.0 {
            continue;
        }
        let cell_of = |p: Vec3| {
            ((p - grid.origin) * to_grid)
                .floor()
                .as_ivec3()
                .clamp(glam::IVec3::ZERO, glam::IVec3::splat(r - 1))
        };
        let lo = cell_of(a.min(b).min(c));
        let hi = cell_of(a.max(b).max(c));
        let m = materials[tri.material as usize];
        let unit_n = n.normalize();
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let cell = [x as u32, y as u32, z as u32];
                    let centre = grid.centre(cell);
                    if !triangle_box_overlap([a - centre, b - centre, c - centre], 0.5 * grid.voxel)
                    {
                        continue;
                    }
                    let w = clamped_barycentric(centre, a, b, c);
                    let uv = [0, 1]
                        .map(|k| w.x * tri.uv[0][k] + w.y * tri.uv[1][k] + w.z * tri.uv[2][k]);
                    let mut albedo = Vec3::from(m.kd);
                    if m.texture >= 0 {
                        albedo *= textures[m.texture as usize].sample(uv);
                    }
                    out.push(VoxelFragment {
                        coord: cell[0] | (cell[1] << 10) | (cell[2] << 20),
                        albedo: pack4x8unorm(albedo.extend(1.0)),
                        normal: pack4x8snorm(unit_n.extend(0.0)),
                        triangle: t as u32,
                    });
                }
            }
        }
    }
    out.sort_unstable();
    out
}

/// `voxelize.wgsl`'s `VoxelParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct VoxelParams {
    origin: [f32; 3],
    voxel: f32,
    resolution: u32,
    triangle_count: u32,
    capacity: u32,
    tiles_per_side: u32,
}

/// The workgroups of a 1D pass over more items than one dispatch dimension holds (65,535
/// workgroups) as a 2D dispatch, each dimension at most 32,768 (`voxel.wgsl::split_groups`;
/// the pass finds its item with `split_item`).
pub fn split_groups(groups: u32) -> (u32, u32) {
    if groups == 0 {
        return (0, 1);
    }
    let x = groups.min(32768);
    (x, groups.div_ceil(x))
}

/// The voxelisation pass and its fragment list.
pub struct Voxelizer {
    /// The grid.
    pub grid: VoxelGrid,
    /// [`VoxelFragment`]s, the first `min(count, capacity)` written.
    pub fragments: wgpu::Buffer,
    /// One `u32`: the fragments the last pass found (more than the capacity when it overflowed).
    pub count: wgpu::Buffer,
    /// Fragments the list holds.
    pub capacity: u32,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    triangle_count: u32,
    tiles_per_side: u32,
}

impl Voxelizer {
    /// The pass over `scene` (its vertex buffer read as storage) into a list of `capacity`
    /// fragments on `grid`.
    ///
    /// # Errors
    /// A grid [`VoxelGrid::check`] refuses, a capacity of 0 or one beyond the device's largest
    /// storage binding, more triangles than one dispatch holds.
    pub fn new(
        device: &wgpu::Device,
        scene: &SceneGpu,
        grid: VoxelGrid,
        capacity: u32,
    ) -> Result<Self, RuntimeError> {
        grid.check()?;
        let bytes = capacity as u64 * std::mem::size_of::<VoxelFragment>() as u64;
        let limit = device.limits().max_storage_buffer_binding_size;
        if capacity == 0 || bytes > limit {
            return Err(RuntimeError::Unsupported(format!(
                "a voxel-fragment list of {capacity} fragments ({bytes} bytes); the device \
                 binds 1 to {} fragments",
                limit / std::mem::size_of::<VoxelFragment>() as u64
            )));
        }
        let triangle_count = scene.vertex_count / 3;
        // One invocation per triangle along x: a dispatch's dimension is bounded.
        let max_groups = device.limits().max_compute_workgroups_per_dimension;
        if shaders::groups_1d(triangle_count) > max_groups {
            return Err(RuntimeError::Unsupported(format!(
                "voxelising {triangle_count} triangles: the device dispatches at most {} \
                 triangles at once",
                max_groups as u64 * shaders::WORKGROUP_1D as u64
            )));
        }
        let tiles_per_side = grid.resolution.div_ceil(TILE);
        let params = VoxelParams {
            origin: grid.origin.to_array(),
            voxel: grid.voxel,
            resolution: grid.resolution,
            triangle_count,
            capacity,
            tiles_per_side,
        };
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("voxelize params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let count = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxel fragment count"),
            size: 4,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let fragments = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("voxel fragments"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let entries = [
            layout::uniform(0, c),
            layout::storage(1, true, c),
            layout::storage(2, true, c),
            layout::storage(3, true, c),
            layout::texture(4, wgpu::TextureViewDimension::D2Array, c),
            layout::storage(5, false, c),
            layout::storage(6, false, c),
        ];
        let bind_layout = layout::bind_group_layout(device, "voxelize", &entries);
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline(device, "voxelize", &module, &[&bind_layout]);
        let bind_group = layout::bind_group(
            device,
            "voxelize",
            &bind_layout,
            &[
                params.as_entire_binding(),
                scene.vertices.as_entire_binding(),
                scene.motion.as_entire_binding(),
                scene.materials.as_entire_binding(),
                wgpu::BindingResource::TextureView(&scene.albedo_view),
                count.as_entire_binding(),
                fragments.as_entire_binding(),
            ],
        );
        Ok(Self {
            grid,
            fragments,
            count,
            capacity,
            pipeline,
            bind_group,
            triangle_count,
            tiles_per_side,
        })
    }

    /// Records the pass: the count cleared, then every triangle over every tile of its
    /// footprint.
    pub fn run(&self, frame: &mut FrameEncoder) {
        frame.encoder.clear_buffer(&self.count, 0, None);
        let mut pass = frame.compute_pass("voxelize");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        let tiles = self.tiles_per_side * self.tiles_per_side;
        pass.dispatch_workgroups(shaders::groups_1d(self.triangle_count), tiles, 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn voxel_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "VoxelParams",
            size_of::<VoxelParams>(),
            &[
                ("origin", offset_of!(VoxelParams, origin)),
                ("voxel", offset_of!(VoxelParams, voxel)),
                ("resolution", offset_of!(VoxelParams, resolution)),
                ("triangle_count", offset_of!(VoxelParams, triangle_count)),
                ("capacity", offset_of!(VoxelParams, capacity)),
                ("tiles_per_side", offset_of!(VoxelParams, tiles_per_side)),
            ],
        );
        // The fragment is the `cssm::voxel` library's, parsed alone.
        let library: String = include_str!("voxel.wgsl")
            .lines()
            .filter(|l| !l.starts_with("#define_import_path"))
            .map(|l| format!("{l}\n"))
            .collect();
        let library = naga::front::wgsl::parse_str(&library).expect("voxel.wgsl parses");
        crate::shaders::tests::check_struct(
            &library,
            "VoxelFragment",
            size_of::<VoxelFragment>(),
            &[
                ("coord", offset_of!(VoxelFragment, coord)),
                ("albedo", offset_of!(VoxelFragment, albedo)),
                ("normal", offset_of!(VoxelFragment, normal)),
                ("triangle", offset_of!(VoxelFragment, triangle)),
            ],
        );
    }

    #[test]
    fn overlap_is_conservative_and_exact_on_simple_cases() {
        let h = 0.5;
        // A triangle through the box's centre, one beside it, one touching a face.
        let through = [
            Vec3::new(-2.0, -2.0, 0.0),
            Vec3::new(2.0, -2.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        ];
        assert!(triangle_box_overlap(through, h));
        let beside = through.map(|v| v + Vec3::new(0.0, 0.0, 0.6));
        assert!(!triangle_box_overlap(beside, h));
        let touching = through.map(|v| v + Vec3::new(0.0, 0.0, 0.5));
        assert!(triangle_box_overlap(touching, h));
        // Near a corner but outside along a diagonal: only the edge axes separate it.
        let diagonal = [
            Vec3::new(1.0, 0.2, -1.0),
            Vec3::new(0.2, 1.0, -1.0),
            Vec3::new(0.6, 0.6, 3.0),
        ];
        assert!(!triangle_box_overlap(diagonal, h));
    }

    /// A voxel the test accepts holds a point of the triangle; one it refuses holds none
    /// (checked by dense sampling of the triangle).
    #[test]
    fn overlap_agrees_with_sampled_points() {
        let mut rng = cssm_raycast::SplitMix64(7);
        let mut next = || rng.next_f64() as f32 * 4.0 - 2.0;
        for _ in 0..200 {
            let tri = [0; 3].map(|_| Vec3::new(next(), next(), next()));
            let inside = (0..=60).any(|i| {
                (0..=60 - i).any(|j| {
                    let (u, v) = (i as f32 / 60.0, j as f32 / 60.0);
                    let p = tri[0] + u * (tri[1] - tri[0]) + v * (tri[2] - tri[0]);
                    p.abs().max_element() <= 0.5
                })
            });
            if inside {
                assert!(triangle_box_overlap(tri, 0.5), "{tri:?}");
            }
        }
    }

    #[test]
    fn the_vertex_words_match_gpu_vertex() {
        // `voxelize.wgsl` reads the vertex buffer as 17 words per vertex.
        assert_eq!(std::mem::size_of::<crate::gpu_types::GpuVertex>(), 17 * 4);
        assert_eq!(std::mem::offset_of!(crate::gpu_types::GpuVertex, uv), 6 * 4);
        assert_eq!(
            std::mem::offset_of!(crate::gpu_types::GpuVertex, material),
            10 * 4
        );
        assert_eq!(
            std::mem::offset_of!(crate::gpu_types::GpuVertex, object),
            12 * 4
        );
    }

    #[test]
    fn packing_matches_wgsl() {
        assert_eq!(pack4x8unorm(Vec4::new(0.0, 1.0, 0.5, 2.0)), 0xff_80_ff_00);
        assert_eq!(pack4x8snorm(Vec4::new(1.0, -1.0, 0.0, 0.0)), 0x00_00_81_7f);
    }

    #[test]
    fn split_dispatches_cover_every_group_within_the_limit() {
        assert_eq!(split_groups(0), (0, 1));
        assert_eq!(split_groups(5), (5, 1));
        assert_eq!(split_groups(32768), (32768, 1));
        assert_eq!(split_groups(32769), (32768, 2));
        let (x, y) = split_groups(1 << 24);
        assert!(x as u64 * y as u64 >= 1 << 24 && x <= 65535 && y <= 65535);
    }

    #[test]
    fn the_grid_holds_the_bounds_inside_voxels() {
        let grid = VoxelGrid::of_scene((Vec3::ZERO, Vec3::new(4.0, 2.0, 1.0)), 5);
        assert_eq!(grid.voxel, 1.0);
        // The box's faces at x = 0 and x = 4 lie at the centres of voxels 0 and 4.
        assert_eq!(grid.centre([0, 0, 0]).x, 0.0);
        assert_eq!(grid.centre([4, 0, 0]).x, 4.0);
        assert!(
            VoxelGrid {
                resolution: 2048,
                ..grid
            }
            .check()
            .is_err()
        );
    }
}
