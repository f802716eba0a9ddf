//! Final gathering per pixel with simplified GPU lightcuts (§4.4.1, §4.5): the hierarchy's
//! nodes, lit by the radiosity iteration ([`crate::radiosity`]), are VPLs; every pixel of the
//! G-buffer walks the tree like a receiver leaf, the oracle bounding the Phong BRDF, and
//! gathers the glossy last bounce towards the eye (`final_gather.wgsl`). With jittering, each
//! frame picks a random texel of every node of the cut and the frames are averaged.
//!
//! CPU twin: [`cpu::gather_pixel`] (test `final_gather_matches_cpu_twin`).

pub mod cpu;

use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::layout,
    frame::{FrameContext, FrameEncoder, PassInfo, Slot, Stage},
    gpu_types::GpuTraversalParams,
    method::{self, Backend, Checks, Energy, GiMethod, MethodEntry, MethodSetup, OptionKind, OptionSpec, Resolved},
    radiosity::{self, AtlasGi, RadiosityOptions},
    shaders::{self, Shader},
};

/// The final-gather pass: indirect radiance per pixel into [`Self::indirect`].
pub struct FinalGather {
    /// Per pixel `vec4f`: rgb indirect radiance (mean over the frames so far), w: cut size.
    pub indirect: wgpu::Buffer,
    params: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
    base: GpuTraversalParams,
}

impl FinalGather {
    /// The pass over the context's G-buffer, gathering from `node_radiance` (per node `vec4f`)
    /// over the context's `.cssm`.
    ///
    /// # Errors
    /// No `.cssm` in the context.
    pub fn new(
        ctx: &FrameContext,
        node_radiance: &wgpu::Buffer,
        threshold: f32,
    ) -> Result<Self, RuntimeError> {
        let device = &ctx.device;
        let cssm = ctx.cssm()?;
        let (w, h) = ctx.size();
        let base = GpuTraversalParams {
            receiver_count: w * h,
            node_count: cssm.hierarchy.node_count,
            threshold,
            exposure: ctx.settings.exposure,
            ..Default::default()
        };
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("final gather params"),
            contents: bytemuck::bytes_of(&base),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let module = Shader::FinalGather.create_for_scene(
            device,
            cssm.query.run_bindings,
            cssm.moving.csm_count,
        );
        let entries = [
            layout::uniform(0, c),
            layout::uniform(1, c),
            layout::storage(2, true, c),
            layout::storage(3, true, c),
            layout::storage(4, true, c),
            layout::storage(5, true, c),
            layout::texture(6, d2, c),
            layout::texture(7, d2, c),
            layout::texture(8, d2, c),
            layout::texture(9, d2, c),
            layout::storage(10, false, c),
        ];
        let bind_layout = layout::bind_group_layout(device, "final gather", &entries);
        let pipeline = layout::compute_pipeline(
            device,
            "final gather",
            &module,
            &cssm
                .moving
                .with_layout(&[&bind_layout, &cssm.query.bind_group_layout]),
        );
        let (indirect, bind_group) = Self::bind(ctx, &bind_layout, &params, node_radiance)?;
        Ok(Self {
            indirect,
            params,
            pipeline,
            bind_layout,
            bind_group,
            size: (w, h),
            base,
        })
    }

    /// The output of the G-buffer's size and the bind group reading that G-buffer.
    fn bind(
        ctx: &FrameContext,
        bind_layout: &wgpu::BindGroupLayout,
        params: &wgpu::Buffer,
        node_radiance: &wgpu::Buffer,
    ) -> Result<(wgpu::Buffer, wgpu::BindGroup), RuntimeError> {
        let hierarchy = &ctx.cssm()?.hierarchy;
        let indirect = ctx.pixel_buffer("final gather");
        let gbuffer = &ctx.gbuffer;
        let views = [
            &gbuffer.position,
            &gbuffer.normal,
            &gbuffer.albedo,
            &gbuffer.atlas,
        ]
        .map(|t| t.create_view(&Default::default()));
        let mut resources = vec![
            params.as_entire_binding(),
            ctx.view.as_entire_binding(),
            hierarchy.nodes.as_entire_binding(),
            hierarchy.leaves.as_entire_binding(),
            node_radiance.as_entire_binding(),
            ctx.scene.materials.as_entire_binding(),
        ];
        resources.extend(views.iter().map(wgpu::BindingResource::TextureView));
        resources.push(indirect.as_entire_binding());
        let bind_group = layout::bind_group(&ctx.device, "final gather", bind_layout, &resources);
        Ok((indirect, bind_group))
    }

    /// Follows the context's new G-buffer size.
    ///
    /// # Errors
    /// No `.cssm` in the context.
    pub fn resize(
        &mut self,
        ctx: &FrameContext,
        node_radiance: &wgpu::Buffer,
    ) -> Result<(), RuntimeError> {
        (self.indirect, self.bind_group) =
            Self::bind(ctx, &self.bind_layout, &self.params, node_radiance)?;
        self.size = ctx.size();
        self.base.receiver_count = self.size.0 * self.size.1;
        Ok(())
    }

    /// Records frame `frame.index` of the progressive average: with `jitter` every sender is a
    /// random texel of its node (seeded by the frame), else the node's representative.
    pub fn run(&self, ctx: &FrameContext, frame: &mut FrameEncoder, jitter: bool) {
        let Some(cssm) = &ctx.cssm else { return };
        let params = GpuTraversalParams {
            seed: frame_seed(frame.index),
            jitter: u32::from(jitter),
            frame: frame.index,
            ..self.base
        };
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let mut pass = frame.compute_pass("final gather");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_bind_group(1, &cssm.query.bind_group, &[]);
        cssm.moving.bind(&mut pass, 2);
        let (x, y) = shaders::groups_2d(self.size);
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// `--method lightcuts`: radiosity for all but the last bounce, then a final gather per pixel.
pub const METHOD: MethodEntry = MethodEntry {
    name: "lightcuts",
    summary: "hierarchical radiosity, then a final gather per pixel with a glossy last bounce \
              (§4.4, §4.5)",
    needs_cssm: true,
    options: &[
        method::BOUNCES,
        method::THRESHOLD,
        OptionSpec {
            name: "jitter",
            help: "every frame sends from a random point of each node of the cut (§4.5), so \
                   the frames' mean converges",
            kind: OptionKind::Switch { default: false },
        },
    ],
    passes: &[
        radiosity::PREPARE_PASSES[0],
        radiosity::PREPARE_PASSES[1],
        radiosity::PREPARE_PASSES[2],
        radiosity::PREPARE_PASSES[3],
        PassInfo {
            name: "final gather",
            stage: Stage::Frame,
            reads: &[
                Slot::Cssm,
                Slot::GBuffer,
                Slot::NodeRadiance,
                Slot::Scene,
                Slot::View,
            ],
            writes: &[Slot::Indirect],
        },
    ],
    backend: Backend::Gpu(Lightcuts::build),
    checks: Checks {
        energy: Energy::Within(0.04),
        golden_flip: 0.005,
        emissive: Energy::Within(0.04),
    },
};

/// The options of `lightcuts`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightcutsOptions {
    /// Indirect bounces: the radiosity iterates `bounces - 1` times, the final gather is the last.
    pub bounces: u32,
    /// Oracle threshold (§4.3), of the radiosity and of the final gather.
    pub threshold: f32,
    /// Jitter the senders every frame (§4.5).
    pub jitter: bool,
}

impl LightcutsOptions {
    /// The typed form of checked options.
    pub fn from_resolved(options: &Resolved) -> Self {
        Self {
            bounces: options.count("bounces"),
            threshold: options.number("threshold"),
            jitter: options.switch("jitter"),
        }
    }
}

/// The `lightcuts` method.
struct Lightcuts {
    gi: AtlasGi,
    gather: FinalGather,
    iterations: u32,
    jitter: bool,
}

impl Lightcuts {
    fn build(setup: &MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError> {
        let ctx = setup.ctx;
        let options = LightcutsOptions::from_resolved(setup.options);
        let radiosity_options = RadiosityOptions {
            threshold: options.threshold,
            exposure: ctx.settings.exposure,
        };
        let gi = AtlasGi::new(ctx, setup.scene, setup.cssm_file()?, radiosity_options)?;
        let iterations = options.bounces.saturating_sub(1);
        let gather = FinalGather::new(ctx, gi.radiosity.radiance(iterations), options.threshold)?;
        Ok(Box::new(Self {
            gi,
            gather,
            iterations,
            jitter: options.jitter,
        }))
    }
}

impl GiMethod for Lightcuts {
    fn prepare(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.gi.run(ctx, frame, self.iterations);
    }

    fn encode(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.gather.run(ctx, frame, self.jitter);
    }

    fn indirect(&self) -> Option<&wgpu::Buffer> {
        Some(&self.gather.indirect)
    }

    fn resize(&mut self, ctx: &FrameContext) -> Result<(), RuntimeError> {
        let radiance = self.gi.radiosity.radiance(self.iterations);
        self.gather.resize(ctx, radiance)
    }
}

/// The seed of frame `frame`'s jitter (what [`FinalGather::run`] uploads).
pub fn frame_seed(frame: u32) -> u32 {
    crate::radiosity::transfer::pcg_hash(frame.wrapping_add(0x9e37_79b9))
}
