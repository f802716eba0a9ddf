//! The bake's depth cube maps on the GPU (§3.2.1; `cssm bake --device gpu`): every pixel's ray
//! of a batch of texels' cube maps, cast through obvhs' binary BVH in a compute shader
//! (`depth_maps.wgsl`, on the ray casting of `bvh_trace.wgsl`), its hits reduced to what the
//! CPU's `cssm_raycast::SceneBvh::front_dual_hit_beyond` returns. The bake turns those into the
//! pixels' depth intervals with its own code, so both devices share everything after the ray
//! cast. Held against the CPU's ray casts by `tests/gpu/depth_maps.rs`.
//!
//! Why a compute BVH traversal and not the paper's rasterised faces with depth peeling: the bake
//! casts one ray per pixel from a few hundred thousand cube centres, six small faces each, and
//! a rasteriser would draw every face of every texel as its own pass over the scene; the
//! H200 has no ray-tracing cores but its compute throughput dwarfs its raster hardware (the
//! G-buffer pass against the BVH segment kernel's queries per second: reports/runtime.md).

use std::time::Duration;

use bytemuck::{Pod, Zeroable};
use cssm_raycast::FrontHit;
use glam::Vec3;
use obvhs::{BvhBuildParams, aabb::Aabb, bvh2::builder::build_bvh2};
use wgpu::util::DeviceExt;

use std::mem::size_of;

use crate::{Gpu, RuntimeError, common::layout};

/// `visibility/depth_maps.wgsl`, the bake's depth cube maps by ray casting (§3.2.1), with
/// `visibility/bvh_trace.wgsl`.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("depth cube maps", "visibility/depth_maps.wgsl");

/// One texel's cube map as the kernel casts it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct DepthMapTexel {
    /// The cube's centre (the texel's position pushed off its surface by the near distance),
    /// computed by the caller exactly as its CPU renderer does.
    pub centre: [f32; 3],
    /// The shift of the texel's pixel grid along each face's u axis, in pixels
    /// (`cssm_formats::cube::PixelGrid::offset`; 0 on the paper's centred grid).
    pub grid_u: f32,
    /// The texel's unit normal.
    pub normal: [f32; 3],
    /// The shift along each face's v axis, in pixels.
    pub grid_v: f32,
}

/// What every ray of a batch shares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthMapSettings {
    /// Cube-map face resolution N.
    pub resolution: u32,
    /// Hits nearer than this are not seen.
    pub min_hit: f32,
    /// Hits closer together than this are one surface.
    pub separation: f32,
    /// Every hit counts as facing the texel (the paper's second layer: the second hit whichever
    /// way it faces).
    pub every_hit_faces: bool,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct GpuDepthMapParams {
    n: u32,
    texel_count: u32,
    every_hit_faces: u32,
    _pad0: u32,
    min_hit: f32,
    separation: f32,
    _pad1: [f32; 2],
}

/// A pixel's answer as the kernel writes it: the first hit's ray parameter (bit 31 set when its
/// surface faces the texel) and the second's, or [`RECOMPUTE`] in the first word.
pub type PixelHits = [u32; 2];

/// First word of a pixel the CPU must cast itself: the kernel's hit list overflowed (a ray
/// through a vertex of many triangles), or it judged the pixel behind the tangent plane.
pub const RECOMPUTE: u32 = u32::MAX;

/// The kernel's "no hit" (`NONE` in `depth_maps.wgsl`): anything at least this far is none.
const NONE: f32 = 3.0e38;

/// The hits of a pixel's ray, or `None` when the CPU must cast it ([`RECOMPUTE`]).
///
/// ```
/// use cssm_runtime::visibility::depth_maps::{RECOMPUTE, decode};
/// let hit = decode([2.5f32.to_bits() | 1 << 31, 3.0e38f32.to_bits()]).unwrap();
/// assert_eq!((hit.first, hit.first_faces, hit.second), (2.5, true, f32::INFINITY));
/// assert!(decode([RECOMPUTE, 0]).is_none());
/// ```
pub fn decode(hits: PixelHits) -> Option<FrontHit> {
    if hits[0] == RECOMPUTE {
        return None;
    }
    let far = |t: f32| if t >= NONE { f32::INFINITY } else { t };
    Some(FrontHit {
        first: far(f32::from_bits(hits[0] & 0x7fff_ffff)),
        first_faces: hits[0] >> 31 != 0,
        second: far(f32::from_bits(hits[1])),
    })
}

/// A scene's BVH in GPU memory and the depth-map kernel over it.
pub struct DepthMapKernel {
    bvh_group: wgpu::BindGroup,
    io_layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    /// Bytes of nodes, triangles and normals on the GPU.
    pub gpu_bytes: u64,
}

impl DepthMapKernel {
    /// Builds the BVH of `triangles` (corners; `normals` their geometric normals, unnormalised,
    /// front by winding) with every box widened by `box_padding` on each side, as the CPU's
    /// `SceneBvh` widens its boxes so that a traversal meets every hit the watertight test
    /// reports.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] for a BVH deeper than the traversal's stack.
    pub fn new(
        gpu: &Gpu,
        triangles: &[[Vec3; 3]],
        normals: &[Vec3],
        box_padding: f32,
    ) -> Result<Self, RuntimeError> {
        let device = &gpu.device;
        let pad = glam::Vec3A::splat(box_padding);
        let boxes: Vec<Aabb> = triangles
            .iter()
            .map(|t| {
                let (min, max) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
                Aabb::new(glam::Vec3A::from(min) - pad, glam::Vec3A::from(max) + pad)
            })
            .collect();
        let bvh = build_bvh2(
            &boxes,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let (node_buffer, vertex_buffer) = super::bvh::upload(device, &bvh, |i| {
            triangles[i as usize].map(|v| v.to_array())
        })?;
        let bvh_normals: Vec<[f32; 4]> = bvh
            .primitive_indices
            .iter()
            .map(|&i| normals[i as usize].extend(0.0).to_array())
            .collect();
        let normal_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bvh triangle normals"),
            contents: bytemuck::cast_slice(&bvh_normals),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let io_layout = layout::bind_group_layout(
            device,
            "depth maps",
            &[
                layout::uniform(0, c),
                layout::storage(1, true, c),
                layout::storage(2, false, c),
            ],
        );
        let bvh_layout = layout::bind_group_layout(
            device,
            "depth maps bvh",
            &[
                layout::storage(0, true, c),
                layout::storage(1, true, c),
                layout::storage(2, true, c),
            ],
        );
        let bvh_group = layout::bind_group(
            device,
            "depth maps bvh",
            &bvh_layout,
            &[
                node_buffer.as_entire_binding(),
                vertex_buffer.as_entire_binding(),
                normal_buffer.as_entire_binding(),
            ],
        );
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline(
            device,
            "depth cube maps",
            &module,
            &[&io_layout, &bvh_layout],
        );
        Ok(Self {
            bvh_group,
            io_layout,
            pipeline,
            gpu_bytes: node_buffer.size() + vertex_buffer.size() + normal_buffer.size(),
        })
    }

    /// Most texels one [`DepthMapKernel::run`] takes at cube resolution `resolution` on `gpu`:
    /// the answers (8 bytes a pixel) fit one storage binding, and at most 64 MiB, so that the
    /// readback stays a fraction of the GPU's and the host's memory.
    pub fn max_texels(gpu: &Gpu, resolution: u32) -> usize {
        let limit = crate::load::storage_binding_bytes(&gpu.device.limits()).min(64 << 20);
        let per_texel = 6 * u64::from(resolution).pow(2) * 8;
        (limit / per_texel).max(1) as usize
    }

    /// Casts every pixel of `texels`' cube maps: `6 N^2` answers per texel, texel after texel,
    /// pixel `face * N^2 + row * N + col` as `cssm_formats::cube` numbers them.
    ///
    /// # Errors
    /// [`RuntimeError::TooLarge`] for more texels than one storage binding holds the answers
    /// of ([`DepthMapKernel::max_texels`] stays within it), or a GPU failure.
    pub fn run(
        &self,
        gpu: &Gpu,
        texels: &[DepthMapTexel],
        settings: DepthMapSettings,
    ) -> Result<Vec<PixelHits>, RuntimeError> {
        self.run_with(gpu, &mut DepthMapBuffers::default(), texels, settings)
    }

    /// [`DepthMapKernel::run`] in `buffers`, kept from call to call: a bake runs hundreds of
    /// batches, and creating a batch's buffers (its answers twice, on the GPU and the readback
    /// side) for each would cost more than copying its texels in. Kernels of different scenes
    /// may share one set.
    ///
    /// # Errors
    /// As [`DepthMapKernel::run`].
    pub fn run_with(
        &self,
        gpu: &Gpu,
        buffers: &mut DepthMapBuffers,
        texels: &[DepthMapTexel],
        settings: DepthMapSettings,
    ) -> Result<Vec<PixelHits>, RuntimeError> {
        if texels.is_empty() {
            return Ok(Vec::new());
        }
        let device = &gpu.device;
        let pixels = 6 * settings.resolution as usize * settings.resolution as usize;
        let items = texels.len() * pixels;
        let answer_bytes = 8 * items as u64;
        crate::load::limit_check(device, "the depth maps' answers", answer_bytes)?;
        if items > u32::MAX as usize {
            return Err(RuntimeError::TooLarge {
                what: "the depth maps' pixels",
                needed: items as u64,
                limit: u64::from(u32::MAX),
            });
        }
        let params = GpuDepthMapParams {
            n: settings.resolution,
            texel_count: texels.len() as u32,
            every_hit_faces: u32::from(settings.every_hit_faces),
            min_hit: settings.min_hit,
            separation: settings.separation,
            ..Default::default()
        };
        let texel_bytes: &[u8] = bytemuck::cast_slice(texels);
        use wgpu::BufferUsages as U;
        let param_buffer = buffers.params.at_least(
            device,
            "depth map parameters",
            size_of::<GpuDepthMapParams>() as u64,
            U::UNIFORM | U::COPY_DST,
        );
        let texel_buffer = buffers.texels.at_least(
            device,
            "depth map texels",
            texel_bytes.len() as u64,
            U::STORAGE | U::COPY_DST,
        );
        let output = buffers.output.at_least(
            device,
            "depth map hits",
            answer_bytes,
            U::STORAGE | U::COPY_SRC,
        );
        let staging = buffers.staging.at_least(
            device,
            "depth map readback",
            answer_bytes,
            U::MAP_READ | U::COPY_DST,
        );
        gpu.queue
            .write_buffer(param_buffer, 0, bytemuck::bytes_of(&params));
        gpu.queue.write_buffer(texel_buffer, 0, texel_bytes);
        // The bindings cover what this batch uses only: the shader reads its sizes from them.
        fn binding(buffer: &wgpu::Buffer, size: u64) -> wgpu::BindingResource<'_> {
            wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer,
                offset: 0,
                size: wgpu::BufferSize::new(size),
            })
        }
        let io = layout::bind_group(
            device,
            "depth maps",
            &self.io_layout,
            &[
                param_buffer.as_entire_binding(),
                binding(texel_buffer, texel_bytes.len() as u64),
                binding(output, answer_bytes),
            ],
        );
        let mut encoder = super::dispatch(
            gpu,
            "depth cube maps",
            &self.pipeline,
            &[&io, &self.bvh_group],
            items,
            None,
        );
        encoder.copy_buffer_to_buffer(output, 0, staging, 0, answer_bytes);
        gpu.queue.submit([encoder.finish()]);
        crate::common::readback::map_read(device, staging, answer_bytes, |bytes| {
            bytemuck::pod_collect_to_vec(bytes)
        })
    }
}

/// The buffers of [`DepthMapKernel::run_with`], created on first use and grown when a batch
/// needs more.
#[derive(Default)]
pub struct DepthMapBuffers {
    params: Reused,
    texels: Reused,
    output: Reused,
    staging: Reused,
}

/// One buffer kept for the next batch.
#[derive(Default)]
struct Reused(Option<wgpu::Buffer>);

impl Reused {
    /// A buffer of at least `size` bytes: the one kept, or a new one (kept in its place) when
    /// the kept one holds fewer.
    fn at_least(
        &mut self,
        device: &wgpu::Device,
        label: &'static str,
        size: u64,
        usage: wgpu::BufferUsages,
    ) -> &wgpu::Buffer {
        if self.0.as_ref().is_none_or(|b| b.size() < size) {
            self.0 = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            }));
        }
        self.0.as_ref().expect("created above")
    }
}

#[cfg(test)]
mod tests {
    use crate::shaders::tests::check_struct;
    use std::mem::{offset_of, size_of};

    #[test]
    fn layouts_match_wgsl() {
        let module = crate::shaders::tests::module(super::SHADER);
        check_struct(
            &module,
            "DepthMapTexel",
            size_of::<super::DepthMapTexel>(),
            &[
                ("centre", offset_of!(super::DepthMapTexel, centre)),
                ("normal", offset_of!(super::DepthMapTexel, normal)),
            ],
        );
        check_struct(
            &module,
            "DepthMapParams",
            size_of::<super::GpuDepthMapParams>(),
            &[
                ("n", offset_of!(super::GpuDepthMapParams, n)),
                (
                    "every_hit_faces",
                    offset_of!(super::GpuDepthMapParams, every_hit_faces),
                ),
                ("min_hit", offset_of!(super::GpuDepthMapParams, min_hit)),
                (
                    "separation",
                    offset_of!(super::GpuDepthMapParams, separation),
                ),
            ],
        );
    }
}
