//! Indirect light from the atlas (§4.4 "direct visualisation", §5 view-dependent lightmap,
//! Fig. 17): the radiosity iteration's indirect irradiance per texel, looked up per pixel at
//! its atlas coordinates (`lookup.wgsl`), nearest texel ([`Filter::Nearest`], `--method hrc`) or
//! a bicubic B-spline ([`Filter::Bicubic`], `--method lightmap`), and reflected with the
//! pixel's albedo. Only the direct light is computed per pixel; the indirect light costs one
//! iteration over the atlas, independent of the image size.
//!
//! CPU twin: [`lookup`] (test `lightmap_lookup_matches_cpu_twin`).

use cssm_formats::visibility::VisibilityQuery;
use glam::{Vec2, Vec3};
use wgpu::util::DeviceExt;

use crate::{
    common::{gbuffer::GBuffer, layout, timestamps::PassTimer},
    load::CssmGpu,
    visibility::library_wgsl,
};

/// How the atlas is filtered at a pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    /// The texel under the pixel.
    Nearest = 0,
    /// Cubic B-spline over the 4x4 texels around it, within its chart.
    Bicubic = 1,
}

/// Uniform cubic B-spline weights of the samples at -1, 0, 1, 2 for the fraction `t`
/// (`lookup.wgsl`: `bspline_weights`).
pub fn bspline_weights(t: f32) -> [f32; 4] {
    let (t2, s) = (t * t, 1.0 - t);
    let t3 = t2 * t;
    [
        s * s * s / 6.0,
        (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
        t3 / 6.0,
    ]
}

/// `lookup.wgsl::lookup`: the irradiance at atlas coordinates `p` (texels) from the
/// per-texel `irradiance`.
pub fn lookup(query: &VisibilityQuery, irradiance: &[Vec3], p: Vec2, filter: Filter) -> Vec3 {
    let Some(centre) = query.texel_at_point(p) else {
        return Vec3::ZERO;
    };
    if filter == Filter::Nearest {
        return irradiance[centre as usize];
    }
    let texels = &query.file().texels;
    let chart = texels[centre as usize].chart;
    let f = p - Vec2::splat(0.5);
    let base = f.floor();
    let t = f - base;
    let (wx, wy) = (bspline_weights(t.x), bspline_weights(t.y));
    let (mut sum, mut total) = (Vec3::ZERO, 0.0);
    for (j, wj) in wy.iter().enumerate() {
        for (i, wi) in wx.iter().enumerate() {
            let cell = query.cell(base.x as i64 - 1 + i as i64, base.y as i64 - 1 + j as i64);
            let Some(cell) = cell.filter(|&c| texels[c as usize].chart == chart) else {
                continue;
            };
            let w = wi * wj;
            sum += w * irradiance[cell as usize];
            total += w;
        }
    }
    if total <= 0.0 {
        irradiance[centre as usize]
    } else {
        sum / total
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct LookupParams {
    filter: u32,
    _pad: [u32; 3],
}

/// The lookup pass: indirect radiance per pixel into [`Self::indirect`].
pub struct AtlasLookup {
    /// Per pixel `vec4f`: rgb indirect radiance towards the eye.
    pub indirect: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

impl AtlasLookup {
    /// The pass over `gbuffer` reading `texel_irradiance` (`vec4f` per texel).
    pub fn new(
        device: &wgpu::Device,
        view: &wgpu::Buffer,
        gbuffer: &GBuffer,
        cssm: &CssmGpu,
        texel_irradiance: &wgpu::Buffer,
        filter: Filter,
    ) -> Self {
        let (w, h) = (gbuffer.position.width(), gbuffer.position.height());
        let indirect = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("atlas lookup"),
            size: 16 * (w * h) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("atlas lookup params"),
            contents: bytemuck::bytes_of(&LookupParams {
                filter: filter as u32,
                _pad: [0; 3],
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let module = layout::shader(
            device,
            "atlas lookup",
            library_wgsl(1) + include_str!("lookup.wgsl"),
        );
        let entries = [
            layout::uniform(0, c),
            layout::uniform(1, c),
            layout::storage(2, true, c),
            layout::texture(3, d2, c),
            layout::texture(4, d2, c),
            layout::texture(5, d2, c),
            layout::storage(6, false, c),
        ];
        let bind_layout = layout::bind_group_layout(device, "atlas lookup", &entries);
        let pipeline = layout::compute_pipeline(
            device,
            "atlas lookup",
            &module,
            &[&bind_layout, &cssm.bind_group_layout],
        );
        let views = [&gbuffer.position, &gbuffer.albedo, &gbuffer.atlas]
            .map(|t| t.create_view(&Default::default()));
        let mut resources = vec![
            params.as_entire_binding(),
            view.as_entire_binding(),
            texel_irradiance.as_entire_binding(),
        ];
        resources.extend(views.iter().map(wgpu::BindingResource::TextureView));
        resources.push(indirect.as_entire_binding());
        let bind_group = layout::bind_group(device, "atlas lookup", &bind_layout, &resources);
        Self {
            indirect,
            pipeline,
            bind_group,
            size: (w, h),
        }
    }

    /// Records the pass.
    pub fn run(&self, encoder: &mut wgpu::CommandEncoder, cssm: &CssmGpu, timer: &mut PassTimer) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("atlas lookup"),
            timestamp_writes: timer.compute("atlas lookup"),
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_bind_group(1, &cssm.bind_group, &[]);
        pass.dispatch_workgroups(self.size.0.div_ceil(8), self.size.1.div_ceil(8), 1);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn shader_validates_with_naga() {
        crate::tests::validate_wgsl(
            "lightmap/lookup",
            &(super::library_wgsl(1) + include_str!("lookup.wgsl")),
        );
    }

    #[test]
    fn bspline_weights_sum_to_one() {
        for k in 0..=10 {
            let w = super::bspline_weights(k as f32 / 10.0);
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            assert!(w.iter().all(|&x| x >= 0.0));
        }
    }
}
