//! The point proxies as virtual point lights, and each voxel's light in spherical harmonics
//! (Chen et al. 2014 §3.1, Eq. 2, 3; `light.wgsl`).
//!
//! "vpl light": each proxy, moved with its object, is lit by every spot light through its
//! shadow map; it sends from the side of its disc that sends more (surfaces are two-sided, a
//! VPL sends from one side): its flux is that side's exitance times the disc's area, the
//! exitance `albedo * E` plus, on the front side (the winding's; emission is one-sided),
//! `pi * Le` for an emitter of radiance `Le`. Emitters thus light the scene through the VPLs
//! like the lights' reflected light (§4.7 of the CSSM paper: any direct light may be the source
//! of the indirect light). "voxel sh": per voxel, over its
//! range of the sorted proxies ([`super::proxies::ProxyGrid`]), the sum of its VPLs' radiant
//! intensity `flux / pi * max(0, n.w)` projected on the real spherical harmonics of order 0
//! and 1 (the paper keeps l = 0 and 1 for distant light), and their centroid, which stands for
//! the voxel's position. The paper accumulates with atomics; a sum over the sorted range gives
//! the same in floating point, deterministically.
//!
//! CPU twins: [`vpl_cpu`] (exact shadow rays where the GPU looks the shadow map up),
//! [`voxel_sh_cpu`]; test `tests/gpu/vf.rs::vpl_light_and_voxel_sh_match_cpu_twins`.

use cssm_formats::Scene;
use cssm_raycast::SceneBvh;
use glam::{Mat4, Vec3, Vec4};

use super::proxies::{Proxy, ProxyGrid};
use crate::{
    common::layout,
    direct::{cpu as direct_cpu, light_entries, light_resources},
    frame::{FrameContext, FrameEncoder},
    gpu_types::GpuMaterial,
    load::AlbedoTexture,
    shaders,
};

/// `vf/light.wgsl`: the direct light onto the proxies, VPLs (`vpl`), and each voxel's order-0/1
/// spherical harmonics of their light (`voxel_sh_sum`).
pub const SHADER: crate::shaders::Shader = crate::shaders::shader!("vf light", "vf/light.wgsl");

/// `vec4f`s per voxel of [`ProxyLight::voxel_sh`]: four SH coefficients (rgb), the centroid.
pub const SH_STRIDE: usize = 5;

/// The VPLs and the voxels' spherical harmonics on the GPU.
pub struct ProxyLight {
    /// Per proxy: xyz world position, w disc radius.
    pub position: wgpu::Buffer,
    /// Per proxy: xyz the side it sends from, w its disc area.
    pub normal: wgpu::Buffer,
    /// Per proxy: rgb flux.
    pub flux: wgpu::Buffer,
    /// Per voxel [`SH_STRIDE`] `vec4f`s: c00, c1-1, c10, c11 (rgb), centroid (xyz) and count.
    pub voxel_sh: wgpu::Buffer,
    vpl: wgpu::ComputePipeline,
    sh: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    count: u32,
    cells: u32,
}

impl ProxyLight {
    /// The passes over `grid`'s proxies, lit by the context's lights and shadow maps.
    pub fn new(ctx: &FrameContext, grid: &ProxyGrid) -> Self {
        let device = &ctx.device;
        let c = wgpu::ShaderStages::COMPUTE;
        let mut entries = light_entries().to_vec();
        entries.extend([
            layout::uniform(5, c),
            layout::storage(6, true, c),
            layout::storage(7, true, c),
            layout::texture(8, wgpu::TextureViewDimension::D2Array, c),
            layout::storage(9, false, c),
            layout::storage(10, false, c),
            layout::storage(11, false, c),
            layout::storage(12, true, c),
            layout::storage(13, true, c),
            layout::storage(14, false, c),
        ]);
        let bind_layout = layout::bind_group_layout(device, "vpl light", &entries);
        let count = grid.grid.count;
        let cells = grid.grid.cells();
        let buffer = |label, elements: u32| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: 16 * u64::from(elements),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let position = buffer("vpl position", count);
        let normal = buffer("vpl normal", count);
        let flux = buffer("vpl flux", count);
        let voxel_sh = buffer("voxel sh", SH_STRIDE as u32 * cells);
        let mut resources = light_resources(&ctx.view, &ctx.scene, &ctx.shadows).to_vec();
        resources.extend([
            grid.params.as_entire_binding(),
            grid.proxies.as_entire_binding(),
            ctx.scene.motion.as_entire_binding(),
            wgpu::BindingResource::TextureView(&ctx.scene.albedo_view),
            position.as_entire_binding(),
            normal.as_entire_binding(),
            flux.as_entire_binding(),
            grid.sorted.as_entire_binding(),
            grid.cells.as_entire_binding(),
            voxel_sh.as_entire_binding(),
        ]);
        let bind_group = layout::bind_group(device, "vpl light", &bind_layout, &resources);
        let module = SHADER.create(device);
        let pipeline = |label, entry| {
            layout::compute_pipeline_entry(device, label, &module, entry, &[&bind_layout])
        };
        Self {
            position,
            normal,
            flux,
            voxel_sh,
            vpl: pipeline("vpl light", "vpl"),
            sh: pipeline("voxel sh", "voxel_sh_sum"),
            bind_group,
            count,
            cells,
        }
    }

    /// Records the VPLs' light, then (after the grid's sort) the voxels' harmonics.
    pub fn run(&self, frame: &mut FrameEncoder) {
        for (name, pipeline, items) in [
            ("vpl light", &self.vpl, self.count),
            ("voxel sh", &self.sh, self.cells),
        ] {
            let mut pass = frame.compute_pass(name);
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.dispatch_workgroups(shaders::groups_1d(items), 1, 1);
        }
    }
}

/// A VPL: world position (w disc radius), the side it sends from (w disc area), flux (rgb).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vpl {
    /// xyz world position, w disc radius.
    pub position: Vec4,
    /// xyz the side it sends from, w disc area.
    pub normal: Vec4,
    /// rgb flux.
    pub flux: Vec4,
}

/// CPU twin of "vpl light" with exact shadow rays (emission sampled as the GPU does).
pub fn vpl_cpu(
    scene: &Scene,
    bvh: &SceneBvh,
    materials: &[GpuMaterial],
    textures: &[AlbedoTexture],
    proxies: &[Proxy],
    motion: &[Mat4],
) -> Vec<Vpl> {
    let eps = direct_cpu::ray_epsilon(scene);
    proxies
        .iter()
        .map(|p| {
            let m = motion[p.object as usize];
            let world = m.transform_point3(Vec3::from(p.position));
            let n = m.transform_vector3(Vec3::from(p.normal)).normalize();
            let irradiance = |side: Vec3| {
                scene
                    .lights
                    .iter()
                    .filter_map(|l| direct_cpu::spot_irradiance(l, bvh, eps, world, side))
                    .map(|(e, _)| e)
                    .sum::<Vec3>()
            };
            let material = &materials[p.material as usize];
            let albedo = direct_cpu::albedo_at(scene, material, textures, p.triangle, world);
            let emission = direct_cpu::emission_at(scene, material, textures, p.triangle, world);
            let pi = std::f32::consts::PI;
            let front = albedo * irradiance(n) + pi * emission;
            let back = albedo * irradiance(-n);
            let (side, exitance) = if back.element_sum() > front.element_sum() {
                (-n, back)
            } else {
                (n, front)
            };
            let area = pi * p.radius * p.radius;
            Vpl {
                position: world.extend(p.radius),
                normal: side.extend(area),
                flux: (exitance * area).extend(0.0),
            }
        })
        .collect()
}

/// CPU twin of "voxel sh": per voxel [`SH_STRIDE`] `vec4f`s from the VPLs, the sorted pairs'
/// proxy indices and the voxels' ranges.
pub fn voxel_sh_cpu(vpls: &[Vpl], sorted: &[[u32; 2]], ranges: &[[u32; 2]]) -> Vec<Vec4> {
    let pi = std::f32::consts::PI;
    let (k0, k1) = (0.5 / pi.sqrt(), 1.0 / (3.0 * pi).sqrt());
    let mut out = Vec::with_capacity(SH_STRIDE * ranges.len());
    for &[start, end] in ranges {
        let mut c = [Vec3::ZERO; 4];
        let mut centroid = Vec3::ZERO;
        for pair in &sorted[start as usize..end as usize] {
            let v = &vpls[pair[1] as usize];
            let (flux, n) = (v.flux.truncate(), v.normal.truncate());
            c[0] += k0 * flux;
            c[1] += k1 * n.y * flux;
            c[2] += k1 * n.z * flux;
            c[3] += k1 * n.x * flux;
            centroid += v.position.truncate();
        }
        let count = (end - start) as f32;
        out.extend(c.map(|x| x.extend(0.0)));
        out.push((centroid / count.max(1.0)).extend(count));
    }
    out
}
