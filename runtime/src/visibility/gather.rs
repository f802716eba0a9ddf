//! A benchmark kernel in the access pattern of a final gather (`gather.wgsl`): every receiver
//! queries a run of consecutive sender texels and sums the visible fractions. Its CPU twin is
//! [`gather_cpu`]; the test `gather_kernel_matches_cpu` holds them together.

use bytemuck::{Pod, Zeroable};
use cssm_formats::visibility::VisibilityQuery;
use wgpu::util::DeviceExt;

use crate::{
    Gpu, RuntimeError,
    common::{layout, timestamps::PassTimer},
    load::CssmGpu,
};

/// `visibility/gather.wgsl`, the gather benchmark kernel, with the CSSM library.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("visibility gather", "visibility/gather.wgsl");

/// A receiver and the first texel of the senders it gathers from.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Receiver {
    /// Position.
    pub position: [f32; 3],
    /// First sender texel (the next `senders` follow, wrapping around).
    pub first_sender: u32,
    /// Normal (zero: unknown).
    pub normal: [f32; 3],
    /// Unused.
    pub _pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(crate) struct GatherParams {
    pub(crate) senders: u32,
    pub(crate) texel_count: u32,
    _pad: [u32; 2],
}

/// The gather kernel.
pub struct GatherKernel {
    pipeline: wgpu::ComputePipeline,
    io_layout: wgpu::BindGroupLayout,
}

/// CPU twin of the kernel: the summed visibility of each receiver.
pub fn gather_cpu(query: &VisibilityQuery, receivers: &[Receiver], senders: u32) -> Vec<f32> {
    let texel_count = query.file().texels.len() as u32;
    receivers
        .iter()
        .map(|r| {
            let n = glam::Vec3::from(r.normal);
            let normal = (n != glam::Vec3::ZERO).then_some(n);
            let mut sum = 0.0;
            for k in 0..senders {
                let texel = (r.first_sender + k) % texel_count;
                sum += query.visibility_oriented(texel, r.position.into(), normal);
            }
            sum
        })
        .collect()
}

impl GatherKernel {
    /// The kernel for CSSMs bound with `cssm`'s layout.
    pub fn new(gpu: &Gpu, cssm: &CssmGpu) -> Self {
        let device = &gpu.device;
        let module = SHADER.create_for(device, cssm.shape());
        let c = wgpu::ShaderStages::COMPUTE;
        let io_layout = layout::bind_group_layout(
            device,
            "cssm gather io",
            &[
                layout::storage(0, true, c),
                layout::storage(1, false, c),
                layout::uniform(2, c),
            ],
        );
        let pipeline = layout::compute_pipeline(
            device,
            "cssm gather",
            &module,
            &[&io_layout, &cssm.bind_group_layout],
        );
        Self {
            pipeline,
            io_layout,
        }
    }

    /// Gathers from `senders` texels per receiver; returns the sums.
    pub fn run(
        &self,
        gpu: &Gpu,
        cssm: &CssmGpu,
        receivers: &[Receiver],
        senders: u32,
        timer: Option<&mut PassTimer>,
    ) -> Result<Vec<f32>, RuntimeError> {
        if receivers.is_empty() || cssm.params.map_count == 0 {
            return Ok(vec![0.0; receivers.len()]);
        }
        let device = &gpu.device;
        crate::load::limit_check(
            device,
            "the receivers",
            std::mem::size_of_val(receivers) as u64,
        )?;
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("receivers"),
            contents: bytemuck::cast_slice(receivers),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let output = super::answer_buffer(device, "gathered", receivers.len());
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("gather params"),
            contents: bytemuck::bytes_of(&GatherParams {
                senders,
                texel_count: cssm.params.map_count,
                _pad: [0; 2],
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let io = layout::bind_group(
            device,
            "cssm gather io",
            &self.io_layout,
            &[
                input.as_entire_binding(),
                output.as_entire_binding(),
                params.as_entire_binding(),
            ],
        );
        let bytes = super::dispatch_and_read(
            gpu,
            "cssm gather",
            &self.pipeline,
            &[&io, &cssm.bind_group],
            receivers.len(),
            &output,
            timer,
        )?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}
