//! Direct light from spot lights with shadow maps (§4.7), and emitted light: per pixel from the
//! G-buffer ([`ScreenDirect`], `shade.wgsl`: the lights' light reflected once plus the radiance
//! the surface emits towards the eye) and per atlas texel ([`AtlasDirect`], `atlas.wgsl`: the
//! lights' light reflected once plus the texel's emission), the radiance the indirect bounces
//! start from (§4.7: any direct light may be the radiosity's source). Both call `light.wgsl`.
//!
//! Emission is one-sided: a surface emits from its front only, the side its winding normal
//! faces (the G-buffer tells which side a pixel sees; an atlas texel is its front). The light
//! an emitter sends onto other surfaces is not direct light here: it reaches them through the
//! methods' first bounce, as a spot light's reflected light reaches the second surface.
//!
//! CPU reference: [`cpu`], the same shading with exact ray-cast shadows. The two differ only
//! at shadow edges, where the shadow map's PCF blurs what the ray cast decides sharply, and
//! where the shadow map's resolution and its normal offset move an edge by a texel; the test
//! `direct_light_matches_cpu_reference` measures the difference away from those edges.
//!
//! Parameters: shadow-map resolution ([`crate::common::shadow_map::DEFAULT_RESOLUTION`], 2048
//! texels; 1024 is enough for the Cornell box at 640x480). Fails for spot cones wider than
//! [`crate::common::shadow_map::MAX_CUTOFF_DEG`].

pub mod cpu;

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[SCREEN_SHADER, ATLAS_SHADER],
    libraries: &[crate::shaders::library!("direct/light.wgsl")],
};

use crate::{
    RuntimeError,
    common::{layout, shadow_map::ShadowMaps},
    frame::{FrameContext, FrameEncoder},
    load::{CssmGpu, SceneGpu},
    method::{Backend, Checks, Energy, GiMethod, MethodEntry, MethodSetup, Timing},
    shaders,
    visibility::moving::MovingGpu,
};

/// `direct/shade.wgsl` with `direct/light.wgsl` and the shadow lookup.
pub const SCREEN_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("direct screen", "direct/shade.wgsl");

/// `direct/atlas.wgsl` with `direct/light.wgsl` and the shadow lookup.
pub const ATLAS_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("direct atlas", "direct/atlas.wgsl");

/// `--method direct`: the shared passes alone (shadow maps, G-buffer, direct light); no
/// indirect light.
pub const METHOD: MethodEntry = MethodEntry {
    name: "direct",
    summary: "direct light from spot lights (PCF shadow maps) and emitters seen (§4.7; no indirect light)",
    needs_cssm: false,
    options: &[],
    passes: &[],
    backend: Backend::Gpu(|_: &MethodSetup| Ok(Box::new(DirectOnly))),
    checks: Checks {
        energy: Energy::NoIndirect,
        emissive: Energy::NoIndirect,
        ..Checks::DEFAULT
    },
    timing: Timing {
        about: "the baseline the other methods' rows are timed beside",
        compare_with: &[],
        rows: &[],
    },
};

/// The `direct` method: nothing beyond the shared passes.
struct DirectOnly;

impl GiMethod for DirectOnly {
    fn encode(&mut self, _: &FrameContext, _: &mut FrameEncoder) {}

    fn indirect(&self) -> Option<&wgpu::Buffer> {
        None
    }

    fn resize(&mut self, _: &FrameContext) -> Result<(), RuntimeError> {
        Ok(())
    }
}

/// Layout entries 0 to 4 of both passes: view, materials, lights, shadow maps, sampler.
pub(crate) fn light_entries() -> [wgpu::BindGroupLayoutEntry; 5] {
    let c = wgpu::ShaderStages::COMPUTE;
    [
        layout::uniform(0, c),
        layout::storage(1, true, c),
        layout::storage(2, true, c),
        layout::depth_array(3, c),
        layout::comparison_sampler(4, c),
    ]
}

pub(crate) fn light_resources<'a>(
    view: &'a wgpu::Buffer,
    scene: &'a SceneGpu,
    shadows: &'a ShadowMaps,
) -> [wgpu::BindingResource<'a>; 5] {
    [
        view.as_entire_binding(),
        scene.materials.as_entire_binding(),
        shadows.lights.as_entire_binding(),
        wgpu::BindingResource::TextureView(&shadows.view),
        wgpu::BindingResource::Sampler(&shadows.sampler),
    ]
}

/// Direct light per pixel into an `Rgba32Float` radiance texture.
pub struct ScreenDirect {
    /// Linear radiance per pixel.
    pub radiance: wgpu::Texture,
    pipeline: wgpu::ComputePipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

impl ScreenDirect {
    /// The pass shading the context's G-buffer.
    pub fn new(ctx: &FrameContext) -> Self {
        let device = &ctx.device;
        let module = SCREEN_SHADER.create(device);
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let mut entries = light_entries().to_vec();
        entries.extend([
            layout::texture(5, d2, c),
            layout::texture(6, d2, c),
            layout::texture(7, d2, c),
            layout::storage_texture(8, wgpu::TextureFormat::Rgba32Float, c),
            layout::texture(9, d2, c),
        ]);
        let bind_layout = layout::bind_group_layout(device, "direct screen", &entries);
        let pipeline = layout::compute_pipeline(device, "direct screen", &module, &[&bind_layout]);
        let (radiance, bind_group) = Self::bind(ctx, &bind_layout);
        Self {
            radiance,
            pipeline,
            bind_layout,
            bind_group,
            size: ctx.size(),
        }
    }

    /// The radiance texture of the G-buffer's size and the bind group reading that G-buffer.
    fn bind(
        ctx: &FrameContext,
        bind_layout: &wgpu::BindGroupLayout,
    ) -> (wgpu::Texture, wgpu::BindGroup) {
        let gbuffer = &ctx.gbuffer;
        let radiance =
            layout::radiance_texture(&ctx.device, "direct radiance", gbuffer.position.size());
        let views = [
            &gbuffer.position,
            &gbuffer.normal,
            &gbuffer.albedo,
            &radiance,
            &gbuffer.emission,
        ]
        .map(|t| t.create_view(&Default::default()));
        let mut resources = light_resources(&ctx.view, &ctx.scene, &ctx.shadows).to_vec();
        resources.extend(views.iter().map(wgpu::BindingResource::TextureView));
        let bind_group = layout::bind_group(&ctx.device, "direct screen", bind_layout, &resources);
        (radiance, bind_group)
    }

    /// Follows the context's new G-buffer size.
    pub fn resize(&mut self, ctx: &FrameContext) {
        (self.radiance, self.bind_group) = Self::bind(ctx, &self.bind_layout);
        self.size = ctx.size();
    }

    /// Records the pass.
    pub fn run(&self, frame: &mut FrameEncoder) {
        let mut pass = frame.compute_pass("direct light");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        let (x, y) = shaders::groups_2d(self.size);
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// Direct light into the atlas texels of a loaded CSSM: one `vec4f` per texel (rgb: diffuse
/// radiance leaving the texel's front side, its emission included), in texel order.
pub struct AtlasDirect {
    /// The radiance per texel (`STORAGE | COPY_SRC`).
    pub texel_radiance: wgpu::Buffer,
    /// Number of texels.
    pub texel_count: u32,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
}

impl AtlasDirect {
    /// The pass over the texels of `cssm`, lit by the context's lights, each texel of a moving
    /// object where `moving`'s motion puts it (§3.3).
    pub fn new(ctx: &FrameContext, cssm: &CssmGpu, moving: &MovingGpu) -> Self {
        let (device, view, scene, shadows) = (&ctx.device, &ctx.view, &ctx.scene, &ctx.shadows);
        let texel_count = cssm.params.map_count;
        let texel_radiance = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("texel radiance"),
            size: 16 * texel_count.max(1) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        // Composed for the file's moving objects: a static scene's texels read no motion.
        let module = ATLAS_SHADER.create_for_scene(device, Default::default(), moving.csm_count);
        let c = wgpu::ShaderStages::COMPUTE;
        let mut entries = light_entries().to_vec();
        entries.extend([layout::storage(5, true, c), layout::storage(6, false, c)]);
        let bind_layout = layout::bind_group_layout(device, "direct atlas", &entries);
        // Group 0 its own; with moving objects their group at MOVING_GROUP (no CSSM query in
        // between).
        let mut layouts = vec![Some(&bind_layout)];
        if moving.csm_count > 0 {
            layouts.resize(shaders::MOVING_GROUP as usize, None);
            layouts.push(Some(&moving.bind_group_layout));
        }
        let pipeline =
            layout::compute_pipeline_with_gaps(device, "direct atlas", &module, "main", &layouts);
        let mut resources = light_resources(view, scene, shadows).to_vec();
        resources.extend([
            cssm.texels.as_entire_binding(),
            texel_radiance.as_entire_binding(),
        ]);
        let bind_group = layout::bind_group(device, "direct atlas", &bind_layout, &resources);
        Self {
            texel_radiance,
            texel_count,
            pipeline,
            bind_group,
        }
    }

    /// Records the pass (`moving`: the group [`Self::new`] was built with).
    pub fn run(&self, frame: &mut FrameEncoder, moving: &MovingGpu) {
        let mut pass = frame.compute_pass("direct light into atlas");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        moving.bind(&mut pass, shaders::MOVING_GROUP);
        pass.dispatch_workgroups(shaders::groups_1d(self.texel_count), 1, 1);
    }
}
