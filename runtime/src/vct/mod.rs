//! Voxel cone tracing over a sparse voxel octree (Crassin et al. 2011): one diffuse bounce and
//! glossy reflections of it, `--method vct`.
//!
//! Whenever a light or an object moves ([`SparseVoxels`]):
//! 1. `voxelize` (`common::voxelize`): the scene's triangles into a voxel-fragment list,
//!    conservatively, at `resolution`³;
//! 2. `octree build` ([`octree`], §4.2.1): the node pool, top-down, one level at a time;
//! 3. `svo inject`, `svo mip`, `svo bricks` ([`radiance`], §8.2, §4.2.3, §4.1): the RSM's flux
//!    into the leaves, each coarser node the mean of its children, every tile's brick.
//!
//! Every frame:
//! 1. `vct trace` ([`trace`], §5, §7): per pixel of the image reduced `downsample` times per
//!    side, `cones` cones of half angle `aperture` around the normal, cosine-distributed along a
//!    Fibonacci spiral that `jitter` turns by a per-pixel angle, their mean the diffuse
//!    irradiance; and for a glossy material one cone along the mirror direction whose aperture
//!    is the Phong lobe's half-power angle. A cone steps half its diameter at a time and samples
//!    the octree quadrilinearly (the two levels around its diameter, trilinear in the bricks),
//!    accumulating front to back;
//! 2. the shared filters (`common::filters`): an edge-aware blur of `blur` taps, which averages
//!    the neighbours' turned spirals (few narrow cones a pixel, many over the blur: narrow cones
//!    do not blur a surface's own light and its neighbours' into what they see, which wide ones
//!    do; reports/vct-error.md), and the up-sampling to full resolution;
//! 3. `vct resolve` (`common::resolve`): albedo / pi times the diffuse irradiance plus Ks times
//!    the glossy cone's.
//!
//! With `bounces` above 1, `svo bounce` (§8.1): the fragments' albedo and normal into their
//! leaves, then per bounce every leaf gathers with [`BOUNCE_CONES`] cones of
//! [`BOUNCE_APERTURE`] from the bricks as they are (its direct light plus its albedo times what
//! it gathers), MIP-mapping and bricks again.
//!
//! With `view=ambient-occlusion` (§6) the pass writes, instead, one minus the mean opacity the
//! diffuse cones meet within `occlusion-radius` leaf voxels, as grey.
//!
//! What it leaves out, so far: the octree's incremental update for moving objects (§4.2.2:
//! everything is rebuilt); emissive surfaces, whose light it does not inject (its light comes
//! from the spot lights' RSM only: a scene lit by emitters alone renders its direct light and
//! no indirect light, the flux bound of an empty light list held at 1 so that nothing divides
//! by zero). What the method itself approximates: a voxel
//! is opaque where any surface touches it and radiates the same in every direction, so light leaks through walls thinner than a
//! voxel at the level a cone samples, a surface's own coarse voxels shade it, and a cone's
//! aperture blurs what it sees. `reports/runtime.md` measures it against the path tracer.
//!
//! CPU twin: [`cpu`], the same values in a dense pyramid and the same cone (tests
//! `voxel_light_matches_cpu_twin`, `cones_match_cpu_twin`).

pub mod cpu;
pub mod octree;
pub mod radiance;
pub mod trace;

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[octree::SHADER, radiance::SHADER, trace::SHADER],
    libraries: &[crate::shaders::library!("vct/svo.wgsl")],
};

use std::collections::BTreeSet;

use glam::Vec3;

use crate::{
    RuntimeError,
    common::{
        converge::{BouncePlan, Convergence},
        filters::{self, EdgeAwareFilter, FilterOptions},
        readback::read_buffer,
        resolve::PlaneResolve,
        voxelize::{self, VoxelFragment, VoxelGrid, Voxelizer},
    },
    frame::{FrameContext, FrameEncoder, PassInfo, Slot, Stage},
    method::{
        Backend, Checks, Energy, GiMethod, MethodEntry, MethodSetup, OptionKind, OptionSpec,
        Resolved, Timing,
    },
};

use octree::OctreeBuild;
use radiance::{PoolLayout, Svo, VoxelRadiance};
use trace::{ConeTrace, TraceParams};

/// Diffuse cones of a leaf's gather in the bounces ([`VctOptions::bounce_params`]).
pub const BOUNCE_CONES: u32 = 16;

/// Half angle of those cones, degrees.
pub const BOUNCE_APERTURE: f32 = 7.5;

/// The typed options of `vct`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VctOptions {
    /// Leaf voxels per side of the scene's bounding cube, a power of two.
    pub resolution: u32,
    /// Diffuse cones per pixel.
    pub cones: u32,
    /// Half angle of the diffuse cones, degrees.
    pub aperture: f32,
    /// Six values per voxel, one per direction of view (§9), instead of one.
    pub anisotropic: bool,
    /// Distance of the cones' apex off the surface, leaf voxels.
    pub offset: f32,
    /// A sample's opacity corrected for a step shorter than its voxel (§5).
    pub correct_opacity: bool,
    /// Diffuse bounces: 1 the direct light's, each more gathered into the leaves (§8.1); 0
    /// until converged ([`crate::common::converge`]).
    pub bounces: u32,
    /// The ambient occlusion view's reach in leaf voxels (§6), `None` for the indirect light.
    pub occlusion: Option<f32>,
    /// Reduction per side of the traced image (the shared filters' up-sampling brings it back).
    pub downsample: u32,
    /// Taps on each side of the shared edge-aware blur of the traced image, 0 for none.
    pub blur: u32,
    /// The diffuse cones' spiral turned by a per-pixel angle.
    pub jitter: bool,
}

impl Default for VctOptions {
    fn default() -> Self {
        Self::from_resolved(
            &METHOD
                .resolve(&Default::default())
                .expect("defaults are valid"),
        )
    }
}

impl VctOptions {
    /// The typed form of checked options.
    pub fn from_resolved(options: &Resolved) -> Self {
        Self {
            resolution: options.count("resolution"),
            cones: options.count("cones"),
            aperture: options.number("aperture"),
            anisotropic: options.switch("anisotropic"),
            offset: options.number("offset"),
            correct_opacity: options.switch("opacity-correction"),
            bounces: options.count("bounces"),
            occlusion: (options.choice("view") == "ambient-occlusion")
                .then(|| options.number("occlusion-radius")),
            downsample: options.count("downsample"),
            blur: options.count("blur"),
            jitter: options.switch("jitter"),
        }
    }

    /// The cones' parameters: every pixel of the reduced image, or in the ambient occlusion
    /// view every pixel, unfiltered.
    pub fn trace_params(&self) -> TraceParams {
        let occlusion = self.occlusion.is_some();
        TraceParams {
            occlusion_radius: self.occlusion.unwrap_or(0.0),
            factor: if occlusion { 1 } else { self.downsample },
            turn: u32::from(self.jitter && !occlusion),
            ..TraceParams::new(self.cones, self.aperture.to_radians(), self.offset)
        }
    }

    /// The cones of the bounces into the leaves (§8.1): [`BOUNCE_CONES`] of [`BOUNCE_APERTURE`],
    /// the spiral not turned. A leaf's gather has no blur after it to average turned spirals
    /// over, so it keeps the wider cones the pixels had before their filters (2026-12-08).
    pub fn bounce_params(&self) -> TraceParams {
        TraceParams::new(BOUNCE_CONES, BOUNCE_APERTURE.to_radians(), self.offset)
    }

    /// The shared filters' settings: the traced image up-sampled, blurred by `blur`.
    pub fn filter(&self) -> FilterOptions {
        FilterOptions::reduced(self.downsample, self.blur)
    }

    /// The options the table's ranges cannot say: a power-of-two resolution, an aperture
    /// below 90°.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] naming the option.
    pub fn check(&self) -> Result<(), RuntimeError> {
        if !self.resolution.is_power_of_two() {
            return Err(RuntimeError::Unsupported(format!(
                "vct resolution {} is not a power of two (try {})",
                self.resolution,
                self.resolution.next_power_of_two()
            )));
        }
        if !(self.aperture > 0.0 && self.aperture < 90.0) {
            return Err(RuntimeError::Unsupported(format!(
                "vct aperture {}° is not between 0 and 90",
                self.aperture
            )));
        }
        Ok(())
    }
}

/// `--method vct`.
pub const METHOD: MethodEntry = MethodEntry {
    name: "vct",
    summary: "voxel cone tracing over a sparse voxel octree, one bounce of the spot lights (Crassin et al. 2011)",
    needs_cssm: false,
    options: &[
        OptionSpec {
            name: "bounces",
            help: "indirect bounces: each after the first gathers, with the diffuse cones, from \
                   the voxels into their leaves (§8.1); 0 (the default): until a bounce adds at \
                   most 1% of the voxels' light, at most 8",
            kind: OptionKind::Count {
                default: 0,
                min: 0,
                max: crate::method::MAX_BOUNCES,
            },
        },
        OptionSpec {
            name: "resolution",
            help: "leaf voxels per side of the scene's bounding cube, a power of two",
            kind: OptionKind::Count {
                default: 128,
                min: 8,
                max: voxelize::MAX_RESOLUTION,
            },
        },
        OptionSpec {
            name: "cones",
            help: "diffuse cones per pixel, cosine-distributed over the hemisphere (§7); the \
                   bounces into the leaves keep 16 of 7.5°",
            kind: OptionKind::Count {
                default: 8,
                min: 1,
                max: 64,
            },
        },
        OptionSpec {
            name: "aperture",
            help: "half angle of the diffuse cones, degrees: narrow cones see past what a wide \
                   one blurs into its own surface, and the turned spirals and the blur fill the \
                   hemisphere between them",
            kind: OptionKind::Number {
                default: 3.0,
                min: 0.5,
            },
        },
        OptionSpec {
            name: "anisotropic",
            help: "six values per voxel, one per direction of view, so a wall seen face on stays \
                   opaque at coarse levels (§9); false: one, the children's mean",
            kind: OptionKind::Switch { default: true },
        },
        OptionSpec {
            name: "offset",
            help: "distance of the cones' apex off the surface along its normal, in leaf \
                   voxels: past the surface's own voxels, which would shade it",
            kind: OptionKind::Number {
                default: 2.0,
                min: 0.0,
            },
        },
        OptionSpec {
            name: "opacity-correction",
            help: "correct each sample's opacity for a step shorter than its voxel (§5); \
                   false: take it as it is, which keeps more of a thin wall's opacity where \
                   the interpolation spreads it",
            kind: OptionKind::Switch { default: false },
        },
        OptionSpec {
            name: "view",
            help: "indirect: the indirect light; ambient-occlusion: one minus the mean opacity \
                   the diffuse cones meet within occlusion-radius (§6), as grey (with \
                   --component indirect)",
            kind: OptionKind::Choice {
                default: "indirect",
                choices: &["indirect", "ambient-occlusion"],
            },
        },
        OptionSpec {
            name: "occlusion-radius",
            help: "how far the ambient occlusion's cones reach, in leaf voxels",
            kind: OptionKind::Number {
                default: 16.0,
                min: 1.0,
            },
        },
        OptionSpec {
            name: "jitter",
            help: "turn the diffuse cones' spiral about the normal by a per-pixel angle, so \
                   that neighbouring pixels look along other directions and the blur averages \
                   them (false: one spiral, whose gaps show as blotches)",
            kind: OptionKind::Switch { default: true },
        },
        filters::downsample_option(
            "cones traced at 1/N of the resolution per side, then up-sampled",
            1,
        ),
        filters::blur_option(
            "taps on each side of an edge-aware blur of the traced image, 0 for none",
            4,
        ),
    ],
    passes: &[
        PassInfo {
            name: "voxelize",
            stage: Stage::Prepare,
            reads: &[Slot::Scene],
            writes: &[Slot::Voxels],
        },
        PassInfo {
            name: "octree build",
            stage: Stage::Prepare,
            reads: &[Slot::Voxels],
            writes: &[Slot::Voxels],
        },
        PassInfo {
            name: "svo inject",
            stage: Stage::Prepare,
            reads: &[Slot::Voxels, Slot::Rsm, Slot::Lights],
            writes: &[Slot::Voxels],
        },
        PassInfo {
            name: "svo mip",
            stage: Stage::Prepare,
            reads: &[Slot::Voxels],
            writes: &[Slot::Voxels],
        },
        PassInfo {
            name: "svo bricks",
            stage: Stage::Prepare,
            reads: &[Slot::Voxels],
            writes: &[Slot::Voxels],
        },
        PassInfo {
            name: "svo bounce",
            stage: Stage::Prepare,
            reads: &[Slot::Voxels],
            writes: &[Slot::Voxels],
        },
        PassInfo {
            name: "vct trace",
            stage: Stage::Frame,
            reads: &[Slot::Voxels, Slot::GBuffer, Slot::Scene, Slot::View],
            writes: &[Slot::Reduced, Slot::Indirect],
        },
        filters::PASSES[0],
        filters::PASSES[1],
        PassInfo {
            name: "vct resolve",
            stage: Stage::Frame,
            reads: &[Slot::Upsampled, Slot::GBuffer, Slot::Scene, Slot::View],
            writes: &[Slot::Indirect],
        },
    ],
    backend: Backend::Gpu(VctMethod::build),
    // In the closed sphere the method misses 20.9% of the light (lavapipe; 28.6% with 16 cones
    // of 7.5°, the defaults before 2026-12-08): the curved shell fills only part of each coarse
    // voxel's columns, so a cone sampling coarse voxels at the wall sees it partly transparent
    // and light leaves the sphere (`reports/runtime.md`). Its light is the RSM's: emitters add
    // none.
    checks: Checks {
        energy: Energy::Within(0.25),
        emissive: Energy::NoIndirect,
        ..Checks::DEFAULT
    },
    timing: Timing {
        about: "Crassin et al. 2011, §10: the light still (the octree built once, a frame the \
                cones) and moving every frame (the paper's dynamic case: the RSM, voxelisation, \
                octree build, injection, MIP-mapping and bricks every frame); the voxel \
                resolutions by `--sweep resolution=...`",
        compare_with: &["direct", "rsm"],
        rows: Timing::DEFAULT.rows,
    },
};

/// The `vct` method: the octree when something moves, the cones, the filters and the resolve
/// every frame (the cones alone in the ambient occlusion view).
struct VctMethod {
    voxels: SparseVoxels,
    trace: ConeTrace,
    filter: EdgeAwareFilter,
    resolve: PlaneResolve,
    occlusion_view: bool,
}

impl VctMethod {
    fn build(setup: &MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError> {
        let ctx = setup.ctx;
        let options = VctOptions::from_resolved(setup.options);
        options.check()?;
        let params = options.trace_params();
        let bounce_params = options.bounce_params();
        let voxels = SparseVoxels::new(
            ctx,
            setup.scene.bounds(),
            options.resolution,
            options.anisotropic,
            options.correct_opacity,
            &bounce_params,
            // The cones' gather is the last bounce.
            BouncePlan::from_option(options.bounces).one_fewer(),
        )?;
        let filter = EdgeAwareFilter::two_planes(ctx, options.filter())?;
        let trace = ConeTrace::new(ctx, &voxels.svo, params, filter.input());
        let resolve = PlaneResolve::new(ctx, "vct resolve", filter.output());
        Ok(Box::new(Self {
            voxels,
            trace,
            filter,
            resolve,
            occlusion_view: options.occlusion.is_some(),
        }))
    }
}

impl GiMethod for VctMethod {
    fn prepare(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.voxels.run(ctx, frame);
    }

    fn encode(&mut self, _ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.trace.run(frame, &self.voxels.svo);
        if !self.occlusion_view {
            self.filter.run(frame);
            self.resolve.run(frame);
        }
    }

    fn indirect(&self) -> Option<&wgpu::Buffer> {
        Some(if self.occlusion_view {
            &self.trace.occlusion
        } else {
            self.resolve.indirect()
        })
    }

    fn resize(&mut self, ctx: &FrameContext) -> Result<(), RuntimeError> {
        self.filter.resize_two_planes(ctx);
        self.trace.resize(ctx, self.filter.input());
        self.resolve.resize(ctx, self.filter.output());
        Ok(())
    }

    /// The bounces into the leaves and the cones' own.
    fn convergence(&self, ctx: &FrameContext) -> Option<Result<Convergence, RuntimeError>> {
        let leaves = self.voxels.radiance.convergence(&ctx.device, &ctx.queue);
        Some(leaves.map(|c| Convergence {
            bounces: c.bounces + 1,
            ..c
        }))
    }
}

/// Room for geometry that moves after the pools are sized: half as much again.
fn with_margin(count: u64) -> u64 {
    count + count / 2 + 64
}

/// The scene's sparse voxel octree with its light: voxelisation, the octree's build, the light
/// injection, MIP-mapping and bricks, recorded together whenever a light or an object moves.
pub struct SparseVoxels {
    /// The voxelisation pass and its fragment list.
    pub voxelizer: Voxelizer,
    /// The octree's structure.
    pub octree: OctreeBuild,
    /// The brick pool and the octree's reads.
    pub svo: Svo,
    /// The passes from the RSM into the bricks.
    pub radiance: VoxelRadiance,
}

impl SparseVoxels {
    /// The octree of `ctx`'s scene (`bounds` its bounds) at `resolution` leaves per side, its
    /// voxels anisotropic (§9) or not, its cones' opacity corrected for their step (§5) or
    /// not; bounces after the first gather with `cones`, as many as `plan` says (those into the
    /// leaves: the cones' own is not counted). The pools are sized from a first voxelisation read back
    /// (its fragments, then the nodes they occupy at every level), with room for half as much
    /// again.
    ///
    /// # Errors
    /// A resolution the voxeliser or the octree refuse, pools beyond the device's limits, the
    /// shadow maps without their RSM, a failed read-back.
    pub fn new(
        ctx: &FrameContext,
        bounds: (Vec3, Vec3),
        resolution: u32,
        anisotropic: bool,
        correct_opacity: bool,
        cones: &TraceParams,
        plan: BouncePlan,
    ) -> Result<Self, RuntimeError> {
        let device = &ctx.device;
        let grid = VoxelGrid::of_scene(bounds, resolution);
        let probe = Voxelizer::new(device, &ctx.scene, grid, 1)?;
        let count = Self::voxelize(ctx, &probe)?;
        let capacity = u32::try_from(with_margin(count as u64)).map_err(|_| {
            RuntimeError::Unsupported(format!("{count} voxel fragments at {resolution}³"))
        })?;
        let voxelizer = Voxelizer::new(device, &ctx.scene, grid, capacity)?;
        let count = Self::voxelize(ctx, &voxelizer)?;
        let size = count as u64 * std::mem::size_of::<VoxelFragment>() as u64;
        let bytes = read_buffer(device, &ctx.queue, &voxelizer.fragments, 0, size.max(16))?;
        let fragments: &[VoxelFragment] = bytemuck::cast_slice(&bytes[..size as usize]);
        // A tile for the root and one for every occupied node above the leaves; those of the
        // level above the leaves hold leaves. Each level's cells from the finer level's, so
        // only the leaves' pass reads every fragment.
        let max_level = octree::max_level(resolution);
        let mut cells: BTreeSet<[u32; 3]> = fragments.iter().map(|f| f.cell()).collect();
        let mut inner_tiles = 1u64;
        let mut leaf_tiles = 0u64;
        for level in (0..max_level).rev() {
            cells = cells.iter().map(|c| c.map(|k| k >> 1)).collect();
            if level + 1 == max_level {
                leaf_tiles = cells.len() as u64;
            } else {
                inner_tiles += cells.len() as u64;
            }
        }
        let tiles = inner_tiles + leaf_tiles;
        let capacity = |count: u64| {
            u32::try_from(with_margin(count)).map_err(|_| {
                RuntimeError::Unsupported(format!("{tiles} octree tiles at {resolution}³"))
            })
        };
        let tile_capacity = capacity(tiles)?;
        let pool = PoolLayout {
            anisotropic,
            inner_tiles: capacity(inner_tiles)?,
            leaf_tiles: capacity(leaf_tiles)?,
        };
        let octree = OctreeBuild::new(device, &voxelizer, tile_capacity)?;
        let svo = Svo::new(device, &octree, &grid, pool, correct_opacity)?;
        let radiance =
            VoxelRadiance::new(device, &voxelizer, &octree, &svo, &ctx.shadows, cones, plan)?;
        Ok(Self {
            voxelizer,
            octree,
            svo,
            radiance,
        })
    }

    /// One voxelisation, its fragment count read back.
    fn voxelize(ctx: &FrameContext, voxelizer: &Voxelizer) -> Result<u32, RuntimeError> {
        let mut timer = crate::common::timestamps::PassTimer::new(&ctx.device, &ctx.queue);
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        voxelizer.run(&mut FrameEncoder {
            encoder: &mut encoder,
            timer: &mut timer,
            index: 0,
        });
        ctx.queue.submit([encoder.finish()]);
        let count = read_buffer(&ctx.device, &ctx.queue, &voxelizer.count, 0, 4)?;
        Ok(u32::from_le_bytes([count[0], count[1], count[2], count[3]]))
    }

    /// Records every pass, after the shadow maps' raster (the RSM), with the bounces of the
    /// plan given at creation (§8.1: each gathers from the bricks into the leaves).
    pub fn run(&self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.voxelizer.run(frame);
        self.octree.run(frame, &ctx.queue);
        self.radiance.run(frame, &self.svo);
    }
}
