//! Visibility queries on the GPU (§3.2.2): the WGSL library `cssm.wgsl`, which any shader can
//! include to call `cssm_visible` / `cssm_visibility` / `cssm_visibility_texel` against a
//! [`CssmGpu`] bind group, and [`QueryKernel`], a compute pass that answers
//! a batch of queries (for tests against the CPU reference and for benchmarks).
//!
//! The library computes exactly what `cssm_formats::visibility::VisibilityQuery` computes; the
//! test `gpu_matches_cpu_reference` holds the two together on 100,000 random pairs. They can
//! differ only where floating-point rounding of the GPU (fused multiply-adds, its division)
//! moves a depth comparison across its threshold.

pub mod bvh;
pub mod gather;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use wgpu::util::DeviceExt;

use crate::{
    Gpu, RuntimeError,
    common::{layout, readback},
    gpu_types::TYPES_WGSL,
    load::CssmGpu,
};

/// The WGSL visibility library as plain WGSL, its bindings at `@group(group)`, preceded by the
/// shared struct declarations (`types.wgsl`): append your own shader code to it. This is for a
/// shader of your own composed without naga_oil; with naga_oil, add the libraries of
/// [`crate::shaders::composer`] and `#import cssm::visibility::{cssm_visible, ...}` as the
/// runtime's own modules do. Here the lines naga_oil reads (`#define_import_path`, `#import`)
/// are dropped and the bind group filled in.
pub fn library_wgsl(group: u32) -> String {
    let group = group.to_string();
    [TYPES_WGSL, include_str!("cssm.wgsl")]
        .iter()
        .flat_map(|source| source.lines())
        .filter(|line| !line.starts_with("#define_import_path") && !line.starts_with("#import"))
        .map(|line| line.replace("#{CSSM_GROUP}", &group) + "\n")
        .collect()
}

/// One query: is `receiver` (with normal `receiver_normal`, or zero when unknown) visible from
/// the surface point with barycentric coordinates `sender_bary` on triangle `sender_triangle`?
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct QueryPair {
    /// Barycentric coordinates of the sender on its triangle.
    pub sender_bary: [f32; 3],
    /// Scene triangle of the sender.
    pub sender_triangle: u32,
    /// Receiver position.
    pub receiver: [f32; 3],
    /// Unused.
    pub _pad0: u32,
    /// Receiver normal (zero: unknown).
    pub receiver_normal: [f32; 3],
    /// Unused.
    pub _pad1: u32,
}

impl QueryPair {
    /// A query from (`triangle`, `bary`) to `receiver` with normal `normal`.
    pub fn new(triangle: u32, bary: [f32; 3], receiver: Vec3, normal: Option<Vec3>) -> Self {
        Self {
            sender_bary: bary,
            sender_triangle: triangle,
            receiver: receiver.to_array(),
            receiver_normal: normal.unwrap_or(Vec3::ZERO).to_array(),
            ..Default::default()
        }
    }
}

/// `count` random sender/receiver pairs on the surface of `scene`, area-uniform, seeded (the
/// sampler and generator of `cssm check`): the CSSM queries, and the segments an exact ray cast
/// of the same pairs tests (those of `cssm_raycast::exact_visible`).
pub fn random_pairs(
    scene: &cssm_formats::Scene,
    count: usize,
    seed: u64,
) -> (Vec<QueryPair>, Vec<bvh::Segment>) {
    let sampler = cssm_raycast::SurfaceSampler::new(scene);
    let mut rng = cssm_raycast::SplitMix64(seed);
    let eps = 1e-4 * scene.diameter();
    (0..count)
        .map(|_| {
            let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
            let (p_j, p_i) = (sampler.point(r()), sampler.point(r()));
            let side = if (p_j.position - p_i.position).dot(p_i.normal) >= -eps {
                1.0
            } else {
                -1.0
            };
            (
                QueryPair::new(
                    p_j.triangle as u32,
                    p_j.bary,
                    p_i.position,
                    Some(p_i.normal),
                ),
                bvh::Segment {
                    a: (p_j.position + p_j.normal * eps).to_array(),
                    b: (p_i.position + p_i.normal * (side * eps)).to_array(),
                    ..Default::default()
                },
            )
        })
        .unzip()
}

/// A compute pass that answers a batch of [`QueryPair`]s: the visible fraction of each (PCF),
/// or -1 where no texel stands for the sender.
pub struct QueryKernel {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl QueryKernel {
    /// Builds the kernel for CSSMs bound with `cssm`'s layout.
    pub fn new(gpu: &Gpu, cssm: &CssmGpu) -> Self {
        let device = &gpu.device;
        let module = crate::shaders::Shader::Query.create(device);
        let c = wgpu::ShaderStages::COMPUTE;
        let io_layout = layout::bind_group_layout(
            device,
            "cssm query io",
            &[layout::storage(0, true, c), layout::storage(1, false, c)],
        );
        let pipeline = layout::compute_pipeline(
            device,
            "cssm query",
            &module,
            &[&io_layout, &cssm.bind_group_layout],
        );
        Self {
            pipeline,
            layout: io_layout,
        }
    }

    /// Answers `pairs` on the GPU, `repeat` times in one pass (for timing; the answers are the
    /// same each time), and reads the answers back.
    pub fn run(
        &self,
        gpu: &Gpu,
        cssm: &CssmGpu,
        pairs: &[QueryPair],
        timer: Option<&mut crate::common::timestamps::PassTimer>,
    ) -> Result<Vec<f32>, RuntimeError> {
        if pairs.is_empty() {
            return Ok(Vec::new());
        }
        let device = &gpu.device;
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("query pairs"),
            contents: bytemuck::cast_slice(pairs),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let output = answer_buffer(device, "query answers", pairs.len());
        let io = layout::bind_group(
            device,
            "query io",
            &self.layout,
            &[input.as_entire_binding(), output.as_entire_binding()],
        );
        let bytes = dispatch_and_read(
            gpu,
            "cssm query",
            &self.pipeline,
            &[&io, &cssm.bind_group],
            pairs.len(),
            &output,
            timer,
        )?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}

/// Workgroups (x, y) covering `items` threads of 64: a 2D dispatch for large batches (at most
/// 65,535 groups per dimension); kernels index `id.x + id.y * groups.x * 64`.
pub(crate) fn dispatch_size(items: u32) -> (u32, u32) {
    let groups = items.div_ceil(crate::shaders::WORKGROUP_1D);
    if groups <= 65_535 {
        (groups, 1)
    } else {
        (65_535, groups.div_ceil(65_535))
    }
}

/// A storage buffer for one 4-byte answer per item, readable back.
pub(crate) fn answer_buffer(device: &wgpu::Device, label: &str, items: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: 4 * items as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// Runs a one-thread-per-item kernel (indexing `id.x + id.y * groups.x * 64`) over `items`
/// with `bind_groups` at groups 0, 1, ..., timed as `label`, and reads back `answers` (4 bytes
/// per item).
pub(crate) fn dispatch_and_read(
    gpu: &Gpu,
    label: &'static str,
    pipeline: &wgpu::ComputePipeline,
    bind_groups: &[&wgpu::BindGroup],
    items: usize,
    answers: &wgpu::Buffer,
    mut timer: Option<&mut crate::common::timestamps::PassTimer>,
) -> Result<Vec<u8>, RuntimeError> {
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    let (gx, gy) = dispatch_size(items as u32);
    {
        let timestamp_writes = timer.as_deref_mut().and_then(|t| t.compute(label));
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(label),
            timestamp_writes,
        });
        pass.set_pipeline(pipeline);
        for (i, group) in bind_groups.iter().enumerate() {
            pass.set_bind_group(i as u32, *group, &[]);
        }
        pass.dispatch_workgroups(gx, gy, 1);
    }
    if let Some(t) = timer.as_deref() {
        t.resolve(&mut encoder);
    }
    gpu.queue.submit([encoder.finish()]);
    readback::read_buffer(&gpu.device, &gpu.queue, answers, 0, 4 * items as u64)
}

#[cfg(test)]
mod tests {
    use crate::shaders::{Shader, tests::check_struct};
    use std::mem::{offset_of, size_of};

    #[test]
    fn query_pair_layout_matches_wgsl() {
        let module = crate::shaders::tests::module(Shader::Query);
        check_struct(
            &module,
            "QueryPair",
            size_of::<super::QueryPair>(),
            &[
                ("sender_bary", offset_of!(super::QueryPair, sender_bary)),
                (
                    "sender_triangle",
                    offset_of!(super::QueryPair, sender_triangle),
                ),
                ("receiver", offset_of!(super::QueryPair, receiver)),
                (
                    "receiver_normal",
                    offset_of!(super::QueryPair, receiver_normal),
                ),
            ],
        );
    }

    #[test]
    fn gather_layouts_match_wgsl() {
        use super::gather::{GatherParams, Receiver};
        let module = crate::shaders::tests::module(Shader::Gather);
        check_struct(
            &module,
            "Receiver",
            size_of::<Receiver>(),
            &[
                ("position", offset_of!(Receiver, position)),
                ("first_sender", offset_of!(Receiver, first_sender)),
                ("normal", offset_of!(Receiver, normal)),
            ],
        );
        check_struct(
            &module,
            "GatherParams",
            size_of::<GatherParams>(),
            &[
                ("senders", offset_of!(GatherParams, senders)),
                ("texel_count", offset_of!(GatherParams, texel_count)),
            ],
        );
    }

    #[test]
    fn bvh_layouts_match_wgsl() {
        use super::bvh::{GpuBvhNode, Segment};
        let module = crate::shaders::tests::module(Shader::Bvh);
        check_struct(
            &module,
            "BvhNode",
            size_of::<GpuBvhNode>(),
            &[
                ("min", offset_of!(GpuBvhNode, min)),
                ("prim_count", offset_of!(GpuBvhNode, prim_count)),
                ("max", offset_of!(GpuBvhNode, max)),
                ("first_index", offset_of!(GpuBvhNode, first_index)),
            ],
        );
        check_struct(
            &module,
            "Segment",
            size_of::<Segment>(),
            &[("a", offset_of!(Segment, a)), ("b", offset_of!(Segment, b))],
        );
    }
}
