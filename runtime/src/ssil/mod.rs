//! Hierarchical screen-space indirect illumination with voxel visibility (Soler et al. 2010,
//! "A Fast Deferred Shading Pipeline for Real Time Approximate Indirect Illumination"),
//! `--method ssil`.
//!
//! Every frame ([`ScreenSpaceGi`], `pipeline.rs`), a file per pass:
//! 1. `ssil sender` ([`sender`], `sender.wgsl`): the diffuse direct light leaving every pixel plus the
//!    radiance it emits (the G-buffer's emission, zero where the eye sees an emitter's back:
//!    emission is one-sided), the light the first bounce gathers (§3: the "direct
//!    illumination" G-buffer, diffuse, §5.3);
//! 2. `gbuffer pyramid` (`common::pyramid`, §4, Eq. 5): position, normal and albedo of levels
//!    1 and up, each coarse pixel the child its neighbours agree with most, not an average;
//!    `ssil light pyramid`: the sent light's mean per level;
//! 3. `ssil voxels` ([`voxels`], `voxels.wgsl`, §4 after Eisemann and Décoret 2008): with
//!    `visibility=voxels`, the view frustum's solid voxelisation, 128 one-bit slices of view
//!    depth per pixel of the first gathered level, each fragment toggling (XOR) its column
//!    from its depth on; then each coarser level's columns the AND of their children;
//! 4. `ssil gather` ([`gather`], `gather.wgsl`, §3, §4, Eq. 3 and 4), per bounce and per level from the
//!    coarsest (level `start-level + levels - 1`) to the finest gathered (`start-level`):
//!    `samples` samples in the ring between `radius / 2` and `radius` level pixels (the full
//!    disc at the finest), each sending its light through the point-to-disc form factor of the
//!    scene area its share of the ring stands for (the paper's energy factor 2^2k at level k),
//!    counted when the march through the level's voxels from the receiver to it is clear
//!    (`bias` pixels skipped at both ends); glossy receivers gather a lobe-weighted irradiance
//!    from as many more samples importance-sampled around the mirrored view ray's direction on
//!    screen; the coarser levels' result, joint-bilaterally up-sampled, added;
//!    `accumulate`: the bounce's sum at the finest level into the filters' input and, when
//!    another bounce follows, its diffuse light (albedo / pi times the irradiance) that
//!    bounce's senders (§4, "Multi-bounce computation"; `later-visibility` says whether the
//!    later bounces test visibility, which §5.3 suggests dropping);
//! 5. the shared filters (`common::filters`): an edge-aware blur of `blur` taps at the finest
//!    gathered level, guided by that level of the pyramid, and joint bilateral up-sampling to
//!    the G-buffer's resolution;
//! 6. `ssil temporal` ([`temporal`], `temporal.wgsl`, §4, Eq. 6): the previous frame's result reprojected
//!    through the frame history (`common::history`: the previous camera and G-buffer) and
//!    blended in with `temporal` (less on glossy pixels as the camera turns);
//! 7. `ssil resolve` (`common::resolve`): albedo / pi times the diffuse irradiance plus Ks
//!    times the lobe-weighted one.
//!
//! What screen space cannot see, by design: light from surfaces outside the image or hidden
//! behind others (they are not in the G-buffer), and occluders outside the view frustum. The
//! voxels need closed geometry: an open surface fills everything behind it along its pixels'
//! rays. Senders are diffuse. `reports/runtime.md` measures it against the path tracer.
//!
//! CPU twin: [`cpu`] (tests in `tests/gpu/ssil.rs`).

pub mod cpu;
pub mod gather;
mod pipeline;
pub mod sender;
pub mod temporal;
pub mod voxels;

use wgpu::util::DeviceExt;

pub use gather::{FrameParams, GatherParams, pixel_area};
pub use pipeline::ScreenSpaceGi;
pub use voxels::SLICES;

use crate::{
    RuntimeError,
    common::{
        converge::{BouncePlan, CONVERGED_FRACTION, Convergence},
        filters::{self, FilterOptions},
        pyramid::PyramidLayout,
    },
    frame::{FrameContext, FrameEncoder, PassInfo, Slot, Stage},
    method::{
        Backend, Checks, Energy, GiMethod, MethodEntry, MethodSetup, OptionKind, OptionSpec,
        Resolved, Timing, TimingRow,
    },
};

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[
        sender::SHADER,
        voxels::SHADER,
        gather::SHADER,
        temporal::SHADER,
    ],
    libraries: &[],
};

/// Most bounces (each a gather of every level, every frame).
pub const MAX_BOUNCES: u32 = 4;

/// Most gathered levels.
pub const MAX_LEVELS: u32 = 8;

/// Coarsest first gathered level (3: an eighth of the resolution per side).
pub const MAX_START_LEVEL: u32 = 3;

/// The constant part `alpha` of the glossy samples' importance function (§4: 0.1).
pub const UNIFORM_WEIGHT: f32 = 0.1;

/// How the gather decides whether a sample's light reaches the receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Visibility {
    /// A march through the frustum's solid voxels (§4).
    Voxels,
    /// Every sample visible.
    None,
}

/// Which disc the point-to-disc form factor of a sample takes (Eq. 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FormFactor {
    /// The disc of the sample's own level pixel, counted as many times as its share of the
    /// ring holds pixels: the Monte-Carlo estimate of the sum over the level's pixels.
    PixelDisc,
    /// The disc of the whole share, as the paper applies Eq. 4: less noise, but a sample
    /// near its receiver is bounded by one disc where its share holds many pixels.
    SampleDisc,
}

/// The typed options of `ssil`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SsilOptions {
    /// Samples per pixel and level (and as many more for a glossy pixel's lobe).
    pub samples: u32,
    /// Gathered levels.
    pub levels: u32,
    /// The finest gathered level: the G-buffer reduced `2^start_level` times per side.
    pub start_level: u32,
    /// Outer radius of the sampled ring, in pixels of each level.
    pub radius: f32,
    /// The first bounce's visibility.
    pub visibility: Visibility,
    /// Whether the bounces after the first test visibility too.
    pub later_visibility: bool,
    /// Bounces; 0 until converged ([`Self::plan`]).
    pub bounces: u32,
    /// With `bounces` 0: the share of the light a bounce reflects at most to be the last
    /// ([`CONVERGED_FRACTION`], the option table's; tests choose others).
    pub converge: f32,
    /// Level pixels skipped at both ends of a visibility march.
    pub bias: f32,
    /// Taps on each side of the edge-aware blur at the finest gathered level.
    pub blur: u32,
    /// Weight of the reprojected history (Eq. 6's `a`), below 1.
    pub temporal: f32,
    /// The samples' form factor.
    pub form_factor: FormFactor,
}

impl Default for SsilOptions {
    fn default() -> Self {
        Self::from_resolved(
            &METHOD
                .resolve(&Default::default())
                .expect("defaults are valid"),
        )
    }
}

impl SsilOptions {
    /// The typed form of checked options.
    pub fn from_resolved(options: &Resolved) -> Self {
        Self {
            samples: options.count("level-samples"),
            levels: options.count("levels"),
            start_level: options.count("start-level"),
            radius: options.number("radius"),
            visibility: match options.choice("visibility") {
                "none" => Visibility::None,
                _ => Visibility::Voxels,
            },
            later_visibility: options.switch("later-visibility"),
            bounces: options.count("bounces"),
            converge: CONVERGED_FRACTION,
            bias: options.number("bias"),
            blur: options.count("blur"),
            temporal: options.number("temporal"),
            form_factor: match options.choice("form-factor") {
                "sample-disc" => FormFactor::SampleDisc,
                _ => FormFactor::PixelDisc,
            },
        }
    }

    /// Refuses a history weight of 1 or more (the image would never change).
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] naming the value.
    pub fn check(&self) -> Result<(), RuntimeError> {
        if !(0.0..1.0).contains(&self.temporal) {
            return Err(RuntimeError::Unsupported(format!(
                "ssil temporal={} must be at least 0 and below 1",
                self.temporal
            )));
        }
        Ok(())
    }

    /// The coarsest gathered level.
    pub fn last_level(&self) -> u32 {
        self.start_level + self.levels - 1
    }

    /// The bounces: `bounces`, or with `bounces` 0 until one adds at most `converge` of the
    /// light, at most [`MAX_BOUNCES`] ([`crate::common::converge`]).
    pub fn plan(&self) -> BouncePlan {
        match self.bounces {
            0 => BouncePlan {
                max: MAX_BOUNCES,
                fraction: self.converge,
            },
            n => BouncePlan::exactly(n),
        }
    }

    /// Whether bounce `bounce` (0 for the first) tests visibility.
    pub fn visibility_in(&self, bounce: u32) -> bool {
        self.visibility == Visibility::Voxels && (bounce == 0 || self.later_visibility)
    }

    /// The shared filters' settings.
    pub fn filter(&self) -> FilterOptions {
        FilterOptions::reduced(1 << self.start_level, self.blur)
    }
}

/// The levels' geometry: the pyramid's layout, the gathered levels, the voxel columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Levels {
    /// The pyramid up to the coarsest gathered level.
    pub pyramid: PyramidLayout,
    /// The finest gathered level.
    pub start: u32,
    /// The coarsest gathered level.
    pub last: u32,
}

impl Levels {
    /// The levels of `options` over a G-buffer of `full` size.
    pub fn new(full: (u32, u32), options: &SsilOptions) -> Self {
        Self {
            pyramid: PyramidLayout {
                full,
                levels: options.last_level(),
            },
            start: options.start_level,
            last: options.last_level(),
        }
    }

    /// Voxel column of `level`'s (0, 0): the columns of the gathered levels, finest first.
    pub fn grid_offset(&self, level: u32) -> u32 {
        (self.start..level)
            .map(|j| {
                let (w, h) = self.pyramid.size(j);
                w * h
            })
            .sum()
    }

    /// Voxel columns of every gathered level.
    pub fn columns(&self) -> u32 {
        self.grid_offset(self.last + 1)
    }

    /// The gather's parameters at `level` in `bounce` of `options`.
    pub fn gather_params(&self, level: u32, bounce: u32, options: &SsilOptions) -> GatherParams {
        let filter = FilterOptions::default();
        let (w, h) = self.pyramid.size(level);
        let coarse = (level < self.last).then(|| level + 1);
        let coarse_size = coarse.map_or((0, 0), |c| self.pyramid.size(c));
        GatherParams {
            full_size: [self.pyramid.full.0, self.pyramid.full.1],
            size: [w, h],
            coarse_size: [coarse_size.0, coarse_size.1],
            level,
            offset: self.pyramid.offset(level),
            coarse_offset: coarse.map_or(0, |c| self.pyramid.offset(c)),
            has_coarse: u32::from(coarse.is_some()),
            samples: options.samples,
            disc: u32::from(level == self.start),
            radius: options.radius,
            visibility: u32::from(options.visibility_in(bounce)),
            bias: options.bias,
            grid_offset: self.grid_offset(level),
            depth_sigma: filter.depth_sigma,
            normal_power: filter.normal_power,
            bounce,
            next_bounce: u32::from(bounce + 1 < options.plan().max),
            pixels: self.pyramid.pixels(),
            uniform_weight: UNIFORM_WEIGHT,
            sample_disc: u32::from(options.form_factor == FormFactor::SampleDisc),
            padding: 0,
        }
    }
}

/// A uniform buffer holding `value`, rewritten every frame.
fn uniform_buffer<T: bytemuck::Pod>(device: &wgpu::Device, label: &str, value: &T) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::bytes_of(value),
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
    })
}

/// A storage buffer of `bytes` (at least 16), read back by the tests.
fn storage_buffer(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// `--method ssil`.
// Every check is set here, and `..Checks::DEFAULT` stays so that a new kind of check takes its
// default without editing this method.
#[allow(clippy::needless_update)]
pub const METHOD: MethodEntry = MethodEntry {
    name: "ssil",
    summary: "hierarchical screen-space indirect light with voxel visibility, multi-bounce \
              (Soler et al. 2010)",
    needs_cssm: false,
    options: &[
        OptionSpec {
            name: "level-samples",
            help: "samples per pixel and level, in the ring between radius/2 and radius (§4)",
            kind: OptionKind::Count {
                default: 32,
                min: 1,
                max: 256,
            },
        },
        OptionSpec {
            name: "levels",
            help: "gathered levels of the G-buffer pyramid, each twice as coarse (§4)",
            kind: OptionKind::Count {
                default: 5,
                min: 1,
                max: MAX_LEVELS,
            },
        },
        OptionSpec {
            name: "start-level",
            help: "finest gathered level: 1 half, 2 quarter, 3 an eighth of the resolution (§4)",
            kind: OptionKind::Count {
                default: 1,
                min: 1,
                max: MAX_START_LEVEL,
            },
        },
        OptionSpec {
            name: "radius",
            help: "outer radius of the sampled ring, in pixels of each level (§4: 40 at 1280x720)",
            kind: OptionKind::Number {
                default: 32.0,
                min: 1.0,
            },
        },
        OptionSpec {
            name: "visibility",
            help: "voxels: march through the frustum's solid voxelisation (§4); none: every \
                   sample visible",
            kind: OptionKind::Choice {
                default: "voxels",
                choices: &["voxels", "none"],
            },
        },
        OptionSpec {
            name: "later-visibility",
            help: "test visibility in the bounces after the first too (§5.3 suggests not)",
            kind: OptionKind::Switch { default: false },
        },
        OptionSpec {
            name: "bounces",
            help: "indirect bounces, each gathering the previous one's light (§4); 0: until a \
                   bounce adds at most 1% of the light, at most 4, decided every frame (the \
                   default is the paper's 2: each bounce costs every frame's time)",
            kind: OptionKind::Count {
                default: 2,
                min: 0,
                max: MAX_BOUNCES,
            },
        },
        OptionSpec {
            name: "bias",
            help: "level pixels skipped at both ends of a visibility march (§4)",
            kind: OptionKind::Number {
                default: 1.0,
                min: 0.0,
            },
        },
        filters::blur_option(
            "taps on each side of the edge-aware blur at the finest gathered level",
            2,
        ),
        OptionSpec {
            name: "temporal",
            help: "weight of the reprojected previous frame, 0 to below 1 (§4, Eq. 6)",
            kind: OptionKind::Number {
                default: 0.8,
                min: 0.0,
            },
        },
        OptionSpec {
            name: "form-factor",
            help: "pixel-disc: each sample the point-to-disc form factor of its own pixel, \
                   times the pixels it stands for; sample-disc: of a disc of all of them (Eq. 4 \
                   as the paper applies it)",
            kind: OptionKind::Choice {
                default: "pixel-disc",
                choices: &["pixel-disc", "sample-disc"],
            },
        },
    ],
    passes: &[
        PassInfo {
            name: "ssil sender",
            stage: Stage::Frame,
            reads: &[Slot::GBuffer, Slot::Lights, Slot::ShadowMaps, Slot::View],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "gbuffer pyramid",
            stage: Stage::Frame,
            reads: &[Slot::GBuffer, Slot::View],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil light pyramid",
            stage: Stage::Frame,
            reads: &[Slot::Reduced],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil converge",
            stage: Stage::Frame,
            reads: &[Slot::Reduced],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil voxels",
            stage: Stage::Frame,
            reads: &[Slot::Scene, Slot::View],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil voxel levels",
            stage: Stage::Frame,
            reads: &[Slot::Reduced],
            writes: &[Slot::Reduced],
        },
        PassInfo {
            name: "ssil gather",
            stage: Stage::Frame,
            reads: &[Slot::Reduced, Slot::Scene, Slot::View],
            writes: &[Slot::Reduced],
        },
        filters::PASSES[0],
        filters::PASSES[1],
        PassInfo {
            name: "ssil temporal",
            stage: Stage::Frame,
            reads: &[Slot::Upsampled, Slot::GBuffer, Slot::View],
            writes: &[Slot::Upsampled],
        },
        PassInfo {
            name: "ssil resolve",
            stage: Stage::Frame,
            reads: &[Slot::Upsampled, Slot::GBuffer, Slot::Scene, Slot::View],
            writes: &[Slot::Indirect],
        },
    ],
    backend: Backend::Gpu(SsilMethod::build),
    checks: Checks {
        energy: Energy::OnScreenOnly,
        golden_flip: 0.01,
        emissive: Energy::OnScreenOnly,
        ..Checks::DEFAULT
    },
    timing: Timing {
        about: "Soler et al. 2010, Fig. 9: its four settings (quarter or half resolution, levels, \
                samples per level, the radius of 40 pixels), each without and with the voxel \
                visibility, then the defaults; camera and light at rest",
        compare_with: &["direct"],
        rows: &[
            TimingRow {
                label: "quarter, 4 levels, 64 samples, 1 bounce, visibility none",
                options: "start-level=2,levels=4,level-samples=64,radius=40,visibility=none,bounces=1",
                moving_light: false,
            },
            TimingRow {
                label: "quarter, 4 levels, 64 samples, 1 bounce, visibility voxels",
                options: "start-level=2,levels=4,level-samples=64,radius=40,visibility=voxels,bounces=1",
                moving_light: false,
            },
            TimingRow {
                label: "quarter, 4 levels, 256 samples, 1 bounce, visibility none",
                options: "start-level=2,levels=4,level-samples=256,radius=40,visibility=none,bounces=1",
                moving_light: false,
            },
            TimingRow {
                label: "quarter, 4 levels, 256 samples, 1 bounce, visibility voxels",
                options: "start-level=2,levels=4,level-samples=256,radius=40,visibility=voxels,bounces=1",
                moving_light: false,
            },
            TimingRow {
                label: "half, 4 levels, 64 samples, 1 bounce, visibility none",
                options: "start-level=1,levels=4,level-samples=64,radius=40,visibility=none,bounces=1",
                moving_light: false,
            },
            TimingRow {
                label: "half, 4 levels, 64 samples, 1 bounce, visibility voxels",
                options: "start-level=1,levels=4,level-samples=64,radius=40,visibility=voxels,bounces=1",
                moving_light: false,
            },
            TimingRow {
                label: "half, 5 levels, 64 samples, 1 bounce, visibility none",
                options: "start-level=1,levels=5,level-samples=64,radius=40,visibility=none,bounces=1",
                moving_light: false,
            },
            TimingRow {
                label: "half, 5 levels, 64 samples, 1 bounce, visibility voxels",
                options: "start-level=1,levels=5,level-samples=64,radius=40,visibility=voxels,bounces=1",
                moving_light: false,
            },
            TimingRow {
                label: "defaults",
                options: "",
                moving_light: false,
            },
        ],
    },
};

/// The `ssil` method.
struct SsilMethod {
    gi: ScreenSpaceGi,
}

impl SsilMethod {
    fn build(setup: &MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError> {
        let options = SsilOptions::from_resolved(setup.options);
        let gi = ScreenSpaceGi::new(setup.ctx, setup.scene.bounds(), &options)?;
        Ok(Box::new(Self { gi }))
    }
}

impl GiMethod for SsilMethod {
    fn encode(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.gi.encode(ctx, frame);
    }

    fn indirect(&self) -> Option<&wgpu::Buffer> {
        Some(self.gi.indirect())
    }

    fn resize(&mut self, ctx: &FrameContext) -> Result<(), RuntimeError> {
        self.gi.resize(ctx);
        Ok(())
    }

    /// The last frame's bounces.
    fn convergence(&self, ctx: &FrameContext) -> Option<Result<Convergence, RuntimeError>> {
        Some(self.gi.convergence(ctx))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rings of the levels cover the screen once: level k's ring, `r/2` to `r` of its
    /// pixels, is `2^(k-1) r` to `2^k r` full-res pixels, where level k - 1's ends.
    #[test]
    fn levels_follow_each_other() {
        let options = SsilOptions {
            start_level: 2,
            levels: 3,
            ..Default::default()
        };
        let levels = Levels::new((640, 480), &options);
        assert_eq!((levels.start, levels.last), (2, 4));
        assert_eq!(levels.grid_offset(2), 0);
        assert_eq!(levels.grid_offset(3), 160 * 120);
        assert_eq!(levels.columns(), 160 * 120 + 80 * 60 + 40 * 30);
        let first = levels.gather_params(2, 0, &options);
        assert_eq!(
            (first.disc, first.has_coarse, first.coarse_size),
            (1, 1, [80, 60])
        );
        let last = levels.gather_params(4, 1, &options);
        assert_eq!((last.disc, last.has_coarse, last.next_bounce), (0, 0, 0));
        assert_eq!(
            last.visibility, 0,
            "later bounces skip visibility by default"
        );
        assert_eq!(levels.gather_params(4, 0, &options).visibility, 1);
    }

    #[test]
    fn temporal_weight_below_one() {
        let mut options = SsilOptions::default();
        assert!(options.check().is_ok());
        options.temporal = 1.0;
        let err = options.check().unwrap_err().to_string();
        assert!(err.contains("temporal=1"), "{err}");
    }
}
