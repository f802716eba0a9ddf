//! Visibility queries on the GPU (§3.2.2): the WGSL library `cssm.wgsl`, which any shader can
//! include to call `cssm_visible` / `cssm_visibility` / `cssm_visibility_texel` against a
//! [`CssmGpu`] bind group, and [`QueryKernel`], a compute pass that answers
//! a batch of queries (for tests against the CPU reference and for benchmarks).
//!
//! The library computes exactly what `cssm_formats::visibility::VisibilityQuery` computes; the
//! test `gpu_matches_cpu_reference` holds the two together on 100,000 random pairs. They can
//! differ only where floating-point rounding of the GPU (fused multiply-adds, its division)
//! moves a depth comparison across its threshold.
//!
//! Moving rigid objects (§3.3): [`moving`] holds their query (`moving.wgsl`) and bind group;
//! `posed.wgsl` (`cssm::posed::posed_texel`) puts an atlas texel where its object's motion
//! puts it, for the passes that read texel geometry.

pub mod bvh;
pub mod depth_maps;
pub mod gather;
pub mod moving;
pub mod tiles;

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[
        QUERY_SHADER,
        gather::SHADER,
        tiles::SHADER,
        moving::SHADER,
        bvh::SHADER,
        depth_maps::SHADER,
    ],
    libraries: &[
        crate::shaders::library!("visibility/cssm.wgsl"),
        crate::shaders::library!("visibility/moving.wgsl"),
        crate::shaders::library!("visibility/posed.wgsl"),
        crate::shaders::library!("visibility/bvh_trace.wgsl"),
    ],
};

use bytemuck::{Pod, Zeroable};
use cssm_formats::visibility::QueryWork;
use glam::Vec3;
use wgpu::util::DeviceExt;

use crate::{
    Gpu, RuntimeError,
    common::{layout, readback},
    gpu_types::TYPES_WGSL,
    load::CssmGpu,
};

/// `visibility/query.wgsl`, the batch query kernel, with the CSSM library.
pub const QUERY_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("visibility query", "visibility/query.wgsl");

/// The WGSL visibility library as plain WGSL, its bindings at `@group(group)`, composed for a
/// file of shape `shape` ([`CssmGpu::shape`]; or call [`CssmGpu::library_wgsl`]), preceded by
/// the shared struct declarations (`types.wgsl`): append your own shader code to it. This is for
/// a shader of your own composed without naga_oil; with naga_oil, add the libraries of
/// [`crate::shaders::composer`] and `#import cssm::visibility::{cssm_visible, ...}` as the
/// runtime's own modules do. Here the lines naga_oil reads (`#define_import_path`, `#import`)
/// are dropped, the bind group and the search's steps filled in and the library's
/// `#if NAME > K` blocks kept or dropped by the shape's definitions.
pub fn library_wgsl(group: u32, shape: crate::shaders::CssmShape) -> String {
    plain_wgsl(&[TYPES_WGSL, include_str!("cssm.wgsl")], group, shape)
}

/// `sources`, in order, as plain WGSL composed for `shape` with the CSSM bindings at
/// `@group(group)`, as [`library_wgsl`] composes the library: naga_oil's `#define_import_path`
/// and `#import` lines dropped, `#{CSSM_GROUP}` and `#{CSSM_SEARCH_STEPS}` filled in, the
/// `#if NAME > K` blocks over the shape's definitions kept or dropped. For tools that compile
/// a version of the library of their own (the lab's instruction counts of the query).
///
/// # Panics
/// On an `#if` that is not `NAME > K` over a definition of the shape (a bug of the source).
pub fn plain_wgsl(sources: &[&str], group: u32, shape: crate::shaders::CssmShape) -> String {
    let defs = [
        ("CSSM_RUN_BINDINGS", shape.run_bindings),
        ("CSSM_SEARCH_STEPS", shape.search_steps),
        ("CSSM_SEARCH_LOOP", u32::from(shape.search_loop)),
        ("CSSM_COUNTERS", u32::from(shape.counters)),
    ];
    let holds = |condition: &str| -> bool {
        let (name, k) = condition
            .split_once(" > ")
            .expect("the library's #if compares a definition with a number");
        let k: u32 = k.trim().parse().expect("the library's #if has a number");
        let (_, value) = defs
            .iter()
            .find(|(n, _)| *n == name.trim())
            .expect("the library's #if names a definition of the shape");
        *value > k
    };
    // Whether each enclosing `#if` holds; a line is kept when all do.
    let mut open: Vec<bool> = Vec::new();
    let mut out = String::new();
    for line in sources.iter().flat_map(|source| source.lines()) {
        let directive = line.trim_start();
        if let Some(condition) = directive.strip_prefix("#if ") {
            open.push(holds(condition));
        } else if directive.starts_with("#else") {
            if let Some(last) = open.last_mut() {
                *last = !*last;
            }
        } else if directive.starts_with("#endif") {
            open.pop();
        } else if !directive.starts_with("#define_import_path")
            && !directive.starts_with("#import")
            && open.iter().all(|&kept| kept)
        {
            out.push_str(
                &line
                    .replace("#{CSSM_GROUP}", &group.to_string())
                    .replace("#{CSSM_SEARCH_STEPS}", &shape.search_steps.to_string()),
            );
            out.push('\n');
        }
    }
    out
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
    /// Composed with the query's work counters ([`Self::counting`]).
    counting: bool,
}

/// The work of one query as the kernel counted it (`CssmWork` in `visibility/cssm.wgsl`): the
/// GPU's side of `cssm_formats::visibility::QueryWork`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct KernelWork {
    /// Pixel tests that read the run data.
    pub taps: u32,
    /// Binary-search steps that loaded a run.
    pub search_steps: u32,
    /// Texel records loaded for the answers.
    pub texel_loads: u32,
    /// Atlas grid cells and texels' charts read, finding the senders.
    pub sender_loads: u32,
}

impl From<QueryWork> for KernelWork {
    /// What the kernel's counters hold of the CPU twin's count of one query (the triangles'
    /// coordinates it does not count).
    fn from(w: QueryWork) -> Self {
        let count = |n: u64| u32::try_from(n).unwrap_or(u32::MAX);
        Self {
            taps: count(w.taps),
            search_steps: count(w.search_steps),
            texel_loads: count(w.texel_loads),
            sender_loads: count(w.sender_loads),
        }
    }
}

impl From<KernelWork> for QueryWork {
    /// The kernel's counters as the CPU twin counts them (no triangles' coordinates).
    fn from(w: KernelWork) -> Self {
        Self {
            taps: w.taps.into(),
            search_steps: w.search_steps.into(),
            texel_loads: w.texel_loads.into(),
            sender_loads: w.sender_loads.into(),
            triangle_loads: 0,
        }
    }
}

impl QueryKernel {
    /// Builds the kernel for CSSMs bound with `cssm`'s layout.
    pub fn new(gpu: &Gpu, cssm: &CssmGpu) -> Self {
        Self::build(gpu, cssm, false)
    }

    /// [`Self::new`] composed with the query's work counters: [`Self::run_counted`] reads back
    /// what each query did. For tests and the benchmarks' counts; the counters cost time.
    pub fn counting(gpu: &Gpu, cssm: &CssmGpu) -> Self {
        Self::build(gpu, cssm, true)
    }

    fn build(gpu: &Gpu, cssm: &CssmGpu, counting: bool) -> Self {
        let device = &gpu.device;
        let shape = crate::shaders::CssmShape {
            counters: counting,
            ..cssm.shape()
        };
        let module = QUERY_SHADER.create_for(device, shape);
        let c = wgpu::ShaderStages::COMPUTE;
        let mut entries = vec![layout::storage(0, true, c), layout::storage(1, false, c)];
        if counting {
            entries.push(layout::storage(2, false, c));
        }
        let io_layout = layout::bind_group_layout(device, "cssm query io", &entries);
        let pipeline = layout::compute_pipeline(
            device,
            "cssm query",
            &module,
            &[&io_layout, &cssm.bind_group_layout],
        );
        Self {
            pipeline,
            layout: io_layout,
            counting,
        }
    }

    /// Answers `pairs` on the GPU and reads the answers back.
    ///
    /// # Errors
    /// The pairs exceed the device's storage binding limit, or the readback fails.
    pub fn run(
        &self,
        gpu: &Gpu,
        cssm: &CssmGpu,
        pairs: &[QueryPair],
        timer: Option<&mut crate::common::timestamps::PassTimer>,
    ) -> Result<Vec<f32>, RuntimeError> {
        Ok(self.run_with_work(gpu, cssm, pairs, timer)?.0)
    }

    /// [`Self::run`] on a [`Self::counting`] kernel: the answers and each query's work.
    ///
    /// # Errors
    /// As [`Self::run`]; [`RuntimeError::Unsupported`] on a kernel built without counters.
    pub fn run_counted(
        &self,
        gpu: &Gpu,
        cssm: &CssmGpu,
        pairs: &[QueryPair],
    ) -> Result<(Vec<f32>, Vec<KernelWork>), RuntimeError> {
        if !self.counting {
            return Err(RuntimeError::Unsupported(
                "run_counted needs a kernel built by QueryKernel::counting".into(),
            ));
        }
        self.run_with_work(gpu, cssm, pairs, None)
    }

    fn run_with_work(
        &self,
        gpu: &Gpu,
        cssm: &CssmGpu,
        pairs: &[QueryPair],
        timer: Option<&mut crate::common::timestamps::PassTimer>,
    ) -> Result<(Vec<f32>, Vec<KernelWork>), RuntimeError> {
        if pairs.is_empty() {
            return Ok((Vec::new(), Vec::new()));
        }
        let device = &gpu.device;
        crate::load::limit_check(
            device,
            "the query pairs",
            std::mem::size_of_val(pairs) as u64,
        )?;
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("query pairs"),
            contents: bytemuck::cast_slice(pairs),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let output = answer_buffer(device, "query answers", pairs.len());
        let work = self
            .counting
            .then(|| answer_buffer(device, "query work", 4 * pairs.len()));
        let mut resources = vec![input.as_entire_binding(), output.as_entire_binding()];
        resources.extend(work.iter().map(wgpu::Buffer::as_entire_binding));
        let io = layout::bind_group(device, "query io", &self.layout, &resources);
        let encoder = dispatch(
            gpu,
            "cssm query",
            &self.pipeline,
            &[&io, &cssm.bind_group],
            pairs.len(),
            timer,
        );
        gpu.queue.submit([encoder.finish()]);
        let answers = readback::read_buffer(&gpu.device, &gpu.queue, &output, 0, output.size())?;
        let work = match &work {
            Some(buffer) => {
                let bytes =
                    readback::read_buffer(&gpu.device, &gpu.queue, buffer, 0, buffer.size())?;
                bytemuck::cast_slice(&bytes).to_vec()
            }
            None => Vec::new(),
        };
        Ok((bytemuck::cast_slice(&answers).to_vec(), work))
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
/// with `bind_groups` at groups 0, 1, ..., timed as `label`, and reads back the whole of
/// `answers`.
pub(crate) fn dispatch_and_read(
    gpu: &Gpu,
    label: &'static str,
    pipeline: &wgpu::ComputePipeline,
    bind_groups: &[&wgpu::BindGroup],
    items: usize,
    answers: &wgpu::Buffer,
    timer: Option<&mut crate::common::timestamps::PassTimer>,
) -> Result<Vec<u8>, RuntimeError> {
    let encoder = dispatch(gpu, label, pipeline, bind_groups, items, timer);
    gpu.queue.submit([encoder.finish()]);
    readback::read_buffer(&gpu.device, &gpu.queue, answers, 0, answers.size())
}

/// Encodes one invocation of `pipeline` per item (timed by `timer` when given).
pub(crate) fn dispatch(
    gpu: &Gpu,
    label: &'static str,
    pipeline: &wgpu::ComputePipeline,
    bind_groups: &[&wgpu::BindGroup],
    items: usize,
    mut timer: Option<&mut crate::common::timestamps::PassTimer>,
) -> wgpu::CommandEncoder {
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
    encoder
}

#[cfg(test)]
mod tests {
    use crate::shaders::tests::check_struct;
    use std::mem::{offset_of, size_of};

    #[test]
    fn query_pair_layout_matches_wgsl() {
        let module = crate::shaders::tests::module(super::QUERY_SHADER);
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
    fn moving_layouts_match_wgsl() {
        use super::moving::{GpuCsm, GpuPlacement, MovingEnd, MovingPair};
        let module = crate::shaders::tests::module(crate::visibility::moving::SHADER);
        // The library's own structs, which the composed module names by their module: its
        // struct declarations alone.
        let source = include_str!("moving.wgsl");
        let structs: String = source
            .split("\nstruct ")
            .skip(1)
            .map(|s| format!("struct {}}}\n", &s[..s.find('}').expect("struct ends")]))
            .collect();
        let library = naga::front::wgsl::parse_str(&structs).expect("the structs parse");
        check_struct(
            &module,
            "MovingEnd",
            size_of::<MovingEnd>(),
            &[
                ("bary", offset_of!(MovingEnd, bary)),
                ("triangle", offset_of!(MovingEnd, triangle)),
                ("position", offset_of!(MovingEnd, position)),
                ("object", offset_of!(MovingEnd, object)),
                ("normal", offset_of!(MovingEnd, normal)),
            ],
        );
        check_struct(
            &module,
            "MovingPair",
            size_of::<MovingPair>(),
            &[
                ("a", offset_of!(MovingPair, a)),
                ("b", offset_of!(MovingPair, b)),
            ],
        );
        check_struct(
            &library,
            "ObjectPlacement",
            size_of::<GpuPlacement>(),
            &[
                ("to_baked_x", offset_of!(GpuPlacement, to_baked)),
                ("normal_x", offset_of!(GpuPlacement, normal)),
                ("to_object_x", offset_of!(GpuPlacement, to_object)),
                ("group", offset_of!(GpuPlacement, group)),
            ],
        );
        check_struct(
            &library,
            "Csm",
            size_of::<GpuCsm>(),
            &[
                ("center", offset_of!(GpuCsm, center)),
                ("radius", offset_of!(GpuCsm, radius)),
                ("directions", offset_of!(GpuCsm, directions)),
                ("resolution", offset_of!(GpuCsm, resolution)),
                ("object", offset_of!(GpuCsm, object)),
                ("cells_base", offset_of!(GpuCsm, cells_base)),
                ("offsets_base", offset_of!(GpuCsm, offsets_base)),
                ("runs_base", offset_of!(GpuCsm, runs_base)),
            ],
        );
    }

    #[test]
    fn gather_layouts_match_wgsl() {
        use super::gather::{GatherParams, Receiver};
        let module = crate::shaders::tests::module(crate::visibility::gather::SHADER);
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

    /// The tile kernel's pixel layout, and its module with the counters and the looped search.
    #[test]
    fn tile_layouts_match_wgsl() {
        use super::tiles::TilePixel;
        let module = crate::shaders::tests::module(crate::visibility::tiles::SHADER);
        check_struct(
            &module,
            "TilePixel",
            size_of::<TilePixel>(),
            &[
                ("position", offset_of!(TilePixel, position)),
                ("triangle", offset_of!(TilePixel, triangle)),
                ("normal", offset_of!(TilePixel, normal)),
                ("bary", offset_of!(TilePixel, bary)),
            ],
        );
        for (counters, search_loop) in [(true, false), (true, true), (false, true)] {
            let shape = crate::shaders::CssmShape {
                counters,
                search_loop,
                search_steps: 9,
                ..Default::default()
            };
            for shader in [
                super::QUERY_SHADER,
                crate::visibility::tiles::SHADER,
                crate::lightcuts::FINAL_GATHER_SHADER,
            ] {
                let module = shader.module_for(shape).unwrap_or_else(|e| panic!("{e}"));
                naga::valid::Validator::new(
                    naga::valid::ValidationFlags::all(),
                    crate::shaders::tests::CAPABILITIES,
                )
                .validate(&module)
                .unwrap_or_else(|e| panic!("{} {shape:?}: {e:?}", shader.label()));
            }
        }
    }

    #[test]
    fn bvh_layouts_match_wgsl() {
        use super::bvh::{GpuBvhNode, Segment};
        let module = crate::shaders::tests::module(crate::visibility::bvh::SHADER);
        // Declared by the library `cssm::bvh`: naga_oil decorates its name.
        let node = naga_oil::compose::Composer::decorated_name(Some("cssm::bvh"), "BvhNode");
        check_struct(
            &module,
            &node,
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

    /// The modules importing the moving objects' query compose and validate for every number of
    /// CSMs the GPU query takes.
    #[test]
    fn moving_modules_compose_for_every_csm_count() {
        use crate::visibility::moving::MOVING_MAX_CSMS;
        for shader in [
            crate::visibility::moving::SHADER,
            crate::radiosity::GATHER_SHADER,
            crate::lightcuts::FINAL_GATHER_SHADER,
        ] {
            for csms in 0..=MOVING_MAX_CSMS as u32 {
                let module = shader
                    .module_for_scene(Default::default(), csms)
                    .unwrap_or_else(|e| panic!("{} for {csms}: {e}", shader.label()));
                naga::valid::Validator::new(
                    naga::valid::ValidationFlags::all(),
                    crate::shaders::tests::CAPABILITIES,
                )
                .validate(&module)
                .unwrap_or_else(|e| panic!("{} for {csms}: {e:?}", shader.label()));
            }
        }
    }

    /// The storage bindings of the CSSM group a module declares.
    fn cssm_bindings(module: &naga::Module) -> Vec<u32> {
        let mut bindings: Vec<u32> = module
            .global_variables
            .iter()
            .filter_map(|(_, v)| v.binding.as_ref())
            .filter(|b| b.group == crate::shaders::CSSM_GROUP)
            .map(|b| b.binding)
            .collect();
        bindings.sort_unstable();
        bindings
    }

    /// Every module that queries the CSSM composes and validates for runs spread over 1 to
    /// MAX_RUN_BINDINGS bindings, and declares exactly the bindings the loader's layout has.
    #[test]
    fn query_modules_compose_for_every_run_binding_count() {
        use crate::{load::MAX_RUN_BINDINGS, shaders::tests::CAPABILITIES};
        for shader in [
            super::QUERY_SHADER,
            crate::visibility::gather::SHADER,
            crate::visibility::tiles::SHADER,
            crate::visibility::moving::SHADER,
            crate::radiosity::GATHER_SHADER,
            crate::lightmap::LOOKUP_SHADER,
            crate::lightcuts::FINAL_GATHER_SHADER,
        ] {
            for n in 1..=MAX_RUN_BINDINGS {
                let shape = crate::shaders::CssmShape {
                    run_bindings: n,
                    ..Default::default()
                };
                let module = shader
                    .module_for(shape)
                    .unwrap_or_else(|e| panic!("{} for {n}: {e}", shader.label()));
                naga::valid::Validator::new(naga::valid::ValidationFlags::all(), CAPABILITIES)
                    .validate(&module)
                    .unwrap_or_else(|e| panic!("{} for {n}: {e:?}", shader.label()));
                let declared = cssm_bindings(&module);
                // naga_oil brings in the globals a module uses: a module that reads the runs
                // (`cssm_run`) reads every run binding.
                if declared.contains(&5) {
                    let runs: Vec<u32> = declared.into_iter().filter(|&b| b >= 5).collect();
                    assert_eq!(runs, (5..5 + n).collect::<Vec<_>>(), "{}", shader.label());
                }
            }
        }
    }

    /// The plain-WGSL library parses and validates for every binding count, with the
    /// bindings of `CssmGpu::layout_entries`.
    #[test]
    fn plain_library_matches_the_layout() {
        use crate::load::{CssmGpu, MAX_RUN_BINDINGS};
        for n in 1..=MAX_RUN_BINDINGS {
            let shape = crate::shaders::CssmShape {
                run_bindings: n,
                search_loop: n % 2 == 0,
                search_steps: n + 2,
                ..Default::default()
            };
            let source = super::library_wgsl(2, shape)
                + "@compute @workgroup_size(1) fn main() { let v = cssm_visibility(0u, vec3f(0.3), vec3f(1.0), vec3f(0.0)); }";
            assert!(!source.contains('#'), "a directive was left in:\n{source}");
            let module = naga::front::wgsl::parse_str(&source)
                .unwrap_or_else(|e| panic!("{n}: {}", e.emit_to_string(&source)));
            naga::valid::Validator::new(
                naga::valid::ValidationFlags::all(),
                crate::shaders::tests::CAPABILITIES,
            )
            .validate(&module)
            .unwrap_or_else(|e| panic!("{n}: {e:?}"));
            let mut declared: Vec<u32> = module
                .global_variables
                .iter()
                .filter_map(|(_, v)| v.binding.as_ref())
                .inspect(|b| assert_eq!(b.group, 2))
                .map(|b| b.binding)
                .collect();
            declared.sort_unstable();
            let layout: Vec<u32> = CssmGpu::layout_entries(wgpu::ShaderStages::COMPUTE, n)
                .iter()
                .map(|e| e.binding)
                .collect();
            assert_eq!(declared, layout, "{n} run bindings");
        }
    }

    #[test]
    fn runs_split_by_the_binding_limit() {
        use crate::load::run_split;
        // Fits one binding (and an empty file still has one).
        assert_eq!(run_split(100, 400), (100, 1));
        assert_eq!(run_split(0, 400), (100, 1));
        // One run over: a second binding.
        assert_eq!(run_split(101, 400), (100, 2));
        // Sibenik at atlas 256, cube 32: 137.6 MiB of runs over WebGPU's 128 MiB.
        let runs = (137.6 * 1024.0 * 1024.0 / 4.0) as u64;
        assert_eq!(run_split(runs, 128 << 20), (32 << 20, 2));
        // A limit that is not a multiple of 4 rounds down; a huge one stays within u32.
        assert_eq!(run_split(10, 7), (1, 10));
        assert_eq!(run_split(10, u64::MAX).0, u32::MAX);
    }
}
