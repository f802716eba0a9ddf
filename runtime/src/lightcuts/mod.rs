//! Final gathering per pixel with simplified GPU lightcuts (§4.4.1, §4.5): the hierarchy's
//! nodes, lit by the radiosity iteration ([`crate::radiosity`]), are VPLs; every pixel of the
//! G-buffer walks the tree like a receiver leaf, the oracle bounding the Phong BRDF, and
//! gathers the glossy last bounce towards the eye (`final_gather.wgsl`). With jittering, each
//! frame picks a random texel of every node of the cut and the frames are averaged.
//!
//! The gather writes two planes, the irradiance and the irradiance weighted by the pixel's
//! Phong lobe, which the shared resolve (`common/resolve.rs`) reflects with the pixel's albedo
//! and Ks. With `downsample=N` it gathers at one pixel in N x N (the G-buffer at each block's
//! representative pixel, `common/lowres.wgsl`) and the shared edge-aware filters
//! (`common/filters/`) bring the planes back to full resolution, as `rsm` does (§4.5 of
//! Bang's thesis): N² times fewer gathers, the cost of the method's frame.
//!
//! CPU twin: [`cpu::gather_pixel`] (test `final_gather_matches_cpu_twin`).

pub mod cpu;
pub mod near;

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[FINAL_GATHER_SHADER],
    libraries: &[],
};

use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::converge::{BouncePlan, Convergence},
    common::{
        filters::{self, EdgeAwareFilter, FilterOptions},
        layout,
        resolve::PlaneResolve,
    },
    frame::{FrameContext, FrameEncoder, PassInfo, Slot, Stage},
    gpu_types::GpuTraversalParams,
    method::{
        self, Backend, Checks, GiMethod, MethodEntry, MethodSetup, OptionKind, OptionSpec,
        Resolved, Timing,
    },
    radiosity::{self, AtlasGi, RadiosityOptions},
    shaders,
};

/// `lightcuts/final_gather.wgsl` with the CSSM library and `radiosity/transfer.wgsl`.
pub const FINAL_GATHER_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("final gather", "lightcuts/final_gather.wgsl");

/// `final_gather.wgsl`'s `GatherGrid`: the gather's resolution and form.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuGatherGrid {
    low_size: [u32; 2],
    factor: u32,
    mode: u32,
}

/// How the final gather finds a pixel's indirect light (`gather=`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GatherForm {
    /// Every pixel walks the whole hierarchy (the paper's §4.4.1 per pixel).
    Walk = 0,
    /// The atlas's far field, gathered once per texel, looked up with the bicubic filter, plus
    /// each pixel's own near field; glossy pixels walk for their lobe.
    Atlas = 1,
}

/// The near field's reach in world units: `sizes` times the mean texel size of `hierarchy`
/// (the square root of the scene's area over its texels; the atlas's texel density is one
/// for the whole scene, so this is every chart's texel).
pub fn near_radius(hierarchy: &cssm_formats::hierarchy::Hierarchy, sizes: f32) -> f32 {
    let (Some(root), leaves) = (hierarchy.nodes.first(), hierarchy.leaf_texels.len()) else {
        return 0.0;
    };
    sizes * (root.area / leaves.max(1) as f32).sqrt()
}

/// The final-gather pass: per gather pixel (the G-buffer's, or one in `factor` x `factor`), two
/// planes of the indirect light arriving there into a planes buffer: the irradiance (w: the
/// cut size) and the irradiance weighted by the pixel's Phong lobe towards the eye.
pub struct FinalGather {
    params: wgpu::Buffer,
    grid: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    factor: u32,
    form: GatherForm,
    /// The near lists, packed (a word without lists).
    near_lists: wgpu::Buffer,
    low_size: (u32, u32),
    base: GpuTraversalParams,
}

/// The near lists of `file`'s texels for the near field of `sizes` texel sizes (`near=`), or
/// `None` for a file with moving objects, whose texels move away from where the lists were
/// made (their near fields walk the hierarchy).
pub fn near_lists(file: &cssm_formats::CssmFile, sizes: f32) -> Option<near::NearLists> {
    let radius = near_radius(&file.hierarchy, sizes);
    file.csms
        .is_empty()
        .then(|| near::NearLists::new(&file.hierarchy, &file.texels, radius, radius / sizes))
}

/// How the final gather gathers a pixel's near field.
pub struct NearSetup<'a> {
    /// The form of the gather.
    pub form: GatherForm,
    /// The near field's reach (world units; [`near_radius`]).
    pub radius: f32,
    /// The texels' near lists, or none: every near field walks the hierarchy.
    pub lists: Option<&'a near::NearLists>,
    /// Every pixel gathers the emitters' light itself, left out of the far field and the near
    /// field ([`radiosity::cpu::FarSplit::emitters_apart`]).
    pub emitters_apart: bool,
}

impl FinalGather {
    /// The pass over the context's G-buffer at one pixel in `factor` x `factor`, gathering from
    /// `sources.0` (per node `vec4f` radiance) and, in the [`GatherForm::Atlas`] form, the far
    /// field `sources.1` (per texel `vec4f`) and the near field `near` says over the context's
    /// `.cssm` into `planes` (two planes of `vec4f` at [`filters::low_size`]).
    ///
    /// # Errors
    /// No `.cssm` in the context.
    pub fn new(
        ctx: &FrameContext,
        sources: (&wgpu::Buffer, &wgpu::Buffer),
        near: &NearSetup,
        threshold: f32,
        factor: u32,
        planes: &wgpu::Buffer,
    ) -> Result<Self, RuntimeError> {
        let device = &ctx.device;
        let cssm = ctx.cssm()?;
        let low_size = filters::low_size(ctx.size(), factor);
        // Lists larger than a binding allows are left out: every near field walks instead.
        let binding = crate::load::storage_binding_bytes(&device.limits());
        let lists = near.lists.filter(|l| l.bytes() <= binding);
        let (near_margin, near_plane) = lists.map_or((0.0, 0.0), |l| (l.margin, l.plane));
        let packed = lists.map_or(vec![0], near::NearLists::packed);
        let base = GpuTraversalParams {
            receiver_count: low_size.0 * low_size.1,
            node_count: cssm.hierarchy.node_count,
            threshold,
            exposure: ctx.settings.exposure,
            near_radius: near.radius,
            near_margin,
            near_plane,
            emitters: u32::from(near.emitters_apart && near.form == GatherForm::Atlas),
            ..Default::default()
        };
        let near_lists =
            crate::load::storage_buffer(device, "near lists", bytemuck::cast_slice(&packed));
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("final gather params"),
            contents: bytemuck::bytes_of(&base),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let grid = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("final gather grid"),
            size: std::mem::size_of::<GpuGatherGrid>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let module =
            FINAL_GATHER_SHADER.create_for_scene(device, cssm.query.shape(), cssm.moving.csm_count);
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
            layout::uniform(11, c),
            layout::storage(12, true, c),
            // `lightmap/bicubic.wgsl`'s `atlas_values`: the far field.
            layout::storage(15, true, c),
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
        let bind_group = Self::bind(
            ctx,
            &bind_layout,
            [&params, &grid, &near_lists],
            sources,
            planes,
        )?;
        let gather = Self {
            params,
            grid,
            pipeline,
            bind_layout,
            bind_group,
            factor,
            form: near.form,
            near_lists,
            low_size,
            base,
        };
        gather.write_grid(ctx);
        Ok(gather)
    }

    fn write_grid(&self, ctx: &FrameContext) {
        let grid = GpuGatherGrid {
            low_size: [self.low_size.0, self.low_size.1],
            factor: self.factor,
            mode: self.form as u32,
        };
        ctx.queue
            .write_buffer(&self.grid, 0, bytemuck::bytes_of(&grid));
    }

    /// The bind group reading the context's G-buffer and writing `planes`.
    fn bind(
        ctx: &FrameContext,
        bind_layout: &wgpu::BindGroupLayout,
        [params, grid, near_lists]: [&wgpu::Buffer; 3],
        (node_radiance, far): (&wgpu::Buffer, &wgpu::Buffer),
        planes: &wgpu::Buffer,
    ) -> Result<wgpu::BindGroup, RuntimeError> {
        let hierarchy = &ctx.cssm()?.hierarchy;
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
        resources.push(planes.as_entire_binding());
        resources.push(grid.as_entire_binding());
        resources.push(near_lists.as_entire_binding());
        let mut at: Vec<(u32, wgpu::BindingResource)> = (0..).zip(resources).collect();
        at.push((15, far.as_entire_binding()));
        Ok(layout::bind_group_at(
            &ctx.device,
            "final gather",
            bind_layout,
            &at,
        ))
    }

    /// Follows the context's new G-buffer size, writing into `planes` (sized for it).
    ///
    /// # Errors
    /// No `.cssm` in the context.
    pub fn resize(
        &mut self,
        ctx: &FrameContext,
        sources: (&wgpu::Buffer, &wgpu::Buffer),
        planes: &wgpu::Buffer,
    ) -> Result<(), RuntimeError> {
        self.low_size = filters::low_size(ctx.size(), self.factor);
        self.base.receiver_count = self.low_size.0 * self.low_size.1;
        self.write_grid(ctx);
        self.bind_group = Self::bind(
            ctx,
            &self.bind_layout,
            [&self.params, &self.grid, &self.near_lists],
            sources,
            planes,
        )?;
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
        let (x, y) = shaders::groups_2d(self.low_size);
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// Where the final gather's planes go: a full-resolution planes buffer the resolve reads, or
/// the reduced-resolution input of the edge-aware filters, whose output the resolve reads.
enum Planes {
    Full(wgpu::Buffer),
    Reduced(EdgeAwareFilter),
}

impl Planes {
    fn new(ctx: &FrameContext, options: &LightcutsOptions) -> Result<Self, RuntimeError> {
        if options.downsample <= 1 {
            return Ok(Planes::Full(Self::full(ctx)));
        }
        Ok(Planes::Reduced(EdgeAwareFilter::two_planes(
            ctx,
            options.filter(),
        )?))
    }

    /// Two planes of `vec4f` at the G-buffer's size.
    fn full(ctx: &FrameContext) -> wgpu::Buffer {
        let (w, h) = ctx.size();
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("final gather planes"),
            size: 2 * 16 * u64::from(w) * u64::from(h),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        })
    }

    /// What the gather writes.
    fn gathered(&self) -> &wgpu::Buffer {
        match self {
            Planes::Full(planes) => planes,
            Planes::Reduced(filter) => filter.input(),
        }
    }

    /// What the resolve reads.
    fn resolved(&self) -> &wgpu::Buffer {
        match self {
            Planes::Full(planes) => planes,
            Planes::Reduced(filter) => filter.output(),
        }
    }

    fn run(&self, frame: &mut FrameEncoder) {
        if let Planes::Reduced(filter) = self {
            filter.run(frame);
        }
    }

    fn resize(&mut self, ctx: &FrameContext) {
        match self {
            Planes::Full(planes) => *planes = Self::full(ctx),
            Planes::Reduced(filter) => filter.resize_two_planes(ctx),
        }
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
        method::LINKS,
        OptionSpec {
            name: "gather",
            help: "atlas: each pixel looks up the far field, gathered once per texel, and \
                   gathers its own near field (glossy pixels also walk for their lobe); walk: \
                   every pixel walks the whole hierarchy",
            kind: OptionKind::Choice {
                default: "atlas",
                choices: &["atlas", "walk"],
            },
        },
        OptionSpec {
            name: "near",
            help: "reach of the near field a pixel gathers itself with gather=atlas, in texel \
                   sizes (its senders' weight falls from 1 at half the reach to 0 at it)",
            kind: OptionKind::Number {
                default: 4.0,
                min: 1.0,
            },
        },
        OptionSpec {
            name: "emitters",
            help: "with gather=atlas, where the light of emitting surfaces (MTL Ke, glTF \
                   emissive) is gathered: pixel, by every pixel (their shadows at the pixel's \
                   resolution); far, in the far field with the rest (at the texels')",
            kind: OptionKind::Choice {
                default: "pixel",
                choices: &["pixel", "far"],
            },
        },
        OptionSpec {
            name: "jitter",
            help: "every frame sends from a random point of each node of the cut (§4.5), so \
                   the frames' mean converges",
            kind: OptionKind::Switch { default: false },
        },
        // Default 2: on the Cornell boxes (plain and glossy floor) its error against the path
        // tracer is no larger than the full gather's (0.0788 against 0.0817 relative RMSE, and
        // 0.2311 against 0.2337) for a quarter of the gathers; 4 leaves the 10% target
        // (0.1067). reports/final-gather.md, "A reduced-resolution gather".
        filters::downsample_option(
            "final gather at 1/N of the resolution per side, then up-sampled by the \
                   edge-aware filters (N² times fewer gathers)",
            2,
        ),
        filters::blur_option(
            "taps on each side of the edge-aware blur of a down-sampled gather, 0 for none",
            0,
        ),
    ],
    passes: &[
        radiosity::PREPARE_PASSES[0],
        radiosity::PREPARE_PASSES[1],
        radiosity::PREPARE_PASSES[2],
        radiosity::PREPARE_PASSES[3],
        radiosity::PREPARE_PASSES[4],
        radiosity::PREPARE_PASSES[5],
        // With `gather=atlas` only: the far field walked, then (its links cached,
        // radiosity/links.rs) re-cut where stale and multiplied.
        PassInfo {
            name: "lightcuts: far field",
            stage: Stage::Prepare,
            reads: &[Slot::Cssm, Slot::TexelRadiance, Slot::NodeRadiance],
            writes: &[Slot::TexelIrradiance],
        },
        PassInfo {
            name: "lightcuts: far-field re-cut",
            stage: Stage::Prepare,
            reads: &[Slot::Cssm, Slot::NodeRadiance],
            writes: &[],
        },
        PassInfo {
            name: "lightcuts: far-field product",
            stage: Stage::Prepare,
            reads: &[Slot::TexelRadiance, Slot::NodeRadiance],
            writes: &[Slot::TexelIrradiance],
        },
        PassInfo {
            name: "final gather",
            stage: Stage::Frame,
            reads: &[
                Slot::Cssm,
                Slot::GBuffer,
                Slot::NodeRadiance,
                Slot::TexelIrradiance,
                Slot::Scene,
                Slot::View,
            ],
            writes: &[Slot::Reduced],
        },
        // With `downsample` above 1 only.
        filters::PASSES[0],
        filters::PASSES[1],
        PassInfo {
            name: "lightcuts resolve",
            stage: Stage::Frame,
            reads: &[
                Slot::Reduced,
                Slot::Upsampled,
                Slot::GBuffer,
                Slot::Scene,
                Slot::View,
            ],
            writes: &[Slot::Indirect],
        },
    ],
    backend: Backend::Gpu(Lightcuts::build),
    checks: Checks::DEFAULT,
    timing: Timing::PER_BAKE,
};

/// The options of `lightcuts`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightcutsOptions {
    /// Indirect bounces: the radiosity iterates `bounces - 1` times, the final gather is the
    /// last (0: the radiosity until converged, then the final gather).
    pub bounces: u32,
    /// Oracle threshold (§4.3), of the radiosity and of the final gather.
    pub threshold: f32,
    /// The radiosity's bounces multiply the cached links once built (`links=cached`).
    pub links: bool,
    /// How a pixel gathers.
    pub form: GatherForm,
    /// The near field's reach in texel sizes ([`GatherForm::Atlas`]).
    pub near: f32,
    /// Every pixel gathers the emitters' light itself, kept out of the far field and the
    /// near field ([`GatherForm::Atlas`]; `emitters=pixel`).
    pub emitters_apart: bool,
    /// Jitter the senders every frame (§4.5).
    pub jitter: bool,
    /// Reduction of the final gather's resolution per side (1: every pixel).
    pub downsample: u32,
    /// Taps on each side of the edge-aware blur of a down-sampled gather.
    pub blur: u32,
}

impl LightcutsOptions {
    /// The typed form of checked options.
    pub fn from_resolved(options: &Resolved) -> Self {
        Self {
            bounces: options.count("bounces"),
            threshold: options.number("threshold"),
            links: options.choice("links") == "cached",
            form: if options.choice("gather") == "walk" {
                GatherForm::Walk
            } else {
                GatherForm::Atlas
            },
            near: options.number("near"),
            emitters_apart: options.choice("emitters") == "pixel",
            jitter: options.switch("jitter"),
            downsample: options.count("downsample"),
            blur: options.count("blur"),
        }
    }

    /// The shared filters' settings for a down-sampled gather.
    pub fn filter(&self) -> FilterOptions {
        FilterOptions::reduced(self.downsample, self.blur)
    }
}

/// The `lightcuts` method.
struct Lightcuts {
    gi: AtlasGi,
    /// The far field, with [`GatherForm::Atlas`].
    far: Option<radiosity::FarField>,
    /// Bound where the final gather reads the far field ([`GatherForm::Walk`] reads none).
    far_buffer: wgpu::Buffer,
    gather: FinalGather,
    planes: Planes,
    resolve: PlaneResolve,
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
        let plan = BouncePlan::from_option(options.bounces).one_fewer();
        let file = setup.cssm_file()?;
        let mut gi = AtlasGi::new(ctx, file, radiosity_options, plan)?;
        if !options.links {
            gi.radiosity.walk_always();
        }
        // The atlas form's far field and near lists; the walk reads neither.
        let (near_radius, far, lists) = match options.form {
            GatherForm::Atlas => {
                let radius = near_radius(&file.hierarchy, options.near);
                let split = radiosity::cpu::FarSplit {
                    near_radius: radius,
                    emitters_apart: options.emitters_apart,
                };
                let far = gi.radiosity.far_field(&ctx.device, ctx.cssm()?, split);
                (radius, Some(far), near_lists(file, options.near))
            }
            GatherForm::Walk => (0.0, None, None),
        };
        let far_buffer = match &far {
            Some(far) => far.irradiance.clone(),
            None => ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("final gather: no far field"),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            }),
        };
        let planes = Planes::new(ctx, &options)?;
        let gather = FinalGather::new(
            ctx,
            (gi.radiosity.radiance(), &far_buffer),
            &NearSetup {
                form: options.form,
                radius: near_radius,
                lists: lists.as_ref(),
                emitters_apart: options.emitters_apart,
            },
            options.threshold,
            options.downsample,
            planes.gathered(),
        )?;
        let resolve = PlaneResolve::new(ctx, "lightcuts resolve", planes.resolved());
        Ok(Box::new(Self {
            gi,
            far,
            far_buffer,
            gather,
            planes,
            resolve,
            jitter: options.jitter,
        }))
    }
}

impl GiMethod for Lightcuts {
    fn prepare(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        // The far field's links are made for the radiance its last pass read: before the
        // iteration that writes the next.
        if let (Some(far), Some(cssm)) = (&mut self.far, &ctx.cssm) {
            far.update_links(&ctx.device, &ctx.queue, cssm, frame);
        }
        self.gi.run(ctx, frame);
        if let (Some(far), Some(cssm)) = (&mut self.far, &ctx.cssm) {
            far.run(frame, cssm);
        }
    }

    fn encode(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.gather.run(ctx, frame, self.jitter);
        self.planes.run(frame);
        self.resolve.run(frame);
    }

    fn indirect(&self) -> Option<&wgpu::Buffer> {
        Some(self.resolve.indirect())
    }

    fn resize(&mut self, ctx: &FrameContext) -> Result<(), RuntimeError> {
        self.planes.resize(ctx);
        let sources = (self.gi.radiosity.radiance(), &self.far_buffer);
        self.gather.resize(ctx, sources, self.planes.gathered())?;
        self.resolve.resize(ctx, self.planes.resolved());
        Ok(())
    }

    /// The radiosity's bounces and the final gather's.
    fn convergence(&self, ctx: &FrameContext) -> Option<Result<Convergence, RuntimeError>> {
        let radiosity = self.gi.radiosity.convergence(&ctx.device, &ctx.queue);
        Some(radiosity.map(|c| Convergence {
            bounces: c.bounces + 1,
            ..c
        }))
    }
}

/// The seed of frame `frame`'s jitter (what [`FinalGather::run`] uploads).
pub fn frame_seed(frame: u32) -> u32 {
    crate::common::random::pcg_hash(frame.wrapping_add(0x9e37_79b9))
}

#[cfg(test)]
mod tests {
    #[test]
    fn gather_grid_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::FINAL_GATHER_SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "GatherGrid",
            size_of::<super::GpuGatherGrid>(),
            &[
                ("low_size", offset_of!(super::GpuGatherGrid, low_size)),
                ("factor", offset_of!(super::GpuGatherGrid, factor)),
            ],
        );
    }
}
