//! The baseline the CSSM query competes with: exact segment visibility by traversing obvhs'
//! binary BVH in a compute shader (`bvh.wgsl`; the H100 has no hardware ray queries). Held
//! against the CPU ray casts of `cssm_raycast::SceneBvh` by the test
//! `bvh_kernel_matches_cpu_ray_casts`.

use std::time::Duration;

use bytemuck::{Pod, Zeroable};
use cssm_formats::Scene;
use obvhs::{BvhBuildParams, bvh2::builder::build_bvh2_from_tris};
use wgpu::util::DeviceExt;

use crate::{
    Gpu, RuntimeError,
    common::{layout, timestamps::PassTimer},
};

/// `visibility/bvh.wgsl`, the exact ray-cast baseline, with `visibility/bvh_trace.wgsl`.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("bvh segments", "visibility/bvh.wgsl");

/// Deepest BVH the kernel's traversal stack holds.
pub const MAX_DEPTH: usize = 60;

/// A BVH node as `bvh.wgsl` reads it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub(crate) struct GpuBvhNode {
    pub(crate) min: [f32; 3],
    pub(crate) prim_count: u32,
    pub(crate) max: [f32; 3],
    pub(crate) first_index: u32,
}

/// A segment whose interior is tested for hits.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Segment {
    /// Start.
    pub a: [f32; 3],
    /// Unused.
    pub _pad0: u32,
    /// End.
    pub b: [f32; 3],
    /// Unused.
    pub _pad1: u32,
}

/// A scene's BVH in GPU memory and the segment kernel over it.
pub struct BvhKernel {
    bind_group: wgpu::BindGroup,
    io_layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    /// Bytes of nodes and triangles on the GPU.
    pub gpu_bytes: u64,
}

impl BvhKernel {
    /// Builds the BVH of `scene` (obvhs PLOC, medium quality, as the bake's) and the kernel.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] for a BVH deeper than [`MAX_DEPTH`].
    pub fn new(gpu: &Gpu, scene: &Scene) -> Result<Self, RuntimeError> {
        let device = &gpu.device;
        let tris = cssm_raycast::scene_triangles(scene);
        let bvh = build_bvh2_from_tris(
            &tris,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let (node_buffer, vertex_buffer) = upload(device, &bvh, |i| {
            let t = &tris[i as usize];
            [t.v0, t.v1, t.v2].map(|v| [v.x, v.y, v.z])
        })?;
        let c = wgpu::ShaderStages::COMPUTE;
        let io_layout = layout::bind_group_layout(
            device,
            "segments",
            &[layout::storage(0, true, c), layout::storage(1, false, c)],
        );
        let bvh_layout = layout::bind_group_layout(
            device,
            "bvh",
            &[layout::storage(0, true, c), layout::storage(1, true, c)],
        );
        let bind_group = layout::bind_group(
            device,
            "bvh",
            &bvh_layout,
            &[
                node_buffer.as_entire_binding(),
                vertex_buffer.as_entire_binding(),
            ],
        );
        let module = SHADER.create(device);
        let pipeline =
            layout::compute_pipeline(device, "bvh segments", &module, &[&io_layout, &bvh_layout]);
        Ok(Self {
            bind_group,
            io_layout,
            pipeline,
            gpu_bytes: node_buffer.size() + vertex_buffer.size(),
        })
    }

    /// Tests `segments` on the GPU: `true` where a segment's interior hits nothing.
    pub fn run(
        &self,
        gpu: &Gpu,
        segments: &[Segment],
        timer: Option<&mut PassTimer>,
    ) -> Result<Vec<bool>, RuntimeError> {
        if segments.is_empty() {
            return Ok(Vec::new());
        }
        let device = &gpu.device;
        crate::load::limit_check(
            device,
            "the segments",
            std::mem::size_of_val(segments) as u64,
        )?;
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("segments"),
            contents: bytemuck::cast_slice(segments),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let output = super::answer_buffer(device, "segments clear", segments.len());
        let io = layout::bind_group(
            device,
            "segments",
            &self.io_layout,
            &[input.as_entire_binding(), output.as_entire_binding()],
        );
        let bytes = super::dispatch_and_read(
            gpu,
            "bvh segments",
            &self.pipeline,
            &[&io, &self.bind_group],
            segments.len(),
            &output,
            timer,
        )?;
        Ok(bytemuck::cast_slice::<u8, u32>(&bytes)
            .iter()
            .map(|&c| c != 0)
            .collect())
    }
}

/// The nodes of `bvh` and the corners of its triangles in its primitive order
/// (`corners(i)` of the triangle of input index `i`), in storage buffers as `cssm::bvh`
/// (`bvh_trace.wgsl`) reads them.
///
/// # Errors
/// [`RuntimeError::Unsupported`] for a BVH deeper than [`MAX_DEPTH`].
pub(crate) fn upload(
    device: &wgpu::Device,
    bvh: &obvhs::bvh2::Bvh2,
    corners: impl Fn(u32) -> [[f32; 3]; 3],
) -> Result<(wgpu::Buffer, wgpu::Buffer), RuntimeError> {
    let nodes: Vec<GpuBvhNode> = bvh
        .nodes
        .iter()
        .map(|n| GpuBvhNode {
            min: n.aabb.min.to_array(),
            prim_count: n.prim_count,
            max: n.aabb.max.to_array(),
            first_index: n.first_index,
        })
        .collect();
    let depth = depth(&nodes, 0);
    if depth > MAX_DEPTH {
        return Err(RuntimeError::Unsupported(format!(
            "BVH of {} triangles is {depth} levels deep; the GPU traversal holds {MAX_DEPTH}",
            bvh.primitive_indices.len()
        )));
    }
    let vertices: Vec<[f32; 4]> = bvh
        .primitive_indices
        .iter()
        .flat_map(|&i| corners(i).map(|[x, y, z]| [x, y, z, 0.0]))
        .collect();
    let node_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("bvh nodes"),
        contents: bytemuck::cast_slice(&nodes),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let vertex_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("bvh triangles"),
        contents: bytemuck::cast_slice(&vertices),
        usage: wgpu::BufferUsages::STORAGE,
    });
    Ok((node_buffer, vertex_buffer))
}

/// Levels below `node` (1 for a leaf).
fn depth(nodes: &[GpuBvhNode], root: u32) -> usize {
    let mut deepest = 0;
    let mut stack = vec![(root, 1usize)];
    while let Some((i, d)) = stack.pop() {
        deepest = deepest.max(d);
        let n = &nodes[i as usize];
        if n.prim_count == 0 {
            stack.push((n.first_index, d + 1));
            stack.push((n.first_index + 1, d + 1));
        }
    }
    deepest
}
