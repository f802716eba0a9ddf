//! Point proxies and their voxel grid (Chen et al. 2014 §3.1).
//!
//! Placement ([`place_proxies`], on the CPU when the scene loads): the scene is sampled
//! uniformly by area. Each triangle expects `area * density` proxies; it gets the whole part,
//! and one more when a hash of its centroid falls below the fraction (the paper's Russian
//! roulette, so that a triangle smaller than one proxy's share is sampled with a probability
//! proportional to its area instead of always or never). A proxy's barycentrics are the next
//! pair of a Halton sequence in bases 2 and 3 over all proxies (folded into the triangle), and
//! its disc has the area each proxy stands for, `1 / density`.
//!
//! Every frame ([`ProxyGrid::run`], `proxies.wgsl`): each proxy moved with its object, its
//! voxel's key by Eq. 1, `H(v) = v.z D_x D_y + v.y D_x + v.x` ("proxy hash"); the pairs (key,
//! proxy) sorted by key (`common::sort`, "proxy sort"); each voxel's range in the sorted list
//! ("proxy cells"). CPU twins: [`hash_cpu`], [`cells_cpu`]; test `tests/gpu/vf.rs`.

use cssm_formats::Scene;
use cssm_raycast::SplitMix64;
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{
        layout,
        sort::{KeySort, KeyValue, key_bits},
    },
    frame::FrameEncoder,
    shaders,
};

/// `vf/proxies.wgsl`: the point proxies' voxel keys (`hash`) and each voxel's range of the sorted
/// proxies (`cell_ranges`).
pub const SHADER: crate::shaders::Shader = crate::shaders::shader!("vf proxies", "vf/proxies.wgsl");

/// Most proxies.
pub const MAX_PROXIES: u32 = 1 << 24;

/// Most voxels per side.
pub const MAX_RESOLUTION: u32 = 256;

/// A point proxy as the GPU reads it (`proxies.wgsl`: `Proxy`), in the space of its object as
/// loaded.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Proxy {
    /// Centre of the disc.
    pub position: [f32; 3],
    /// Radius of the disc.
    pub radius: f32,
    /// Unit normal of its triangle.
    pub normal: [f32; 3],
    /// Its triangle.
    pub triangle: u32,
    /// Its object (`Scene::objects`), whose motion moves it.
    pub object: u32,
    /// Its triangle's material.
    pub material: u32,
    /// Texture coordinates (0 where the scene has none).
    pub uv: [f32; 2],
}

/// The radical inverse of `index` in `base`: the Halton sequence.
pub fn halton(mut index: u32, base: u32) -> f32 {
    let (mut result, mut fraction) = (0.0f64, 1.0f64);
    while index > 0 {
        fraction /= f64::from(base);
        result += fraction * f64::from(index % base);
        index /= base;
    }
    result as f32
}

/// A number in [0, 1) from a position: the Russian roulette's hash of a triangle's centroid.
fn position_hash(p: Vec3) -> f64 {
    let bits = u64::from(p.x.to_bits())
        ^ u64::from(p.y.to_bits()).rotate_left(21)
        ^ u64::from(p.z.to_bits()).rotate_left(42);
    SplitMix64(bits).next_f64()
}

/// About `target` proxies spread uniformly by area over `scene`'s triangles (see the module
/// docs); deterministic.
///
/// # Errors
/// A target of 0 or above [`MAX_PROXIES`], or a scene without area.
pub fn place_proxies(scene: &Scene, target: u32) -> Result<Vec<Proxy>, RuntimeError> {
    if target == 0 || target > MAX_PROXIES {
        return Err(RuntimeError::Unsupported(format!(
            "{target} proxies: 1 to {MAX_PROXIES}"
        )));
    }
    let areas: Vec<f64> = (0..scene.triangles.len())
        .map(|t| {
            let [a, b, c] = scene.triangle(t);
            0.5 * f64::from((b - a).cross(c - a).length())
        })
        .collect();
    let total: f64 = areas.iter().sum();
    if !(total.is_finite() && total > 0.0) {
        return Err(RuntimeError::Unsupported(format!(
            "scene '{}' has no surface area to place proxies on",
            scene.name
        )));
    }
    let density = f64::from(target) / total;
    let radius = (1.0 / (std::f64::consts::PI * density)).sqrt() as f32;
    let mut proxies = Vec::new();
    for (t, &area) in areas.iter().enumerate() {
        let [a, b, c] = scene.triangle(t);
        let expected = area * density;
        let extra = position_hash((a + b + c) / 3.0) < expected.fract();
        let count = expected.floor() as usize + usize::from(extra);
        let normal = (b - a).cross(c - a).normalize_or_zero();
        let corners = scene.triangles[t].map(|v| {
            scene
                .texcoords
                .get(v as usize)
                .map_or(glam::Vec2::ZERO, |&uv| uv.into())
        });
        for _ in 0..count {
            if proxies.len() as u32 >= MAX_PROXIES {
                break;
            }
            let index = proxies.len() as u32 + 1;
            let (mut u, mut v) = (halton(index, 2), halton(index, 3));
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let uv = corners[0] + u * (corners[1] - corners[0]) + v * (corners[2] - corners[0]);
            proxies.push(Proxy {
                position: (a + u * (b - a) + v * (c - a)).to_array(),
                radius,
                normal: normal.to_array(),
                triangle: t as u32,
                object: scene.object_of(t) as u32,
                material: scene.triangle_materials[t],
                uv: uv.to_array(),
            });
        }
    }
    Ok(proxies)
}

/// The voxel grid over the scene (`proxies.wgsl`: `GridParams`): cubic cells of side `cell`
/// from `lo`, `dims` per axis.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GridParams {
    /// The grid's low corner.
    pub lo: [f32; 3],
    /// Side of a cell.
    pub cell: f32,
    /// Cells per axis.
    pub dims: [u32; 3],
    /// Proxies.
    pub count: u32,
}

impl GridParams {
    /// `resolution` cells along the longest side of `(lo, hi)`, as many of the same size as
    /// cover the other sides, for `count` proxies.
    pub fn new((lo, hi): (Vec3, Vec3), resolution: u32, count: u32) -> Self {
        let extent = (hi - lo).max(Vec3::splat(1e-6));
        let cell = extent.max_element() / resolution as f32;
        let dims = (extent / cell)
            .ceil()
            .as_uvec3()
            .clamp(glam::UVec3::ONE, glam::UVec3::splat(resolution));
        Self {
            lo: lo.to_array(),
            cell,
            dims: dims.to_array(),
            count,
        }
    }

    /// Cells in all.
    pub fn cells(&self) -> u32 {
        self.dims.iter().product()
    }

    /// The key of the cell holding `p` by Eq. 1 (outside points clamped to the border cells).
    pub fn key(&self, p: Vec3) -> u32 {
        let dims = glam::UVec3::from(self.dims);
        let v = ((p - Vec3::from(self.lo)) / self.cell)
            .floor()
            .max(Vec3::ZERO)
            .as_uvec3()
            .min(dims - 1);
        v.z * dims.x * dims.y + v.y * dims.x + v.x
    }
}

/// CPU twin of "proxy hash": per proxy its key and index, each proxy moved by its object's
/// `motion`.
pub fn hash_cpu(proxies: &[Proxy], motion: &[Mat4], grid: &GridParams) -> Vec<KeyValue> {
    proxies
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let world = motion[p.object as usize].transform_point3(Vec3::from(p.position));
            KeyValue::new(grid.key(world), i as u32)
        })
        .collect()
}

/// CPU twin of "proxy cells": per cell the range `start..end` of its proxies in the sorted
/// pairs (`0..0` for an empty cell).
pub fn cells_cpu(sorted: &[KeyValue], cells: u32) -> Vec<[u32; 2]> {
    let mut ranges = vec![[0u32; 2]; cells as usize];
    for (i, pair) in sorted.iter().enumerate() {
        let range = &mut ranges[pair.key as usize];
        if i == 0 || sorted[i - 1].key != pair.key {
            range[0] = i as u32;
        }
        range[1] = i as u32 + 1;
    }
    ranges
}

/// The proxies on the GPU and the passes that hash, sort and index them.
pub struct ProxyGrid {
    /// The grid.
    pub grid: GridParams,
    /// The proxies ([`Proxy`]).
    pub proxies: wgpu::Buffer,
    /// (key, proxy) per proxy, as hashed.
    pub pairs: wgpu::Buffer,
    /// The pairs sorted by key.
    pub sorted: wgpu::Buffer,
    /// Per cell `[start, end)` in `sorted`.
    pub cells: wgpu::Buffer,
    /// [`GridParams`] as a uniform.
    pub params: wgpu::Buffer,
    sort: KeySort,
    hash: wgpu::ComputePipeline,
    ranges: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
}

impl ProxyGrid {
    /// `proxies` over a grid of `resolution` cells along the longest side of `bounds`, the
    /// objects' motion read from `motion` (`SceneGpu::motion`).
    ///
    /// # Errors
    /// No proxy, a resolution outside 1 to [`MAX_RESOLUTION`].
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        proxies: &[Proxy],
        bounds: (Vec3, Vec3),
        resolution: u32,
        motion: &wgpu::Buffer,
    ) -> Result<Self, RuntimeError> {
        if proxies.is_empty() {
            return Err(RuntimeError::Unsupported("a proxy grid of no proxy".into()));
        }
        if !(1..=MAX_RESOLUTION).contains(&resolution) {
            return Err(RuntimeError::Unsupported(format!(
                "proxy grid resolution {resolution}: 1 to {MAX_RESOLUTION}"
            )));
        }
        let grid = GridParams::new(bounds, resolution, proxies.len() as u32);
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let proxy_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("proxies"),
            contents: bytemuck::cast_slice(proxies),
            usage: storage,
        });
        let pair_bytes = 8 * u64::from(grid.count);
        let buffer = |label, size: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: storage | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let pairs = buffer("proxy pairs", pair_bytes);
        let sorted = buffer("proxy pairs sorted", pair_bytes);
        let cells = buffer("proxy cells", 8 * u64::from(grid.cells()));
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("proxy grid"),
            contents: bytemuck::bytes_of(&grid),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let bind_layout = layout::bind_group_layout(
            device,
            "proxy grid",
            &[
                layout::uniform(0, c),
                layout::storage(1, true, c),
                layout::storage(2, true, c),
                layout::storage(3, false, c),
                layout::storage(4, false, c),
                layout::storage(5, false, c),
            ],
        );
        let bind_group = layout::bind_group(
            device,
            "proxy grid",
            &bind_layout,
            &[
                params.as_entire_binding(),
                proxy_buffer.as_entire_binding(),
                motion.as_entire_binding(),
                pairs.as_entire_binding(),
                sorted.as_entire_binding(),
                cells.as_entire_binding(),
            ],
        );
        let module = SHADER.create(device);
        let pipeline = |label, entry| {
            layout::compute_pipeline_entry(device, label, &module, entry, &[&bind_layout])
        };
        Ok(Self {
            grid,
            proxies: proxy_buffer,
            pairs,
            sorted,
            cells,
            params,
            sort: KeySort::new(device, queue),
            hash: pipeline("proxy hash", "hash"),
            ranges: pipeline("proxy cells", "cell_ranges"),
            bind_group,
        })
    }

    /// Records the sort once into an encoder that is dropped, so that its workspace for
    /// this many proxies exists before the first frame.
    ///
    /// # Errors
    /// The sort's ([`KeySort::record`]).
    pub fn reserve(&mut self, device: &wgpu::Device) -> Result<(), RuntimeError> {
        let mut encoder = device.create_command_encoder(&Default::default());
        self.sort.record(
            &mut encoder,
            &self.pairs,
            &self.sorted,
            self.grid.count,
            key_bits(self.grid.cells()),
        )
    }

    /// Records the hash, the sort and the cells' ranges.
    ///
    /// # Errors
    /// The sort's ([`KeySort::record`]).
    pub fn run(&mut self, frame: &mut FrameEncoder) -> Result<(), RuntimeError> {
        let groups = shaders::groups_1d(self.grid.count);
        {
            let mut pass = frame.compute_pass("proxy hash");
            pass.set_pipeline(&self.hash);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.dispatch_workgroups(groups, 1, 1);
        }
        self.sort.record(
            frame.encoder,
            &self.pairs,
            &self.sorted,
            self.grid.count,
            key_bits(self.grid.cells()),
        )?;
        frame.encoder.clear_buffer(&self.cells, 0, None);
        let mut pass = frame.compute_pass("proxy cells");
        pass.set_pipeline(&self.ranges);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.dispatch_workgroups(groups, 1, 1);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proxy_and_grid_layouts_match_wgsl() {
        use std::mem::{offset_of, size_of};
        // The library alone, without the line naga_oil reads (composition renames its types).
        let source: String = include_str!("proxy.wgsl")
            .lines()
            .filter(|l| !l.starts_with("#define_import_path"))
            .map(|l| format!("{l}\n"))
            .collect();
        let module = naga::front::wgsl::parse_str(&source).expect("proxy.wgsl parses");
        crate::shaders::tests::check_struct(
            &module,
            "Proxy",
            size_of::<Proxy>(),
            &[
                ("position", offset_of!(Proxy, position)),
                ("radius", offset_of!(Proxy, radius)),
                ("normal", offset_of!(Proxy, normal)),
                ("triangle", offset_of!(Proxy, triangle)),
                ("object", offset_of!(Proxy, object)),
                ("material", offset_of!(Proxy, material)),
                ("uv", offset_of!(Proxy, uv)),
            ],
        );
        crate::shaders::tests::check_struct(
            &module,
            "GridParams",
            size_of::<GridParams>(),
            &[
                ("lo", offset_of!(GridParams, lo)),
                ("cell", offset_of!(GridParams, cell)),
                ("dims", offset_of!(GridParams, dims)),
                ("count", offset_of!(GridParams, count)),
            ],
        );
    }

    fn cornell() -> Scene {
        Scene::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenes/cornell-box").as_ref())
            .expect("Cornell box")
    }

    /// About the target in all, on their triangles, every triangle's count within one of its
    /// share, the same result twice.
    #[test]
    fn proxies_spread_by_area() {
        let scene = cornell();
        let proxies = place_proxies(&scene, 4096).unwrap();
        assert_eq!(proxies, place_proxies(&scene, 4096).unwrap());
        let n = proxies.len() as f64;
        assert!((n / 4096.0 - 1.0).abs() < 0.01, "{n} proxies");
        let total: f64 = (0..scene.triangles.len())
            .map(|t| {
                let [a, b, c] = scene.triangle(t);
                0.5 * f64::from((b - a).cross(c - a).length())
            })
            .sum();
        for t in 0..scene.triangles.len() {
            let [a, b, c] = scene.triangle(t);
            let area = 0.5 * f64::from((b - a).cross(c - a).length());
            let on: Vec<&Proxy> = proxies.iter().filter(|p| p.triangle == t as u32).collect();
            let share = area / total * 4096.0;
            assert!(
                (on.len() as f64 - share).abs() <= 1.0,
                "triangle {t}: {} for {share}",
                on.len()
            );
            for p in on {
                let q = Vec3::from(p.position);
                let w = crate::direct::cpu::barycentric(q, a, b, c);
                assert!(w.iter().all(|&x| x > -1e-4), "triangle {t}: {w:?}");
            }
        }
        let disc = std::f64::consts::PI * f64::from(proxies[0].radius).powi(2);
        assert!(
            (disc * 4096.0 / total - 1.0).abs() < 1e-3,
            "a disc is each proxy's share"
        );
    }

    /// Triangles far smaller than one proxy's share: the roulette samples about the expected
    /// number, not all of them or none.
    #[test]
    fn small_triangles_are_sampled_by_area() {
        let mut scene = cornell();
        // The same surface cut into slivers: each triangle of the box split 64 ways along a fan.
        let mut positions = scene.positions.clone();
        let mut triangles = Vec::new();
        let mut materials = Vec::new();
        for (t, &[a, b, c]) in scene.triangles.iter().enumerate() {
            let (pb, pc) = (scene.positions[b as usize], scene.positions[c as usize]);
            let first = positions.len() as u32;
            for k in 0..=64 {
                positions.push(pb.lerp(pc, k as f32 / 64.0));
            }
            for k in 0..64 {
                triangles.push([a, first + k, first + k + 1]);
                materials.push(scene.triangle_materials[t]);
            }
        }
        scene.positions = positions;
        scene.triangles = triangles;
        scene.triangle_materials = materials;
        scene.objects = vec![cssm_formats::scene::SceneObject {
            triangles: 0..scene.triangles.len() as u32,
            ..scene.objects[0].clone()
        }];
        let proxies = place_proxies(&scene, 256).unwrap();
        let n = proxies.len() as f64;
        // 256 expected over 2,304 slivers, each of about a ninth of a proxy's share.
        assert!((n / 256.0 - 1.0).abs() < 0.2, "{n} proxies");
        assert!(place_proxies(&scene, 0).is_err());
    }

    #[test]
    fn halton_is_the_radical_inverse() {
        assert_eq!(halton(1, 2), 0.5);
        assert_eq!(halton(2, 2), 0.25);
        assert_eq!(halton(3, 2), 0.75);
        assert!((halton(1, 3) - 1.0 / 3.0).abs() < 1e-7);
        assert!((halton(5, 3) - 7.0 / 9.0).abs() < 1e-7);
    }

    #[test]
    fn keys_follow_eq_1_and_clamp_to_the_grid() {
        let grid = GridParams::new((Vec3::ZERO, Vec3::new(4.0, 2.0, 1.0)), 4, 1);
        assert_eq!(grid.dims, [4, 2, 1]);
        assert_eq!(grid.cell, 1.0);
        assert_eq!(grid.key(Vec3::new(0.5, 0.5, 0.5)), 0);
        assert_eq!(grid.key(Vec3::new(3.5, 1.5, 0.5)), 4 + 3);
        assert_eq!(grid.key(Vec3::new(-9.0, 9.0, 9.0)), 4);
        assert_eq!(grid.cells(), 8);
        let sorted = [
            KeyValue::new(0, 5),
            KeyValue::new(0, 2),
            KeyValue::new(3, 1),
        ];
        assert_eq!(cells_cpu(&sorted, 4), vec![[0, 2], [0, 0], [0, 0], [2, 3]]);
    }
}
