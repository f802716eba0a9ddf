//! Reflective shadow maps with micro-linear-buffer visibility (Bang 2011, after Dachsbacher and
//! Stamminger 2005): one indirect bounce from the texels of each spot light's RSM, the pixel
//! lights, gathered per pixel along straight radial paths in the RSM with an approximate
//! visibility, at a reduced resolution, then filtered. `--method rsm`.
//!
//! A frame:
//! 1. the RSM is the shadow maps' own raster (`common::shadow_map::Rsm`, §3.1, §4.2): position,
//!    normal towards the light and reflected flux per texel, rendered with the shadow maps when
//!    a light moves;
//! 2. `rsm sampling` (`sample.wgsl`, §3.2, §3.3, Algorithms 5 and 6), per pixel of the image
//!    reduced `downsample` times per side: the receiver projected into the RSM, `paths`
//!    straight paths around it at jittered angles (one base pattern for all pixels, rotated and
//!    scaled a little per pixel), `path-samples` pixel lights along each path near to far at
//!    radii `radius u²` (denser near the receiver, weighted by their share of the disc), each
//!    pixel light's irradiance by Eq. 3.2. Visibility: the micro linear buffer of `slots` slots
//!    of elevation angle in the light's view, reset per path; a pixel light whose slot an
//!    earlier one on the path filled is occluded, unless its predecessor had the same slot
//!    (Algorithm 3), in the branch-free form of Algorithm 6. `visibility=none` is the original
//!    RSM, every pixel light visible;
//! 3. the shared filters (`common::filters`, §4.5): an edge-aware blur (`blur` taps each side)
//!    at the reduced resolution, then a joint bilateral up-sampling to the G-buffer's;
//! 4. `rsm resolve` (`common/resolve.wgsl`): the diffuse irradiance times the albedo over pi, plus the
//!    lobe-weighted irradiance times Ks (the receiver's normalised Phong lobe evaluated per pixel
//!    light, so a glossy floor reflects the walls' light).
//!
//! What it leaves out, by design of the method: light from outside the disc of `radius` around
//! the receiver's projection, light reflected by surfaces the light does not see, a sender's
//! glossy reflection (pixel lights are diffuse), a second bounce, and emissive surfaces: the
//! pixel lights are the spot lights' RSM texels, so the light of an emitter (MTL `Ke`, glTF
//! emissive) reaches the image as direct light only, and a scene lit by emitters alone has no
//! indirect light here. Pixel lights are points
//! (Eq. 3.2) whose squared distance is lengthened by their texel's area over pi (the form
//! factor of a disc of that area), so that a sender next to its receiver stays bounded.
//! `reports/runtime.md` measures it against the path tracer, with and without the buffer.
//!
//! CPU twin: [`cpu::gather`] (test `rsm_sampling_matches_cpu_twin`).

pub mod cpu;

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[SAMPLE_SHADER],
    libraries: &[],
};

use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{
        filters::{self, EdgeAwareFilter, FilterOptions},
        layout,
        resolve::PlaneResolve,
    },
    frame::{FrameContext, FrameEncoder, PassInfo, Slot, Stage},
    method::{
        Backend, Checks, Energy, GiMethod, MethodEntry, MethodSetup, OptionKind, OptionSpec,
        Resolved, Timing, TimingRow,
    },
    shaders,
};

/// `rsm/sample.wgsl`, the RSM gather with the micro linear buffer.
pub const SAMPLE_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("rsm sampling", "rsm/sample.wgsl");

/// Most slots of the micro linear buffer.
pub const MAX_SLOTS: u32 = 16;

/// How the gather decides whether a pixel light reaches the receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Visibility {
    /// The micro linear buffer (§3.3, Algorithms 3 and 6).
    MicroBuffer,
    /// Every pixel light visible: the original RSM.
    None,
}

/// The typed options of `rsm`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RsmOptions {
    /// Straight paths per receiver (§4.4: 15).
    pub paths: u32,
    /// Pixel lights per path (§4.4: 10).
    pub path_samples: u32,
    /// Slots of the micro linear buffer (§4.4: 5; 3 measures closer, `reports/runtime.md`).
    pub slots: u32,
    /// The visibility approximation.
    pub visibility: Visibility,
    /// Radius of the sampled disc in the RSM, in widths of the RSM.
    pub radius: f32,
    /// Reduction of the indirect light's resolution per side (§4.4: 2, a quarter of the pixels).
    pub downsample: u32,
    /// Taps on each side of the edge-aware blur (§4.5: a kernel of 17, 8), 0 for none.
    pub blur: u32,
}

impl Default for RsmOptions {
    fn default() -> Self {
        Self::from_resolved(
            &METHOD
                .resolve(&Default::default())
                .expect("defaults are valid"),
        )
    }
}

impl RsmOptions {
    /// The typed form of checked options.
    pub fn from_resolved(options: &Resolved) -> Self {
        Self {
            paths: options.count("paths"),
            path_samples: options.count("path-samples"),
            slots: options.count("slots"),
            visibility: match options.choice("visibility") {
                "none" => Visibility::None,
                _ => Visibility::MicroBuffer,
            },
            radius: options.number("radius"),
            downsample: options.count("downsample"),
            blur: options.count("blur"),
        }
    }

    /// The shared filters' settings for these options.
    pub fn filter(&self) -> FilterOptions {
        FilterOptions::reduced(self.downsample, self.blur)
    }
}

/// The slot of the micro linear buffer of an elevation angle in [-pi/2, pi/2], the range cut
/// into `slots` equal parts (§3.3, Fig. 3.3); `sample.wgsl::slot_of`.
pub fn slot_of(elevation: f32, slots: u32) -> u32 {
    let at = ((elevation / std::f32::consts::PI + 0.5) * slots as f32).floor();
    at.clamp(0.0, (slots - 1) as f32) as u32
}

/// `sample.wgsl`'s `SamplingParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuSamplingParams {
    paths: u32,
    path_samples: u32,
    slots: u32,
    visibility: u32,
    radius: f32,
    factor: u32,
    low_width: u32,
    low_height: u32,
}

/// The sampling pass: two planes of indirect irradiance per reduced pixel, into the filter's
/// input.
struct Sampling {
    params: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    base: GpuSamplingParams,
}

impl Sampling {
    fn new(
        ctx: &FrameContext,
        options: &RsmOptions,
        filter: &EdgeAwareFilter,
    ) -> Result<Self, RuntimeError> {
        let device = &ctx.device;
        let (low_width, low_height) = filter.low_size();
        let base = GpuSamplingParams {
            paths: options.paths,
            path_samples: options.path_samples,
            slots: options.slots,
            visibility: u32::from(options.visibility == Visibility::MicroBuffer),
            radius: options.radius,
            factor: options.downsample,
            low_width,
            low_height,
        };
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("rsm sampling params"),
            contents: bytemuck::bytes_of(&base),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let array = wgpu::TextureViewDimension::D2Array;
        let entries = [
            layout::uniform(0, c),
            layout::uniform(1, c),
            layout::storage(2, true, c),
            layout::storage(3, true, c),
            layout::texture(4, d2, c),
            layout::texture(5, d2, c),
            layout::texture(6, array, c),
            layout::texture(7, array, c),
            layout::texture(8, array, c),
            layout::storage(9, false, c),
        ];
        let bind_layout = layout::bind_group_layout(device, "rsm sampling", &entries);
        let module = SAMPLE_SHADER.create(device);
        let pipeline = layout::compute_pipeline(device, "rsm sampling", &module, &[&bind_layout]);
        let bind_group = Self::bind(ctx, &bind_layout, &params, filter)?;
        Ok(Self {
            params,
            pipeline,
            bind_layout,
            bind_group,
            base,
        })
    }

    fn bind(
        ctx: &FrameContext,
        bind_layout: &wgpu::BindGroupLayout,
        params: &wgpu::Buffer,
        filter: &EdgeAwareFilter,
    ) -> Result<wgpu::BindGroup, RuntimeError> {
        let rsm = ctx.shadows.rsm.as_ref().ok_or_else(|| {
            RuntimeError::Unsupported("method rsm needs the shadow maps' RSM".into())
        })?;
        let gbuffer = [&ctx.gbuffer.position, &ctx.gbuffer.normal]
            .map(|t| t.create_view(&Default::default()));
        let rsm_views = rsm.views();
        let mut resources = vec![
            params.as_entire_binding(),
            ctx.view.as_entire_binding(),
            ctx.shadows.lights.as_entire_binding(),
            ctx.scene.materials.as_entire_binding(),
        ];
        resources.extend(gbuffer.iter().map(wgpu::BindingResource::TextureView));
        resources.extend(rsm_views.iter().map(wgpu::BindingResource::TextureView));
        resources.push(filter.input().as_entire_binding());
        Ok(layout::bind_group(
            &ctx.device,
            "rsm sampling",
            bind_layout,
            &resources,
        ))
    }

    fn resize(&mut self, ctx: &FrameContext, filter: &EdgeAwareFilter) -> Result<(), RuntimeError> {
        let (low_width, low_height) = filter.low_size();
        self.base.low_width = low_width;
        self.base.low_height = low_height;
        ctx.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&self.base));
        self.bind_group = Self::bind(ctx, &self.bind_layout, &self.params, filter)?;
        Ok(())
    }

    fn run(&self, frame: &mut FrameEncoder) {
        let mut pass = frame.compute_pass("rsm sampling");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        let (x, y) = shaders::groups_2d((self.base.low_width, self.base.low_height));
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// `--method rsm`.
pub const METHOD: MethodEntry = MethodEntry {
    name: "rsm",
    summary: "reflective shadow maps with micro-linear-buffer visibility, one bounce of the \
              spot lights (Bang 2011)",
    needs_cssm: false,
    options: &[
        OptionSpec {
            name: "paths",
            help: "straight sampling paths per pixel in the RSM (§3.2)",
            kind: OptionKind::Count {
                default: 15,
                min: 1,
                max: 64,
            },
        },
        OptionSpec {
            name: "path-samples",
            help: "pixel lights along each path, near to far (§3.2)",
            kind: OptionKind::Count {
                default: 10,
                min: 1,
                max: 32,
            },
        },
        OptionSpec {
            name: "slots",
            help: "slots of elevation angle in the micro linear buffer (§3.3; the thesis: 5)",
            kind: OptionKind::Count {
                default: 3,
                min: 1,
                max: MAX_SLOTS,
            },
        },
        OptionSpec {
            name: "visibility",
            help: "micro-buffer: the approximate visibility of §3.3; none: every pixel light \
                   visible (the original RSM)",
            kind: OptionKind::Choice {
                default: "micro-buffer",
                choices: &["micro-buffer", "none"],
            },
        },
        OptionSpec {
            name: "radius",
            help: "radius of the sampled disc around the pixel's projection, in RSM widths",
            kind: OptionKind::Number {
                default: 1.5,
                min: 0.01,
            },
        },
        filters::downsample_option(
            "indirect light at 1/N of the resolution per side, then up-sampled (§4.4)",
            2,
        ),
        filters::blur_option(
            "taps on each side of the edge-aware blur (§4.5), 0 for none",
            8,
        ),
    ],
    passes: &[
        PassInfo {
            name: "rsm sampling",
            stage: Stage::Frame,
            reads: &[
                Slot::Rsm,
                Slot::Lights,
                Slot::GBuffer,
                Slot::Scene,
                Slot::View,
            ],
            writes: &[Slot::Reduced],
        },
        filters::PASSES[0],
        filters::PASSES[1],
        PassInfo {
            name: "rsm resolve",
            stage: Stage::Frame,
            reads: &[Slot::Upsampled, Slot::GBuffer, Slot::Scene, Slot::View],
            writes: &[Slot::Indirect],
        },
    ],
    backend: Backend::Gpu(RsmMethod::build),
    checks: Checks {
        emissive: Energy::NoIndirect,
        ..Checks::DEFAULT
    },
    timing: Timing {
        about: "Bang 2011, Tables 5.1-5.3: with and without the micro linear buffer, the light \
                still (the RSM rendered once) and moving every frame (the thesis' setting: the \
                RSM rendered every frame)",
        compare_with: &["direct"],
        rows: &[
            TimingRow {
                label: "micro-buffer",
                options: "visibility=micro-buffer",
                moving_light: false,
            },
            TimingRow {
                label: "micro-buffer",
                options: "visibility=micro-buffer",
                moving_light: true,
            },
            TimingRow {
                label: "no visibility",
                options: "visibility=none",
                moving_light: false,
            },
            TimingRow {
                label: "no visibility",
                options: "visibility=none",
                moving_light: true,
            },
        ],
    },
};

/// The `rsm` method: sampling, filters, resolve, every frame.
struct RsmMethod {
    sampling: Sampling,
    filter: EdgeAwareFilter,
    resolve: PlaneResolve,
}

impl RsmMethod {
    fn build(setup: &MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError> {
        let ctx = setup.ctx;
        let options = RsmOptions::from_resolved(setup.options);
        let filter = EdgeAwareFilter::two_planes(ctx, options.filter())?;
        let sampling = Sampling::new(ctx, &options, &filter)?;
        let resolve = PlaneResolve::new(ctx, "rsm resolve", filter.output());
        Ok(Box::new(Self {
            sampling,
            filter,
            resolve,
        }))
    }
}

impl GiMethod for RsmMethod {
    fn encode(&mut self, _ctx: &FrameContext, frame: &mut FrameEncoder) {
        self.sampling.run(frame);
        self.filter.run(frame);
        self.resolve.run(frame);
    }

    fn indirect(&self) -> Option<&wgpu::Buffer> {
        Some(self.resolve.indirect())
    }

    fn resize(&mut self, ctx: &FrameContext) -> Result<(), RuntimeError> {
        self.filter.resize_two_planes(ctx);
        self.sampling.resize(ctx, &self.filter)?;
        self.resolve.resize(ctx, self.filter.output());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampling_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SAMPLE_SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "SamplingParams",
            size_of::<GpuSamplingParams>(),
            &[
                ("paths", offset_of!(GpuSamplingParams, paths)),
                ("path_samples", offset_of!(GpuSamplingParams, path_samples)),
                ("slots", offset_of!(GpuSamplingParams, slots)),
                ("visibility", offset_of!(GpuSamplingParams, visibility)),
                ("radius", offset_of!(GpuSamplingParams, radius)),
                ("factor", offset_of!(GpuSamplingParams, factor)),
                ("low_width", offset_of!(GpuSamplingParams, low_width)),
                ("low_height", offset_of!(GpuSamplingParams, low_height)),
            ],
        );
    }

    #[test]
    fn slots_cut_the_elevation_range_evenly() {
        use std::f32::consts::FRAC_PI_2;
        assert_eq!(slot_of(-FRAC_PI_2, 5), 0);
        assert_eq!(slot_of(FRAC_PI_2, 5), 4);
        assert_eq!(slot_of(0.0, 5), 2);
        assert_eq!(slot_of(0.0, 4), 2);
        assert_eq!(slot_of(-0.01, 4), 1);
        assert_eq!(slot_of(1.0, 1), 0);
    }

    #[test]
    fn visibility_is_a_choice_of_two() {
        let mut values = crate::method::OptionValues::default();
        let spec = METHOD.option("visibility").unwrap();
        values.set("visibility", spec.parse("none").unwrap());
        let options = RsmOptions::from_resolved(&METHOD.resolve(&values).unwrap());
        assert_eq!(options.visibility, Visibility::None);
        let err = spec.parse("ray-cast").unwrap_err();
        assert!(err.contains("micro-buffer, none"), "{err}");
        assert_eq!(RsmOptions::default().visibility, Visibility::MicroBuffer);
        assert_eq!(RsmOptions::default().slots, 3);
    }

    /// A receiver below a floor of pixel lights: with one path and the buffer, the second
    /// pixel light in an already filled slot is occluded, so the buffer never adds light.
    #[test]
    fn the_micro_buffer_only_removes_light() {
        use glam::{Vec3, Vec4};
        let light = crate::common::shadow_map::gpu_light(
            "test",
            &cssm_formats::scene::SpotLight {
                position: Vec3::new(0.0, 2.0, 0.0),
                direction: Vec3::NEG_Y,
                cutoff_deg: 45.0,
                intensity: [10.0; 3],
            },
            (Vec3::splat(-2.0), Vec3::splat(2.0)),
            16,
        )
        .unwrap();
        // A wall of pixel lights at x = 1, facing -x, seen by a receiver on the floor.
        let n = 16usize;
        let mut rsm = cpu::CpuRsm {
            resolution: n as u32,
            position: vec![Vec4::ZERO; n * n],
            normal: vec![Vec4::ZERO; n * n],
            flux: vec![Vec4::ZERO; n * n],
        };
        for y in 0..n {
            for x in 0..n {
                let i = y * n + x;
                let height = (y as f32 + 0.5) / n as f32;
                rsm.position[i] = Vec4::new(1.0 - 0.01 * x as f32, height, 0.0, 1.0);
                rsm.normal[i] = Vec4::new(-1.0, 0.0, 0.0, 0.0);
                rsm.flux[i] = Vec4::new(1.0, 1.0, 1.0, 0.0);
            }
        }
        let receiver = cpu::Receiver {
            pixel: (3, 4),
            position: Vec3::new(0.0, 0.0, 0.0),
            normal: Vec3::Y,
            material: Default::default(),
            eye: Vec3::new(0.0, 1.0, -1.0),
        };
        let mut options = RsmOptions::default();
        let with = cpu::gather(&[rsm.clone()], &[light], &receiver, &options)[0];
        options.visibility = Visibility::None;
        let without = cpu::gather(&[rsm], &[light], &receiver, &options)[0];
        assert!(without.x > 0.0, "{without}");
        assert!(with.x <= without.x, "{with} {without}");
    }
}
