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
    RuntimeError,
    common::converge::{BouncePlan, Convergence},
    common::layout,
    frame::{FrameContext, FrameEncoder, PassInfo, Slot, Stage},
    load::CssmGpu,
    method::{self, Backend, Checks, GiMethod, MethodEntry, MethodSetup, Resolved, Timing},
    radiosity::{self, AtlasGi, RadiosityOptions},
    shaders,
};

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[LOOKUP_SHADER],
    libraries: &[crate::shaders::library!("lightmap/bicubic.wgsl")],
};

/// `lightmap/lookup.wgsl` with the CSSM library.
pub const LOOKUP_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("atlas lookup", "lightmap/lookup.wgsl");

/// How the atlas is filtered at a pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    /// The texel under the pixel.
    Nearest = 0,
    /// Cubic B-spline over the 4x4 texels around it, within its chart.
    Bicubic = 1,
}

/// Uniform cubic B-spline weights of the samples at -1, 0, 1, 2 for the fraction `t`
/// (`bicubic.wgsl`: `bspline_weights`).
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

/// `bicubic.wgsl::atlas_lookup`: the irradiance at atlas coordinates `p` (texels) from the
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
    params: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

impl AtlasLookup {
    /// The pass over the context's G-buffer reading `texel_irradiance` (`vec4f` per texel).
    pub fn new(
        ctx: &FrameContext,
        cssm: &CssmGpu,
        texel_irradiance: &wgpu::Buffer,
        filter: Filter,
    ) -> Self {
        let device = &ctx.device;
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
        let module = LOOKUP_SHADER.create_for(device, cssm.shape());
        let entries = [
            layout::uniform(0, c),
            layout::uniform(1, c),
            // `bicubic.wgsl`'s `atlas_values`.
            layout::storage(15, true, c),
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
        let (indirect, bind_group) = Self::bind(ctx, &bind_layout, &params, texel_irradiance);
        Self {
            indirect,
            params,
            pipeline,
            bind_layout,
            bind_group,
            size: ctx.size(),
        }
    }

    /// The output of the G-buffer's size and the bind group reading that G-buffer.
    fn bind(
        ctx: &FrameContext,
        bind_layout: &wgpu::BindGroupLayout,
        params: &wgpu::Buffer,
        texel_irradiance: &wgpu::Buffer,
    ) -> (wgpu::Buffer, wgpu::BindGroup) {
        let indirect = ctx.pixel_buffer("atlas lookup");
        let gbuffer = &ctx.gbuffer;
        let views = [&gbuffer.position, &gbuffer.albedo, &gbuffer.atlas]
            .map(|t| t.create_view(&Default::default()));
        let mut resources = vec![
            (0, params.as_entire_binding()),
            (1, ctx.view.as_entire_binding()),
            (15, texel_irradiance.as_entire_binding()),
        ];
        resources.extend(
            (3..)
                .zip(&views)
                .map(|(binding, view)| (binding, wgpu::BindingResource::TextureView(view))),
        );
        resources.push((6, indirect.as_entire_binding()));
        let bind_group =
            layout::bind_group_at(&ctx.device, "atlas lookup", bind_layout, &resources);
        (indirect, bind_group)
    }

    /// Follows the context's new G-buffer size.
    pub fn resize(&mut self, ctx: &FrameContext, texel_irradiance: &wgpu::Buffer) {
        (self.indirect, self.bind_group) =
            Self::bind(ctx, &self.bind_layout, &self.params, texel_irradiance);
        self.size = ctx.size();
    }

    /// Records the pass.
    pub fn run(&self, frame: &mut FrameEncoder, cssm: &CssmGpu) {
        let mut pass = frame.compute_pass("atlas lookup");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_bind_group(1, &cssm.bind_group, &[]);
        let (x, y) = shaders::groups_2d(self.size);
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// The passes of `hrc` and `lightmap`.
const PASSES: &[PassInfo] = &[
    radiosity::PREPARE_PASSES[0],
    radiosity::PREPARE_PASSES[1],
    radiosity::PREPARE_PASSES[2],
    radiosity::PREPARE_PASSES[3],
    radiosity::PREPARE_PASSES[4],
    radiosity::PREPARE_PASSES[5],
    PassInfo {
        name: "atlas lookup",
        stage: Stage::Frame,
        reads: &[Slot::Cssm, Slot::GBuffer, Slot::TexelIrradiance, Slot::View],
        writes: &[Slot::Indirect],
    },
];

/// `--method hrc`: hierarchical radiosity shown directly, each pixel its texel's indirect light.
pub const HRC: MethodEntry = MethodEntry {
    name: "hrc",
    summary: "GPU hierarchical radiosity over the atlas, each pixel showing its texel (§4.1-4.3)",
    needs_cssm: true,
    options: &[method::BOUNCES, method::THRESHOLD, method::LINKS],
    passes: PASSES,
    backend: Backend::Gpu(|setup| AtlasGiLookup::build(setup, Filter::Nearest)),
    checks: Checks::DEFAULT,
    timing: Timing::PER_BAKE,
};

/// `--method lightmap`: hierarchical radiosity looked up per pixel with a bicubic B-spline.
pub const LIGHTMAP: MethodEntry = MethodEntry {
    name: "lightmap",
    summary: "hierarchical radiosity looked up per pixel with a bicubic filter (§5, Fig. 17)",
    needs_cssm: true,
    options: &[method::BOUNCES, method::THRESHOLD, method::LINKS],
    passes: PASSES,
    backend: Backend::Gpu(|setup| AtlasGiLookup::build(setup, Filter::Bicubic)),
    checks: Checks::DEFAULT,
    timing: Timing::PER_BAKE,
};

/// The options of `hrc` and `lightmap`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookupOptions {
    /// Radiosity iterations (indirect bounces; 0: until converged).
    pub bounces: u32,
    /// Oracle threshold (§4.3).
    pub threshold: f32,
    /// Bounces multiply the cached links once built (`links=cached`).
    pub links: bool,
}

impl LookupOptions {
    /// The typed form of checked options.
    pub fn from_resolved(options: &Resolved) -> Self {
        Self {
            bounces: options.count("bounces"),
            threshold: options.number("threshold"),
            links: options.choice("links") == "cached",
        }
    }
}

/// `hrc` and `lightmap`: the radiosity solution once per light change, looked up every frame.
struct AtlasGiLookup {
    gi: AtlasGi,
    lookup: AtlasLookup,
}

impl AtlasGiLookup {
    fn build(setup: &MethodSetup, filter: Filter) -> Result<Box<dyn GiMethod>, RuntimeError> {
        let ctx = setup.ctx;
        let options = LookupOptions::from_resolved(setup.options);
        let file = setup.cssm_file()?;
        let radiosity_options = RadiosityOptions {
            threshold: options.threshold,
            exposure: ctx.settings.exposure,
        };
        let plan = BouncePlan::from_option(options.bounces);
        let mut gi = AtlasGi::new(ctx, file, radiosity_options, plan)?;
        if !options.links {
            gi.radiosity.walk_always();
        }
        let lookup = AtlasLookup::new(
            ctx,
            &ctx.cssm()?.query,
            &gi.radiosity.texel_irradiance,
            filter,
        );
        Ok(Box::new(Self { gi, lookup }))
    }
}

impl GiMethod for AtlasGiLookup {
    fn prepare(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.gi.run(ctx, frame);
    }

    fn encode(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        if let Some(cssm) = &ctx.cssm {
            self.lookup.run(frame, &cssm.query);
        }
    }

    fn indirect(&self) -> Option<&wgpu::Buffer> {
        Some(&self.lookup.indirect)
    }

    fn resize(&mut self, ctx: &FrameContext) -> Result<(), RuntimeError> {
        self.lookup.resize(ctx, &self.gi.radiosity.texel_irradiance);
        Ok(())
    }

    fn convergence(&self, ctx: &FrameContext) -> Option<Result<Convergence, RuntimeError>> {
        Some(self.gi.radiosity.convergence(&ctx.device, &ctx.queue))
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn lookup_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::LOOKUP_SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "LookupParams",
            size_of::<super::LookupParams>(),
            &[("mode", offset_of!(super::LookupParams, filter))],
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
