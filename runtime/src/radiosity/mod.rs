//! GPU hierarchical radiosity with clustering (§4.1-§4.3): diffuse indirect bounces over the
//! atlas texels, every visibility answered by the CSSM.
//!
//! - [`HierarchyGpu`]: the bake's median-cut tree (§4.2, `cssm_formats::hierarchy`) on the GPU,
//!   with the leaf table and the inner nodes ordered by depth for the pull.
//! - [`Radiosity`]: the iteration. Each bounce runs `gather.wgsl` (one thread per receiver leaf
//!   walks the tree stacklessly, Fig. 10; refine while the energy oracle's tone-mapped bound is
//!   above the threshold, else gather with the clamped form factor of [`transfer`] and the
//!   receiver's own depth cube map) and `pull.wgsl` (inner nodes = area-weighted mean of their
//!   children, deepest level first). The source is the direct light in the atlas
//!   ([`crate::direct::AtlasDirect`]).
//!
//! After `k` iterations a node's radiance holds the direct light plus `k` diffuse bounces, and
//! every texel's indirect irradiance the last `k`-bounce gather. The number of iterations is a
//! [`BouncePlan`]: exactly `k`, or until a bounce adds at most 1% of the light, tested after
//! each pull on the root, the area-weighted mean of every texel ([`crate::common::converge`]).
//!
//! CPU references: [`cpu::radiosity`] runs the same iteration with the CPU query (its twin,
//! held to it by `tests/gpu/radiosity.rs::radiosity_matches_cpu_twin`) and [`cpu::brute_force`]
//! gathers from every texel with exact ray casts and no hierarchy (the ground truth of
//! `radiosity_matches_brute_force`).

pub mod cpu;
mod cpu_links;
mod far_field;
pub mod links;
mod solve;
pub mod transfer;

pub use far_field::FarField;
pub use solve::{
    AtlasRadiosity, FarSolve, LinkedSolve, atlas_radiosity, atlas_radiosity_lights,
    atlas_radiosity_posed, render_atlas_direct,
};

/// This folder's WGSL, for the registry ([`crate::shaders`]).
pub const SHADERS: crate::shaders::ShaderSet = crate::shaders::ShaderSet {
    modules: &[
        GATHER_SHADER,
        PULL_SHADER,
        links::LINKS_SHADER,
        links::PRODUCT_SHADER,
    ],
    libraries: &[crate::shaders::library!("radiosity/transfer.wgsl")],
};

use cssm_formats::{hierarchy::Hierarchy, moving::posed_texels, texel::Texel};
use glam::Affine3A;
use wgpu::util::DeviceExt;

use cssm_formats::{CssmFile, Scene};

use crate::{
    RuntimeError,
    common::{
        converge::{BouncePlan, ConvergeGpu, ConvergeInputs, Convergence},
        layout,
    },
    direct::AtlasDirect,
    frame::{FrameContext, FrameEncoder, PassInfo, Slot, Stage},
    gpu_types::{GpuHierarchyNode, GpuMaterial, GpuNode, GpuTraversalParams},
    load::{CssmGpu, limit_check, storage_buffer},
    shaders,
};

/// `radiosity/gather.wgsl` with the CSSM library and `radiosity/transfer.wgsl`.
pub const GATHER_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("radiosity gather", "radiosity/gather.wgsl");

/// `radiosity/pull.wgsl`.
pub const PULL_SHADER: crate::shaders::Shader =
    crate::shaders::shader!("radiosity pull", "radiosity/pull.wgsl");

/// Threshold of the oracle when none is given: refine while a sender's tone-mapped bound is
/// above 2% of display white (the lightcuts paper's perceptual 2%, §4.4, on the oracle's scale).
pub const DEFAULT_THRESHOLD: f32 = 0.02;

/// Options of the radiosity iteration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RadiosityOptions {
    /// Oracle threshold on the tone-mapped upper bound (§4.3); smaller is slower and closer.
    pub threshold: f32,
    /// Exposure of the oracle's tone mapper (the display's exposure).
    pub exposure: f32,
}

impl Default for RadiosityOptions {
    fn default() -> Self {
        Self {
            threshold: DEFAULT_THRESHOLD,
            exposure: 1.0,
        }
    }
}

/// Depth of every node (root 0) of a depth-first node array.
pub fn node_depths(nodes: &[GpuNode]) -> Vec<u32> {
    let mut depth = vec![0u32; nodes.len()];
    for i in 0..nodes.len() {
        if nodes[i].count > 1 {
            let (left, right) = (i + 1, nodes[i + 1].skip as usize);
            depth[left] = depth[i] + 1;
            depth[right] = depth[i] + 1;
        }
    }
    depth
}

/// The hierarchy of a loaded CSSM in GPU memory.
pub struct HierarchyGpu {
    /// [`GpuHierarchyNode`] per node (the file's node and its spread, [`transfer::node_spreads`]),
    /// depth-first.
    pub nodes: wgpu::Buffer,
    /// Per leaf in leaf order: `(texel, node index)`.
    pub leaves: wgpu::Buffer,
    /// Inner nodes ordered by depth, deepest first.
    pub pull_order: wgpu::Buffer,
    /// `pull_order` range of every level, deepest first.
    pub levels: Vec<(u32, u32)>,
    /// Number of nodes.
    pub node_count: u32,
    /// Number of leaves (= texels).
    pub leaf_count: u32,
}

impl HierarchyGpu {
    /// Uploads `hierarchy` (validated with its file) and its nodes' spreads over `texels`, the
    /// nodes holding emitters flagged (`emitting`, per material: [`emitting_materials`]).
    ///
    /// # Errors
    /// [`RuntimeError::TooLarge`] when the node array exceeds the device's binding limit.
    pub fn new(
        device: &wgpu::Device,
        hierarchy: &Hierarchy,
        texels: &[Texel],
        emitting: &[bool],
    ) -> Result<Self, RuntimeError> {
        let nodes = &hierarchy.nodes;
        limit_check(
            device,
            "hierarchy nodes",
            (nodes.len() * size_of::<GpuHierarchyNode>()) as u64,
        )?;
        let mut leaves = vec![[0u32; 2]; hierarchy.leaf_texels.len()];
        for (i, n) in nodes.iter().enumerate() {
            if n.count == 1 {
                leaves[n.first as usize] = [hierarchy.leaf_texels[n.first as usize], i as u32];
            }
        }
        let depth = node_depths(nodes);
        let mut inner: Vec<u32> = (0..nodes.len() as u32)
            .filter(|&i| nodes[i as usize].count > 1)
            .collect();
        inner.sort_by_key(|&i| (std::cmp::Reverse(depth[i as usize]), i));
        let mut levels = Vec::new();
        let mut start = 0;
        for k in 1..=inner.len() {
            if k == inner.len() || depth[inner[k] as usize] != depth[inner[start] as usize] {
                levels.push((start as u32, k as u32));
                start = k;
            }
        }
        // COPY_DST: moving objects refit the nodes ([`MovingTexels::place`]).
        let nodes_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("hierarchy nodes"),
            contents: bytemuck::cast_slice(&gpu_nodes(hierarchy, texels, emitting)),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
        });
        Ok(Self {
            nodes: nodes_buffer,
            leaves: storage_buffer(device, "hierarchy leaves", bytemuck::cast_slice(&leaves)),
            pull_order: storage_buffer(
                device,
                "hierarchy pull order",
                bytemuck::cast_slice(&inner),
            ),
            levels,
            node_count: nodes.len() as u32,
            leaf_count: leaves.len() as u32,
        })
    }
}

/// Every node of `hierarchy` as the GPU holds it, with its spread over `texels` and its
/// emitter flags (`emitting`, per material: [`emitting_materials`]).
pub fn gpu_nodes(
    hierarchy: &Hierarchy,
    texels: &[Texel],
    emitting: &[bool],
) -> Vec<GpuHierarchyNode> {
    hierarchy
        .nodes
        .iter()
        .zip(transfer::node_spreads(hierarchy, texels, emitting))
        .map(|(&node, spread)| GpuHierarchyNode { node, spread })
        .collect()
}

/// The texels of a file with moving objects and the hierarchy over them, kept on the CPU so
/// that the hierarchy follows the objects (§3.3): when an object moves, its texels move with it
/// (`posed.wgsl` on the GPU; [`cssm_formats::moving::posed_texels`] here) and every node's
/// bounds are refitted around them ([`Hierarchy::refit`]), so the oracle's bounds (§4.3) and
/// the nodes' mean normals, areas and spreads ([`transfer::node_spreads`]) are those of the
/// texels where they are now.
pub struct MovingTexels {
    /// The texels as baked.
    baked: Vec<Texel>,
    /// The hierarchy, refitted to the texels where they are now.
    hierarchy: Hierarchy,
    /// Each object's motion since loading (the `SceneGpu::motion` matrices).
    motions: Vec<Affine3A>,
    /// Per material, whether it emits ([`emitting_materials`]).
    emitting: Vec<bool>,
}

impl MovingTexels {
    /// The texels and hierarchy of `file` (baked from a scene of `object_count` objects), every
    /// object where it was loaded; `None` for a file without moving objects (no CSM), whose
    /// texels never move.
    pub fn new(file: &CssmFile, object_count: usize, emitting: &[bool]) -> Option<Self> {
        (!file.csms.is_empty()).then(|| Self {
            baked: file.texels.clone(),
            hierarchy: file.hierarchy.clone(),
            motions: vec![Affine3A::IDENTITY; object_count],
            emitting: emitting.to_vec(),
        })
    }

    /// Object `index` moved by `motion` since loading: refits the hierarchy to the texels where
    /// the objects are now and writes its nodes into `gpu`'s.
    ///
    /// # Panics
    /// If `index` is not one of the objects.
    pub fn place(
        &mut self,
        queue: &wgpu::Queue,
        gpu: &HierarchyGpu,
        index: usize,
        motion: Affine3A,
    ) {
        self.motions[index] = motion;
        let texels = posed_texels(&self.baked, &self.motions);
        self.hierarchy.refit(&texels);
        queue.write_buffer(
            &gpu.nodes,
            0,
            bytemuck::cast_slice(&gpu_nodes(&self.hierarchy, &texels, &self.emitting)),
        );
    }

    /// The hierarchy as refitted (what the GPU's nodes hold).
    pub fn hierarchy(&self) -> &Hierarchy {
        &self.hierarchy
    }
}

/// Pull level constants; one 256-byte-aligned uniform per level.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct PullLevel {
    start: u32,
    end: u32,
    _pad: [u32; 2],
}

/// The radiosity iteration over a loaded CSSM: see the module docs.
pub struct Radiosity {
    /// Radiance per node (`vec4f`, rgb), two buffers used in turn; [`Self::radiance`] says
    /// which holds the result of a given number of iterations.
    pub node_radiance: [wgpu::Buffer; 2],
    /// Indirect irradiance per texel (`vec4f`, rgb) of the last iteration.
    pub texel_irradiance: wgpu::Buffer,
    gather_pipeline: wgpu::ComputePipeline,
    pull_pipeline: wgpu::ComputePipeline,
    /// `[gather][written buffer]`: index 0 writes the direct light only, 1 gathers.
    gather_groups: [[wgpu::BindGroup; 2]; 2],
    /// `[level][written buffer]`.
    pull_groups: Vec<[wgpu::BindGroup; 2]>,
    leaf_count: u32,
    level_sizes: Vec<u32>,
    /// The test that ends the iteration once converged, on the root (node 0).
    converge: ConvergeGpu,
    /// What [`Self::far_field`] binds again: the gather's layout, the texels' direct light and
    /// albedo, the hierarchy's nodes and leaves, and the oracle's options.
    gather_layout: wgpu::BindGroupLayout,
    texel_direct: wgpu::Buffer,
    albedo: wgpu::Buffer,
    tree: [wgpu::Buffer; 2],
    node_count: u32,
    options: RadiosityOptions,
    /// The cached links, once built the bounces' products.
    links: links::Links,
}

impl Radiosity {
    /// The passes over `cssm` and `hierarchy`, starting from `texel_direct` (`vec4f` radiance per
    /// texel, [`crate::direct::AtlasDirect::texel_radiance`]) with `texel_albedo` (rgb diffuse
    /// albedo per texel, texel order), iterating as `plan` says.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        device: &wgpu::Device,
        cssm: &CssmGpu,
        moving: &crate::visibility::moving::MovingGpu,
        hierarchy: &HierarchyGpu,
        texel_direct: &wgpu::Buffer,
        texel_albedo: &[[f32; 4]],
        options: RadiosityOptions,
        plan: BouncePlan,
    ) -> Result<Self, RuntimeError> {
        let node_bytes = 16 * hierarchy.node_count.max(1) as u64;
        limit_check(device, "node radiance", node_bytes)?;
        let vec4_buffer = |label: &str, size: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let node_radiance = [
            vec4_buffer("node radiance 0", node_bytes),
            vec4_buffer("node radiance 1", node_bytes),
        ];
        let texel_irradiance = vec4_buffer(
            "texel indirect irradiance",
            16 * hierarchy.leaf_count.max(1) as u64,
        );
        let albedo = storage_buffer(device, "texel albedo", bytemuck::cast_slice(texel_albedo));
        let c = wgpu::ShaderStages::COMPUTE;

        // Gather: group 0 its own buffers, group 1 the CSSM, group 2 the moving objects.
        let module = GATHER_SHADER.create_for_scene(device, cssm.shape(), moving.csm_count);
        let entries = [
            layout::uniform(0, c),
            layout::storage(1, true, c),
            layout::storage(2, true, c),
            layout::storage(3, true, c),
            layout::storage(4, true, c),
            layout::storage(5, true, c),
            layout::storage(6, false, c),
            layout::storage(7, false, c),
        ];
        let gather_layout = layout::bind_group_layout(device, "radiosity gather", &entries);
        let gather_pipeline = layout::compute_pipeline(
            device,
            "radiosity gather",
            &module,
            &moving.with_layout(&[&gather_layout, &cssm.bind_group_layout]),
        );
        let params = |gather: u32| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("radiosity params"),
                contents: bytemuck::bytes_of(&GpuTraversalParams {
                    receiver_count: hierarchy.leaf_count,
                    node_count: hierarchy.node_count,
                    threshold: options.threshold,
                    exposure: options.exposure,
                    seed: 0,
                    jitter: 0,
                    gather,
                    frame: 0,
                    ..Default::default()
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        let param_buffers = [params(0), params(1)];
        let gather_group = |gather: usize, written: usize| {
            layout::bind_group(
                device,
                "radiosity gather",
                &gather_layout,
                &[
                    param_buffers[gather].as_entire_binding(),
                    hierarchy.nodes.as_entire_binding(),
                    hierarchy.leaves.as_entire_binding(),
                    texel_direct.as_entire_binding(),
                    albedo.as_entire_binding(),
                    node_radiance[1 - written].as_entire_binding(),
                    node_radiance[written].as_entire_binding(),
                    texel_irradiance.as_entire_binding(),
                ],
            )
        };
        let gather_groups = [
            [gather_group(0, 0), gather_group(0, 1)],
            [gather_group(1, 0), gather_group(1, 1)],
        ];

        // Pull: one uniform per level.
        let module = PULL_SHADER.create(device);
        let pull_layout = layout::bind_group_layout(
            device,
            "radiosity pull",
            &[
                layout::uniform(0, c),
                layout::storage(1, true, c),
                layout::storage(2, true, c),
                layout::storage(3, false, c),
            ],
        );
        let pull_pipeline =
            layout::compute_pipeline(device, "radiosity pull", &module, &[&pull_layout]);
        let pull_groups = hierarchy
            .levels
            .iter()
            .map(|&(start, end)| {
                let level = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("pull level"),
                    contents: bytemuck::bytes_of(&PullLevel {
                        start,
                        end,
                        _pad: [0; 2],
                    }),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
                [0, 1].map(|written| {
                    layout::bind_group(
                        device,
                        "radiosity pull",
                        &pull_layout,
                        &[
                            level.as_entire_binding(),
                            hierarchy.nodes.as_entire_binding(),
                            hierarchy.pull_order.as_entire_binding(),
                            node_radiance[written].as_entire_binding(),
                        ],
                    )
                })
            })
            .collect();
        // The gather's dispatch, one thread per leaf, until the test sets it to none.
        let gather_args = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("radiosity gather arguments"),
            contents: bytemuck::cast_slice(&[shaders::groups_1d(hierarchy.leaf_count), 1, 1]),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let converge = ConvergeGpu::new(
            device,
            plan,
            &ConvergeInputs {
                solution: [&node_radiance[0], &node_radiance[1]],
                held: Some(hierarchy.node_count),
                // The root: the area-weighted mean of every texel.
                mean: (0, 1),
                additive: false,
                work_args: Some((&gather_args, 0)),
            },
        );
        Ok(Self {
            node_radiance,
            texel_irradiance,
            gather_pipeline,
            pull_pipeline,
            gather_groups,
            pull_groups,
            leaf_count: hierarchy.leaf_count,
            level_sizes: hierarchy.levels.iter().map(|&(s, e)| e - s).collect(),
            converge,
            gather_layout,
            texel_direct: texel_direct.clone(),
            albedo,
            tree: [hierarchy.nodes.clone(), hierarchy.leaves.clone()],
            node_count: hierarchy.node_count,
            options,
            links: {
                let mut links = links::Links::new(device, cssm, moving, hierarchy, options, None);
                // No bounce to multiply (`lightcuts` at one bounce: the final gather is it).
                if plan.max == 0 {
                    links.turn_off();
                }
                links
            },
        })
    }

    /// Every bounce walks the hierarchy, querying the CSSM (the links are never built: the
    /// option `links=walk`).
    pub fn walk_always(&mut self) {
        self.links.turn_off();
    }

    /// How many links the bounces multiply, once built ([`links`]); `None` before, or when
    /// every bounce walks.
    pub fn link_count(&self) -> Option<u64> {
        self.links.count()
    }

    /// Before recording an iteration: builds the cached links for the last recorded
    /// iteration's result if they are due (an iteration ran and they were never built, or its
    /// re-cuts overflowed), else records the re-cut of the receivers whose cut its products
    /// found stale ([`links`]); the counters of the last iteration are read back, so this
    /// waits for the GPU once a light move.
    ///
    /// # Errors
    /// A failed read-back.
    pub fn update_links(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        cssm: &crate::frame::CssmResources,
        frame: &mut FrameEncoder,
    ) -> Result<(), RuntimeError> {
        let [a, b] = &self.node_radiance;
        let inputs = links::LinkInputs {
            tree: &self.tree,
            texel_direct: &self.texel_direct,
            albedo: &self.albedo,
            // The cuts made for the result ([`Self::radiance`]).
            radiance: &self.node_radiance[(self.converge.plan().max % 2) as usize],
            // Bounce k writes buffer k % 2 from the other.
            products: [
                Some([b, a, &self.texel_irradiance]),
                Some([a, b, &self.texel_irradiance]),
            ],
            converged: self.converge.state(),
        };
        self.links
            .before_iteration(device, queue, cssm, &inputs, frame)
    }

    /// The receivers whose cut the last iteration's products found stale (each bounce's
    /// flags counted once a receiver), and the re-cuts that overflowed their slot, as read
    /// back before the iteration after it ([`Self::update_links`]).
    pub fn stale_links(&self) -> (u32, u32) {
        self.links.last_counters
    }

    /// The buffer holding the node radiance after the iteration (both do once it converged).
    pub fn radiance(&self) -> &wgpu::Buffer {
        &self.node_radiance[(self.converge.plan().max % 2) as usize]
    }

    /// How many bounces the last recorded iteration ran (read back; waits for the GPU).
    ///
    /// # Errors
    /// GPU errors of the read-back.
    pub fn convergence(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Convergence, RuntimeError> {
        self.converge.read(device, queue)
    }

    /// Records the start (direct light into the leaves, pulled) and the plan's bounces: each a
    /// gather (or, once the links are built, their product) of as many workgroups as the
    /// convergence test leaves it (none once converged), then the pull and the test on the
    /// root.
    pub fn run(&mut self, frame: &mut FrameEncoder, cssm: &crate::frame::CssmResources) {
        for k in 0..=self.converge.plan().max {
            let written = (k % 2) as usize;
            let gather = usize::from(k > 0);
            if let Some(product) = self.links.product(written).filter(|_| k > 0) {
                product.record(frame);
            } else {
                let mut pass = frame.compute_pass(if k == 0 {
                    "radiosity: direct into leaves"
                } else {
                    "radiosity: gather"
                });
                pass.set_pipeline(&self.gather_pipeline);
                pass.set_bind_group(0, &self.gather_groups[gather][written], &[]);
                pass.set_bind_group(1, &cssm.query.bind_group, &[]);
                cssm.moving.bind(&mut pass, 2);
                if k == 0 {
                    pass.dispatch_workgroups(shaders::groups_1d(self.leaf_count), 1, 1);
                } else {
                    pass.dispatch_workgroups_indirect(self.converge.bounce_args(), 0);
                }
            }
            // wgpu orders the dispatches of one pass: each level reads what the one before wrote,
            // and the test reads the root the last level wrote.
            let mut pass = frame.compute_pass("radiosity: pull");
            pass.set_pipeline(&self.pull_pipeline);
            for (groups, &size) in self.pull_groups.iter().zip(&self.level_sizes) {
                pass.set_bind_group(0, &groups[written], &[]);
                pass.dispatch_workgroups(shaders::groups_1d(size), 1, 1);
            }
            if k == 0 {
                self.converge.start(&mut pass);
            } else {
                self.converge.check(&mut pass, k);
            }
        }
        self.links.ran();
    }
}

/// The passes of [`AtlasGi`], the view-independent part of the hierarchical-radiosity methods,
/// under the names their timestamps carry (`AtlasGi::run`), so that the timings of a frame
/// find their stage in the schedule.
pub const PREPARE_PASSES: [PassInfo; 6] = [
    PassInfo {
        name: "direct light into atlas",
        stage: Stage::Prepare,
        reads: &[Slot::Cssm, Slot::Lights, Slot::ShadowMaps],
        writes: &[Slot::TexelRadiance],
    },
    PassInfo {
        name: "radiosity: direct into leaves",
        stage: Stage::Prepare,
        reads: &[Slot::Cssm, Slot::TexelRadiance],
        writes: &[Slot::NodeRadiance],
    },
    PassInfo {
        name: "radiosity: gather",
        stage: Stage::Prepare,
        reads: &[Slot::Cssm, Slot::TexelRadiance, Slot::NodeRadiance],
        writes: &[Slot::NodeRadiance, Slot::TexelIrradiance],
    },
    PassInfo {
        name: "radiosity: pull",
        stage: Stage::Prepare,
        reads: &[Slot::NodeRadiance],
        writes: &[Slot::NodeRadiance],
    },
    // Instead of the gather once the cached links are built (links.rs).
    PassInfo {
        name: "radiosity: product",
        stage: Stage::Prepare,
        reads: &[Slot::TexelRadiance, Slot::NodeRadiance],
        writes: &[Slot::NodeRadiance, Slot::TexelIrradiance],
    },
    // Before the iteration, the receivers whose cut the last one found stale.
    PassInfo {
        name: "radiosity: re-cut",
        stage: Stage::Prepare,
        reads: &[Slot::Cssm, Slot::NodeRadiance],
        writes: &[],
    },
];

/// Per material of `scene`, whether it emits (its emission above zero in any channel): the
/// texels whose light `lightcuts`' texture-space final gather keeps out of the far field and
/// gathers per pixel ([`crate::gpu_types::NODE_EMITTER`]).
pub fn emitting_materials(scene: &Scene) -> Vec<bool> {
    scene
        .materials
        .iter()
        .map(|m| m.emission.iter().any(|&c| c > 0.0))
        .collect()
}

/// Bounce albedo of every texel of `file` ([`crate::direct::cpu::bounce_albedo`] of its
/// material of `materials` ([`crate::load::cpu_materials`]): Kd times its texture's mean, plus
/// Ks; textures are not sampled in the atlas), as the radiosity iteration takes it.
pub fn texel_albedo(materials: &[GpuMaterial], file: &CssmFile) -> Vec<[f32; 4]> {
    file.texels
        .iter()
        .map(|t| {
            let m = &materials[t.material as usize];
            crate::direct::cpu::bounce_albedo(m.kd_mean, m.ks)
                .extend(0.0)
                .to_array()
        })
        .collect()
}

/// The view-independent part of the indirect light: the direct light into the atlas texels,
/// then the radiosity iteration over the hierarchy. Shared by `hrc`, `lightmap` and
/// `lightcuts`.
pub struct AtlasGi {
    /// Direct light into the texels.
    pub atlas: AtlasDirect,
    /// The bounces.
    pub radiosity: Radiosity,
}

impl AtlasGi {
    /// The passes over the context's `.cssm`, whose file is `file`, with its scene's materials
    /// (`ctx.scene`).
    ///
    /// # Errors
    /// No `.cssm` in the context, or buffers beyond the device's limits.
    pub fn new(
        ctx: &FrameContext,
        file: &CssmFile,
        options: RadiosityOptions,
        plan: BouncePlan,
    ) -> Result<Self, RuntimeError> {
        let cssm = ctx.cssm()?;
        let atlas = AtlasDirect::new(ctx, &cssm.query, &cssm.moving);
        let radiosity = Radiosity::new(
            &ctx.device,
            &cssm.query,
            &cssm.moving,
            &cssm.hierarchy,
            &atlas.texel_radiance,
            &texel_albedo(&ctx.scene.cpu_materials, file),
            options,
            plan,
        )?;
        Ok(Self { atlas, radiosity })
    }

    /// Records the direct light into the atlas and the plan's bounces; from the second call
    /// on, the bounces are the products of the cached links built (once, waiting for the GPU)
    /// for the first call's result ([`Radiosity::update_links`]; a build that fails
    /// leaves every bounce walking).
    pub fn run(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        let Some(cssm) = &ctx.cssm else { return };
        if self
            .radiosity
            .update_links(&ctx.device, &ctx.queue, cssm, frame)
            .is_err()
        {
            self.radiosity.walk_always();
        }
        self.atlas.run(frame, &cssm.moving);
        self.radiosity.run(frame, cssm);
    }
}

#[cfg(test)]
mod tests {
    use crate::shaders::tests::check_struct;
    use std::mem::{offset_of, size_of};

    #[test]
    fn pull_level_layout_matches_wgsl() {
        let module = crate::shaders::tests::module(super::PULL_SHADER);
        check_struct(
            &module,
            "PullLevel",
            size_of::<super::PullLevel>(),
            &[
                ("start", offset_of!(super::PullLevel, start)),
                ("end", offset_of!(super::PullLevel, end)),
            ],
        );
    }
}
