//! The cone tracing pass (`trace.wgsl`, Crassin et al. 2011 §5, §7): per pixel of the reduced
//! image, diffuse cones around the normal (their spiral turned per pixel) and a glossy cone along
//! the mirror direction through the octree's bricks, into the shared filters' two planes; and
//! [`ConeProbe`], the same accumulation for given cones, which the test holds to
//! [`super::cpu::trace_cone`].

use glam::{Vec3, Vec4};
use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{filters, layout, readback::read_buffer},
    frame::{FrameContext, FrameEncoder},
    shaders,
};

use super::radiance::Svo;

/// `vct/trace.wgsl` with `vct/svo.wgsl`: the cones per pixel (`main`) and the test's probe
/// (`probe`).
pub const SHADER: crate::shaders::Shader = crate::shaders::shader!("vct trace", "vct/trace.wgsl");

/// Where a cone's first sample lies, in leaf voxels along it.
pub const START: f32 = 1.0;

/// `trace.wgsl`'s `TraceParams`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct TraceParams {
    /// Diffuse cones, cosine-distributed over the hemisphere.
    pub cones: u32,
    /// tan of the diffuse cones' half angle.
    pub tan_half: f32,
    /// Above 0: the ambient occlusion view (§6), the cones' reach in leaf voxels.
    pub occlusion_radius: f32,
    /// Reduction per side of the traced image (1 in the ambient occlusion view).
    pub factor: u32,
    /// [`START`].
    pub start: f32,
    /// How far off the surface along its normal the cones start, leaf voxels.
    pub offset: f32,
    /// The diffuse half angle, radians.
    pub half_angle: f32,
    /// Nonzero: the diffuse cones' spiral turned per pixel ([`super::cpu::pixel_turn`]).
    pub turn: u32,
}

impl TraceParams {
    /// `cones` diffuse cones of half angle `half_angle` (radians), their apex `offset` leaf
    /// voxels off the surface, at every pixel, the spiral not turned.
    pub fn new(cones: u32, half_angle: f32, offset: f32) -> Self {
        Self {
            cones,
            tan_half: half_angle.tan(),
            occlusion_radius: 0.0,
            factor: 1,
            start: START,
            offset,
            half_angle,
            turn: 0,
        }
    }
}

/// The pass per pixel of the reduced image into the filters' planes (or, in the ambient
/// occlusion view, per pixel into its grey).
pub struct ConeTrace {
    /// The ambient occlusion view's grey per pixel, `vec4f` (in the indirect view one unused
    /// `vec4f`, the binding's placeholder).
    pub occlusion: wgpu::Buffer,
    params: wgpu::Buffer,
    factor: u32,
    occlusion_view: bool,
    pipeline: wgpu::ComputePipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

fn trace_entries() -> [wgpu::BindGroupLayoutEntry; 7] {
    let c = wgpu::ShaderStages::COMPUTE;
    let d2 = wgpu::TextureViewDimension::D2;
    [
        layout::uniform(0, c),
        layout::uniform(1, c),
        layout::storage(2, true, c),
        layout::texture(3, d2, c),
        layout::texture(4, d2, c),
        layout::storage(5, false, c),
        layout::storage(6, false, c),
    ]
}

impl ConeTrace {
    /// The pass with `params` over `ctx`'s G-buffer, writing `planes` (two planes of `vec4f` of
    /// the image reduced `params.factor` times: the filters' input).
    pub fn new(ctx: &FrameContext, svo: &Svo, params: TraceParams, planes: &wgpu::Buffer) -> Self {
        let device = &ctx.device;
        let (factor, occlusion_view) = (params.factor, params.occlusion_radius > 0.0);
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vct trace params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bind_layout = layout::bind_group_layout(device, "vct trace", &trace_entries());
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline(
            device,
            "vct trace",
            &module,
            &[&bind_layout, &svo.sample_layout],
        );
        let (occlusion, bind_group) =
            Self::bind(ctx, &bind_layout, (&params, occlusion_view), planes);
        Self {
            occlusion,
            params,
            factor,
            occlusion_view,
            pipeline,
            bind_layout,
            bind_group,
            size: ctx.size(),
        }
    }

    fn bind(
        ctx: &FrameContext,
        bind_layout: &wgpu::BindGroupLayout,
        (params, occlusion_view): (&wgpu::Buffer, bool),
        planes: &wgpu::Buffer,
    ) -> (wgpu::Buffer, wgpu::BindGroup) {
        let occlusion = if occlusion_view {
            ctx.pixel_buffer("vct occlusion")
        } else {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vct occlusion (unused)"),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        let views = [&ctx.gbuffer.position, &ctx.gbuffer.normal]
            .map(|t| t.create_view(&Default::default()));
        let mut resources = vec![
            params.as_entire_binding(),
            ctx.view.as_entire_binding(),
            ctx.scene.materials.as_entire_binding(),
        ];
        resources.extend(views.iter().map(wgpu::BindingResource::TextureView));
        resources.push(occlusion.as_entire_binding());
        resources.push(planes.as_entire_binding());
        let bind_group = layout::bind_group(&ctx.device, "vct trace", bind_layout, &resources);
        (occlusion, bind_group)
    }

    /// Rebuilds the output for `ctx`'s new size, writing the filters' new `planes`.
    pub fn resize(&mut self, ctx: &FrameContext, planes: &wgpu::Buffer) {
        let params = (&self.params, self.occlusion_view);
        (self.occlusion, self.bind_group) = Self::bind(ctx, &self.bind_layout, params, planes);
        self.size = ctx.size();
    }

    /// Records the pass.
    pub fn run(&self, frame: &mut FrameEncoder, svo: &Svo) {
        let mut pass = frame.compute_pass("vct trace");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_bind_group(1, &svo.sample_group, &[]);
        let (x, y) = shaders::groups_2d(filters::low_size(self.size, self.factor));
        pass.dispatch_workgroups(x, y, 1);
    }
}

/// `trace.wgsl`'s `Probe`: a cone to trace.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Probe {
    /// Apex, in leaf voxels from the grid's corner.
    pub origin: [f32; 3],
    /// Distance of the first sample, leaf voxels.
    pub start: f32,
    /// Unit direction.
    pub dir: [f32; 3],
    /// tan of the half angle.
    pub tan_half: f32,
}

/// Traces given cones through the octree on the GPU (`trace.wgsl::probe`), for the tests.
pub struct ConeProbe {
    pipeline: wgpu::ComputePipeline,
    bind_layout: wgpu::BindGroupLayout,
}

impl ConeProbe {
    /// The probe pipeline for `svo`'s layout.
    pub fn new(device: &wgpu::Device, svo: &Svo) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let bind_layout = layout::bind_group_layout(
            device,
            "vct probe",
            &[layout::storage(7, true, c), layout::storage(8, false, c)],
        );
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline_entry(
            device,
            "vct probe",
            &module,
            "probe",
            &[&bind_layout, &svo.sample_layout],
        );
        Self {
            pipeline,
            bind_layout,
        }
    }

    /// Every cone's `(radiance, opacity)`, read back.
    ///
    /// # Errors
    /// A failed read-back.
    pub fn trace(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        svo: &Svo,
        probes: &[Probe],
    ) -> Result<Vec<Vec4>, RuntimeError> {
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("vct probes"),
            contents: bytemuck::cast_slice(probes),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let size = 16 * probes.len().max(1) as u64;
        let output = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("vct probe results"),
            size,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let group = layout::bind_group_at(
            device,
            "vct probe",
            &self.bind_layout,
            &[
                (7, input.as_entire_binding()),
                (8, output.as_entire_binding()),
            ],
        );
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.set_bind_group(1, &svo.sample_group, &[]);
            pass.dispatch_workgroups(shaders::groups_1d(probes.len() as u32), 1, 1);
        }
        queue.submit([encoder.finish()]);
        let bytes = read_buffer(device, queue, &output, 0, size)?;
        Ok(bytemuck::cast_slice::<u8, [f32; 4]>(&bytes)[..probes.len()]
            .iter()
            .map(|&v| Vec4::from(v))
            .collect())
    }
}

impl Probe {
    /// A cone from `origin` along `dir` (normalised here).
    pub fn new(origin: Vec3, dir: Vec3, tan_half: f32, start: f32) -> Self {
        Self {
            origin: origin.to_array(),
            start,
            dir: dir.normalize().to_array(),
            tan_half,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trace_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "TraceParams",
            size_of::<TraceParams>(),
            &[
                ("cones", offset_of!(TraceParams, cones)),
                ("tan_half", offset_of!(TraceParams, tan_half)),
                (
                    "occlusion_radius",
                    offset_of!(TraceParams, occlusion_radius),
                ),
                ("factor", offset_of!(TraceParams, factor)),
                ("start", offset_of!(TraceParams, start)),
                ("offset", offset_of!(TraceParams, offset)),
                ("half_angle", offset_of!(TraceParams, half_angle)),
                ("turn", offset_of!(TraceParams, turn)),
            ],
        );
        crate::shaders::tests::check_struct(
            &module,
            "Probe",
            size_of::<Probe>(),
            &[
                ("origin", offset_of!(Probe, origin)),
                ("start", offset_of!(Probe, start)),
                ("dir", offset_of!(Probe, dir)),
                ("tan_half", offset_of!(Probe, tan_half)),
            ],
        );
    }
}
