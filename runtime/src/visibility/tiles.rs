//! A benchmark kernel in the access pattern of the final gather, one query a thread
//! (`tiles.wgsl`, issue 48 item 4): a G-buffer's pixels in 8x8 tiles, one workgroup a tile and a
//! sender texel, each thread the two-ended query between its pixel and the sender, as the final
//! gather asks it of a node (§4.4). Millions of threads: 640x480 pixels and 32 senders are
//! 9,830,400. The pixels come from a camera's primary rays on the CPU ([`tile_pixels`]), in the
//! order the kernel's tiles read them; its CPU twin is [`tiles_cpu`], which a test holds to the
//! kernel answer for answer and count for count.

use bytemuck::{Pod, Zeroable};
use cssm_formats::{
    Scene,
    visibility::{QueryTally, VisibilityQuery},
};
use cssm_raycast::SceneBvh;
use glam::Vec3;
use wgpu::util::DeviceExt;

use super::KernelWork;
use crate::{
    Gpu, RuntimeError,
    common::{camera::View, layout, readback, timestamps::PassTimer},
    load::CssmGpu,
    shaders::{CssmShape, WORKGROUP_2D},
};

/// `visibility/tiles.wgsl`, the benchmark kernel of a G-buffer's tiles querying senders, one query
/// a thread, with the CSSM library.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("visibility tiles", "visibility/tiles.wgsl");

/// Pixels of a tile: one workgroup of [`WORKGROUP_2D`]².
pub const TILE_PIXELS: usize = (WORKGROUP_2D * WORKGROUP_2D) as usize;

/// A G-buffer pixel: the surface point the camera sees there (`TilePixel` in `tiles.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct TilePixel {
    /// Surface position.
    pub position: [f32; 3],
    /// Scene triangle, `u32::MAX` where the pixel sees none (or pads a partial tile).
    pub triangle: u32,
    /// Surface normal, facing the camera.
    pub normal: [f32; 3],
    /// Unused.
    pub _pad0: u32,
    /// Barycentric coordinates on the triangle.
    pub bary: [f32; 3],
    /// Unused.
    pub _pad1: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
struct TileParams {
    pixels: u32,
    first: u32,
    stride: u32,
    texel_count: u32,
}

/// The senders of a launch: `count` texels spread evenly over the file's `texel_count`
/// (texel `(first + k * stride) % texel_count` for sender `k`), as the nodes of a cut spread
/// over the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileSenders {
    /// First texel.
    pub first: u32,
    /// Texels between senders.
    pub stride: u32,
    /// Senders.
    pub count: u32,
}

impl TileSenders {
    /// `count` senders spread over `texel_count` texels.
    pub fn spread(texel_count: u32, count: u32) -> Self {
        let stride = (texel_count / count.max(1)).max(1);
        Self {
            first: stride / 2,
            stride,
            count,
        }
    }

    /// Sender `k`'s texel.
    pub fn texel(&self, k: u32, texel_count: u32) -> u32 {
        (self.first + k * self.stride) % texel_count.max(1)
    }
}

/// The G-buffer of `view` over `scene` by primary rays through the pixel centres, in tile
/// order: tile `tx + ty * tiles_x` holds entries `64 * tile ..`, pixel `(x, y)` of the tile at
/// `y * 8 + x` (a partial tile padded with empty pixels). Returns the pixels and the tiles'
/// count across.
pub fn tile_pixels(scene: &Scene, view: &View) -> (Vec<TilePixel>, u32) {
    let bvh = SceneBvh::new(scene);
    let side = WORKGROUP_2D;
    let (tiles_x, tiles_y) = (view.width.div_ceil(side), view.height.div_ceil(side));
    let mut pixels = vec![
        TilePixel {
            triangle: u32::MAX,
            ..Default::default()
        };
        (tiles_x * tiles_y) as usize * TILE_PIXELS
    ];
    for y in 0..view.height {
        for x in 0..view.width {
            let tile = (y / side) * tiles_x + x / side;
            let entry = tile as usize * TILE_PIXELS + ((y % side) * side + x % side) as usize;
            let dir = view.primary_ray(x, y);
            let Some((t, triangle)) = bvh.closest_hit(view.eye, dir, 0.0, f32::INFINITY) else {
                continue;
            };
            let p = view.eye + dir * t;
            let [a, b, c] = scene.triangle(triangle as usize);
            pixels[entry] = TilePixel {
                position: p.to_array(),
                triangle,
                normal: crate::direct::cpu::facing_normal(scene, triangle, view.eye - p).to_array(),
                bary: crate::direct::cpu::barycentric(p, a, b, c),
                ..Default::default()
            };
        }
    }
    (pixels, tiles_x)
}

/// CPU twin of the kernel: the answer of every (sender `k`, pixel) at `k * pixels.len() +
/// pixel`, -1 where the pixel sees nothing or no texel stands for either end. `tally(k, pixel)`
/// gives the tally each query tells its loads to.
pub fn tiles_cpu<T: QueryTally>(
    query: &VisibilityQuery,
    pixels: &[TilePixel],
    senders: TileSenders,
    mut tally: impl FnMut(u32, usize) -> T,
) -> Vec<(f32, T)> {
    let texel_count = query.file().texels.len() as u32;
    let mut out = Vec::with_capacity(pixels.len() * senders.count as usize);
    for k in 0..senders.count {
        let texel = senders.texel(k, texel_count);
        let y = &query.file().texels[texel as usize];
        for (i, q) in pixels.iter().enumerate() {
            let mut t = tally(k, i);
            let answer = tile_query(query, q, texel, y.pos(), y.nrm(), &mut t);
            out.push((answer, t));
        }
    }
    out
}

/// One thread's query: pixel `q` and sender `texel` at `y` (normal `n_y`), -1 as the kernel,
/// its loads told to `tally`.
pub fn tile_query(
    query: &VisibilityQuery,
    q: &TilePixel,
    texel: u32,
    y: Vec3,
    n_y: Vec3,
    tally: &mut impl QueryTally,
) -> f32 {
    if q.triangle == u32::MAX {
        return -1.0;
    }
    let Some(point) = query.atlas_point(q.triangle as usize, q.bary) else {
        return -1.0;
    };
    let own = query
        .sender_slots_at(point, Default::default(), tally)
        .map(Vec::from)
        .unwrap_or_default();
    query
        .visibility_between_counted(
            &own,
            q.position.into(),
            q.normal.into(),
            &[(texel, 1.0)],
            y,
            n_y,
            tally,
        )
        .unwrap_or(-1.0)
}

/// The tile kernel.
pub struct TileKernel {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    counting: bool,
}

impl TileKernel {
    /// The kernel for `cssm`'s layout; `counting`: composed with the query's counters
    /// ([`Self::run`] then returns each query's work).
    pub fn new(gpu: &Gpu, cssm: &CssmGpu, counting: bool) -> Self {
        let device = &gpu.device;
        let shape = CssmShape {
            counters: counting,
            ..cssm.shape()
        };
        let module = SHADER.create_for(device, shape);
        let c = wgpu::ShaderStages::COMPUTE;
        let mut entries = vec![
            layout::storage(0, true, c),
            layout::storage(1, false, c),
            layout::uniform(2, c),
        ];
        if counting {
            entries.push(layout::storage(3, false, c));
        }
        let layout = layout::bind_group_layout(device, "cssm tiles io", &entries);
        let pipeline = layout::compute_pipeline(
            device,
            "cssm tiles",
            &module,
            &[&layout, &cssm.bind_group_layout],
        );
        Self {
            pipeline,
            layout,
            counting,
        }
    }

    /// Answers every (sender, pixel) of `pixels` (in tiles of 64, `tiles_x` across) and
    /// `senders`: the answers at `k * pixels.len() + pixel`, and with counters each query's work.
    ///
    /// # Errors
    /// The pixels or answers exceed the device's storage binding limit, or the readback fails.
    pub fn run(
        &self,
        gpu: &Gpu,
        cssm: &CssmGpu,
        pixels: &[TilePixel],
        tiles_x: u32,
        senders: TileSenders,
        mut timer: Option<&mut PassTimer>,
    ) -> Result<(Vec<f32>, Vec<KernelWork>), RuntimeError> {
        let queries = pixels.len() * senders.count as usize;
        if queries == 0 || cssm.params.map_count == 0 {
            return Ok((vec![-1.0; queries], Vec::new()));
        }
        let device = &gpu.device;
        crate::load::limit_check(
            device,
            "the tile pixels",
            std::mem::size_of_val(pixels) as u64,
        )?;
        crate::load::limit_check(device, "the tile answers", 4 * queries as u64)?;
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("tile pixels"),
            contents: bytemuck::cast_slice(pixels),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let output = super::answer_buffer(device, "tile answers", queries);
        let work = self
            .counting
            .then(|| super::answer_buffer(device, "tile work", 4 * queries));
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("tile params"),
            contents: bytemuck::bytes_of(&TileParams {
                pixels: pixels.len() as u32,
                first: senders.first,
                stride: senders.stride,
                texel_count: cssm.params.map_count,
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let mut resources = vec![
            input.as_entire_binding(),
            output.as_entire_binding(),
            params.as_entire_binding(),
        ];
        resources.extend(work.iter().map(wgpu::Buffer::as_entire_binding));
        let io = layout::bind_group(device, "cssm tiles io", &self.layout, &resources);
        let tiles = (pixels.len() / TILE_PIXELS) as u32;
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let timestamp_writes = timer.as_deref_mut().and_then(|t| t.compute("cssm tiles"));
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("cssm tiles"),
                timestamp_writes,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &io, &[]);
            pass.set_bind_group(1, &cssm.bind_group, &[]);
            let rows = tiles.div_ceil(tiles_x.max(1));
            pass.dispatch_workgroups(tiles_x.max(1), rows, senders.count);
        }
        if let Some(t) = timer.as_deref() {
            t.resolve(&mut encoder);
        }
        gpu.queue.submit([encoder.finish()]);
        let answers = readback::read_buffer(device, &gpu.queue, &output, 0, output.size())?;
        let work = match &work {
            Some(buffer) => {
                let bytes = readback::read_buffer(device, &gpu.queue, buffer, 0, buffer.size())?;
                bytemuck::cast_slice(&bytes).to_vec()
            }
            None => Vec::new(),
        };
        Ok((bytemuck::cast_slice(&answers).to_vec(), work))
    }
}
