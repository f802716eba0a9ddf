//! Indirect energy gathering (Chen et al. 2014 §3.3, Eq. 5-7; `gather.wgsl`) at a resolution
//! between the marching one and the G-buffer's (the paper: marching 64² or 128², gathering
//! 256², the image 512²).
//!
//! Per gathering pixel (the G-buffer at its representative): the filtered lists of the four
//! marching pixels around it, each weighted by the shared up-sampling's weights (bilinear
//! `w_l` times the joint bilateral `w_G` of depth and normal, normalised, Eq. 5, with the
//! normalisation standing for `1 / N_c`); a voxel in several lists counts with their summed
//! weight. A voxel's light (Eq. 6): within `range` of its VPLs' centroid, each of its VPLs as a
//! point of intensity `flux / pi cos_s` (its disc's area over pi added to the squared distance:
//! the form factor of a disc, bounded next to the receiver), beyond it the voxel's order-0/1
//! spherical harmonics of that intensity from the centroid. The pixel keeps the diffuse
//! irradiance and the irradiance weighted by its specular weight (the normalised Phong lobe,
//! or Eq. 7's Gaussian when `sigma` > 0), which the shared filters bring to full resolution
//! and `common::resolve` reflects with the albedo and Ks. Light inside a voxel the lists call
//! visible is not shadowed further: visibility is the voxels'.
//!
//! CPU twin: [`gather_cpu`]; test `tests/gpu/vf.rs::gathering_matches_cpu_twin`.

use glam::{Vec3, Vec4};
use wgpu::util::DeviceExt;

use super::{filter::VisibilityFilter, light::ProxyLight, march::SparseRays, proxies::ProxyGrid};
use crate::{
    common::{filters, layout},
    frame::{FrameContext, FrameEncoder},
    shaders,
};

/// `vf/gather.wgsl` with `common/bilateral.wgsl`: the weighted lists' VPLs and harmonics.
pub const SHADER: crate::shaders::Shader = crate::shaders::shader!("vf gather", "vf/gather.wgsl");

/// How the pixels gather.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GatherShape {
    /// Reduction per side of the gathering resolution from the G-buffer's.
    pub factor: u32,
    /// R of Eq. 6, world units: VPLs within it, spherical harmonics beyond.
    pub range: f32,
    /// `w_G`'s depth tolerance, relative to the distance from the eye.
    pub depth_sigma: f32,
    /// `w_G`'s normal exponent.
    pub normal_power: f32,
    /// `sigma_theta` of Eq. 7; 0 for the Phong lobe.
    pub sigma: f32,
}

/// `gather.wgsl`'s `GatherParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GatherParams {
    /// The G-buffer's size.
    pub full_size: [u32; 2],
    /// The gathering resolution.
    pub size: [u32; 2],
    /// The marching resolution.
    pub march_size: [u32; 2],
    /// Reduction of the gathering resolution.
    pub factor: u32,
    /// Reduction of the marching resolution.
    pub march_factor: u32,
    /// Most voxels of a filtered list.
    pub capacity: u32,
    /// R of Eq. 6.
    pub range: f32,
    /// `w_G`'s depth tolerance.
    pub depth_sigma: f32,
    /// `w_G`'s normal exponent.
    pub normal_power: f32,
    /// `sigma_theta` of Eq. 7, 0 for the Phong lobe.
    pub sigma: f32,
    /// Padding.
    pub pad: u32,
}

/// The gathering pass, into two planes of the shared filters' input.
pub struct Gathering {
    /// The pass's parameters.
    pub params: GatherParams,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
}

impl Gathering {
    /// The pass over `filter`'s lists of `rays`' pixels, the light of `grid`'s voxels and
    /// `light`'s VPLs, into `planes` (two planes at the gathering resolution).
    pub fn new(
        ctx: &FrameContext,
        sources: (&ProxyGrid, &ProxyLight),
        (rays, filter): (&SparseRays, &VisibilityFilter),
        shape: &GatherShape,
        planes: &wgpu::Buffer,
    ) -> Self {
        let (grid, light) = sources;
        let device = &ctx.device;
        let full = ctx.size();
        let size = filters::low_size(full, shape.factor);
        let params = GatherParams {
            full_size: [full.0, full.1],
            size: [size.0, size.1],
            march_size: rays.params.low_size,
            factor: shape.factor,
            march_factor: rays.params.factor,
            capacity: filter.params.capacity,
            range: shape.range,
            depth_sigma: shape.depth_sigma,
            normal_power: shape.normal_power,
            sigma: shape.sigma,
            pad: 0,
        };
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vf gather"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let mut entries = vec![
            layout::uniform(0, c),
            layout::uniform(1, c),
            layout::uniform(2, c),
            layout::texture(3, d2, c),
            layout::texture(4, d2, c),
        ];
        entries.extend((5..13).map(|b| layout::storage(b, true, c)));
        entries.push(layout::storage(13, false, c));
        let bind_layout = layout::bind_group_layout(device, "vf gather", &entries);
        let views = [&ctx.gbuffer.position, &ctx.gbuffer.normal]
            .map(|t| t.create_view(&Default::default()));
        let bind_group = layout::bind_group(
            device,
            "vf gather",
            &bind_layout,
            &[
                uniform.as_entire_binding(),
                ctx.view.as_entire_binding(),
                grid.params.as_entire_binding(),
                wgpu::BindingResource::TextureView(&views[0]),
                wgpu::BindingResource::TextureView(&views[1]),
                ctx.scene.materials.as_entire_binding(),
                filter.lists.as_entire_binding(),
                light.position.as_entire_binding(),
                light.normal.as_entire_binding(),
                light.flux.as_entire_binding(),
                grid.sorted.as_entire_binding(),
                grid.cells.as_entire_binding(),
                light.voxel_sh.as_entire_binding(),
                planes.as_entire_binding(),
            ],
        );
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline(device, "vf gather", &module, &[&bind_layout]);
        Self {
            params,
            pipeline,
            bind_group,
        }
    }

    /// Records the gathering (timed as "vf gather").
    pub fn run(&self, frame: &mut FrameEncoder) {
        let mut pass = frame.compute_pass("vf gather");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        let (x, y) = shaders::groups_2d((self.params.size[0], self.params.size[1]));
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// What the twin reads, as the GPU has it.
pub struct GatherInputs<'a> {
    /// The pass's parameters.
    pub params: GatherParams,
    /// The eye.
    pub eye: Vec3,
    /// The G-buffer's positions (w > 0 where covered), row-major.
    pub position: &'a [Vec4],
    /// The G-buffer's normals (w the material), row-major.
    pub normal: &'a [Vec4],
    /// Ns per material.
    pub ns: &'a [f32],
    /// Per marching pixel its filtered list ([`super::filter::unpack_lists`]).
    pub lists: &'a [Vec<u32>],
    /// Per VPL position (w radius), normal (w disc area), flux.
    pub vpls: [&'a [Vec4]; 3],
    /// (key, proxy) sorted by key.
    pub sorted: &'a [[u32; 2]],
    /// Per voxel `[start, end)` of `sorted`.
    pub ranges: &'a [[u32; 2]],
    /// Per voxel [`super::light::SH_STRIDE`] `vec4f`s.
    pub voxel_sh: &'a [Vec4],
}

/// A receiver: position, normal, direction to the eye, Ns.
struct Receiver {
    x: Vec3,
    n: Vec3,
    v: Vec3,
    ns: f32,
}

fn reflect(i: Vec3, n: Vec3) -> Vec3 {
    i - 2.0 * n.dot(i) * n
}

impl GatherInputs<'_> {
    /// `gather.wgsl`: `specular`.
    fn specular(&self, r: &Receiver, l: Vec3) -> f32 {
        let c = reflect(-l, r.n).dot(r.v).max(0.0).powf(r.ns);
        let norm = (r.ns + 2.0) / (2.0 * std::f32::consts::PI);
        let sigma = self.params.sigma;
        if sigma > 0.0 {
            let g = (1.0 - c) / sigma;
            return norm * (-0.5 * g * g).exp();
        }
        norm * c
    }

    /// `gather.wgsl`: `voxel_light`.
    fn voxel_light(&self, r: &Receiver, v: u32) -> [Vec3; 2] {
        let pi = std::f32::consts::PI;
        let base = super::light::SH_STRIDE * v as usize;
        let centroid = self.voxel_sh[base + 4].truncate();
        let [position, normal, flux] = self.vpls;
        let mut out = [Vec3::ZERO; 2];
        if centroid.distance(r.x) < self.params.range {
            let [start, end] = self.ranges[v as usize];
            for pair in &self.sorted[start as usize..end as usize] {
                let i = pair[1] as usize;
                let d = position[i].truncate() - r.x;
                let d2 = d.length_squared();
                if d2 <= 0.0 {
                    continue;
                }
                let l = d / d2.sqrt();
                let sn = normal[i];
                let cosines = sn.truncate().dot(-l).max(0.0) * r.n.dot(l).max(0.0);
                if cosines <= 0.0 {
                    continue;
                }
                let e = flux[i].truncate() / pi * cosines / (d2 + sn.w / pi);
                out[0] += e;
                out[1] += e * self.specular(r, l);
            }
            return out;
        }
        let d = centroid - r.x;
        let d2 = d.length_squared();
        if d2 <= 0.0 {
            return out;
        }
        let l = d / d2.sqrt();
        let cos_r = r.n.dot(l).max(0.0);
        if cos_r > 0.0 {
            let w = -l;
            let (y0, y1) = (0.5 / pi.sqrt(), (3.0 / (4.0 * pi)).sqrt());
            let c = |k: usize| self.voxel_sh[base + k].truncate();
            let intensity =
                (y0 * c(0) + y1 * (w.y * c(1) + w.z * c(2) + w.x * c(3))).max(Vec3::ZERO);
            let e = intensity * cos_r / d2;
            out = [e, e * self.specular(r, l)];
        }
        out
    }
}

/// CPU twin of the pass at gathering pixel `pixel`: its diffuse and specular-weighted
/// irradiance.
pub fn gather_cpu(inputs: &GatherInputs, pixel: (u32, u32)) -> [Vec3; 2] {
    let p = &inputs.params;
    let full = (p.full_size[0], p.full_size[1]);
    let at = filters::representative(pixel, p.factor, full);
    let row = |(x, y): (u32, u32)| (y * full.0 + x) as usize;
    let g = inputs.position[row(at)];
    if g.w <= 0.0 {
        return [Vec3::ZERO; 2];
    }
    let gn = inputs.normal[row(at)];
    let r = Receiver {
        x: g.truncate(),
        n: gn.truncate(),
        v: (inputs.eye - g.truncate()).normalize(),
        ns: inputs.ns[gn.w as usize],
    };
    let guide = |at: (u32, u32)| {
        let (p, n) = (inputs.position[row(at)], inputs.normal[row(at)]);
        (p.w > 0.0).then(|| (inputs.eye.distance(p.truncate()), n.truncate()))
    };
    let f = p.march_factor as f32;
    let (qx, qy) = ((at.0 as f32 + 0.5) / f - 0.5, (at.1 as f32 + 0.5) / f - 0.5);
    let (bx, by) = (qx.floor(), qy.floor());
    let [mw, mh] = p.march_size;
    let mut lists: [&[u32]; 4] = [&[]; 4];
    let taps: [Option<(f32, Vec3)>; 4] = std::array::from_fn(|k| {
        let sx = (bx as i32 + (k as i32 & 1)).clamp(0, mw as i32 - 1) as u32;
        let sy = (by as i32 + (k as i32 >> 1)).clamp(0, mh as i32 - 1) as u32;
        lists[k] = &inputs.lists[(sy * mw + sx) as usize];
        guide(filters::representative((sx, sy), p.march_factor, full))
    });
    let centre = guide(at).expect("a covered pixel");
    let weights = filters::upsample_weights(
        centre,
        taps,
        (qx - bx, qy - by),
        p.depth_sigma,
        p.normal_power,
    );
    let mut voxels = std::collections::BTreeMap::<u32, f32>::new();
    for (list, &w) in lists.iter().zip(&weights) {
        if w > 0.0 {
            for &v in *list {
                *voxels.entry(v).or_default() += w;
            }
        }
    }
    let mut out = [Vec3::ZERO; 2];
    for (v, w) in voxels {
        let light = inputs.voxel_light(&r, v);
        out[0] += w * light[0];
        out[1] += w * light[1];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One VPL seen head-on and at 60° from its normal by a receiver facing it: the voxel's
    /// order-1 harmonics give 3/4 of the clamped cosine head-on and all of it at 60°, where
    /// order 0 and 1 meet the cosine (1/4 + cos/2 against cos).
    #[test]
    fn harmonics_of_one_vpl_against_the_vpl_itself() {
        use super::super::light::{Vpl, voxel_sh_cpu};
        let vpl = Vpl {
            position: Vec4::new(0.0, 0.0, 0.0, 0.01),
            normal: Vec4::new(0.0, 0.0, 1.0, 1e-6),
            flux: Vec4::new(1.0, 2.0, 3.0, 0.0),
        };
        let sorted = [[0u32, 0u32]];
        let ranges = [[0u32, 1u32]];
        let sh = voxel_sh_cpu(&[vpl], &sorted, &ranges);
        let (position, normal, flux) = ([vpl.position], [vpl.normal], [vpl.flux]);
        let ns = [1.0f32];
        let light = |range: f32, angle: f32| {
            let inputs = GatherInputs {
                params: GatherParams {
                    range,
                    ..Default::default()
                },
                eye: Vec3::ZERO,
                position: &[],
                normal: &[],
                ns: &ns,
                lists: &[],
                vpls: [&position, &normal, &flux],
                sorted: &sorted,
                ranges: &ranges,
                voxel_sh: &sh,
            };
            let at = 10.0 * Vec3::new(angle.sin(), 0.0, angle.cos());
            let r = Receiver {
                x: at,
                n: -at.normalize(),
                v: -at.normalize(),
                ns: 1.0,
            };
            inputs.voxel_light(&r, 0)[0]
        };
        let (head_on, sixty) = (0.0, std::f32::consts::FRAC_PI_3);
        let ratio = light(0.0, head_on) / light(100.0, head_on);
        assert!(
            (ratio - Vec3::splat(0.75)).abs().max_element() < 1e-4,
            "{ratio}"
        );
        let ratio = light(0.0, sixty) / light(100.0, sixty);
        assert!((ratio - Vec3::ONE).abs().max_element() < 1e-4, "{ratio}");
    }

    #[test]
    fn gather_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "GatherParams",
            size_of::<GatherParams>(),
            &[
                ("full_size", offset_of!(GatherParams, full_size)),
                ("size", offset_of!(GatherParams, size)),
                ("march_size", offset_of!(GatherParams, march_size)),
                ("factor", offset_of!(GatherParams, factor)),
                ("march_factor", offset_of!(GatherParams, march_factor)),
                ("capacity", offset_of!(GatherParams, capacity)),
                ("range", offset_of!(GatherParams, range)),
                ("depth_sigma", offset_of!(GatherParams, depth_sigma)),
                ("normal_power", offset_of!(GatherParams, normal_power)),
                ("sigma", offset_of!(GatherParams, sigma)),
                ("pad", offset_of!(GatherParams, pad)),
            ],
        );
    }
}
