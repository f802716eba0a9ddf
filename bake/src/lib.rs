//! The CSSM bake pipeline (Ritschel et al. 2008, §3.2): scene → texture atlas (xatlas) →
//! coherent traversal of its texels → a depth cube map per texel (ray cast with obvhs, in
//! parallel with rayon) → per-pixel piecewise-constant compression → the median-cut texel
//! hierarchy (§4.2) → [`CssmFile`].
//!
//! ```no_run
//! use cssm_bake::{BakeOptions, bake};
//! use cssm_formats::{Scene, Traversal};
//!
//! let scene = Scene::load(std::path::Path::new("scenes/cornell-box"))?;
//! let options = BakeOptions { atlas_resolution: 64, cube_resolution: 32, traversal: Traversal::Spiral, ..Default::default() };
//! let baked = bake(&scene, &options, &mut |_progress| {})?;
//! println!("{} depth maps, ratio {:.1}", baked.file.texels.len(), baked.stats.ratio_gpu());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]

pub mod atlas;
pub mod check;
pub mod compress;
pub mod csm;
pub mod cubemap;
#[cfg_attr(not(feature = "gpu"), path = "no_gpu.rs")]
mod gpu;
pub mod raster;
mod slice;

use slice::bake_slice;
pub mod traverse;

/// Exact ray casting (obvhs), shared with the runtime: [`cssm_raycast`].
pub use cssm_raycast as raycast;

use std::time::{Duration, Instant};

use cssm_formats::{
    BakeParams, CssmFile, Hierarchy, Scene, SceneRef, Traversal,
    cube::{CubeFrame, DepthQuantizer, PixelGrid},
};
use rayon::prelude::*;

/// Accepted atlas and cube-map resolutions: the container's own limits, so a bake never writes a
/// file that `cssm::validate` refuses.
pub use cssm_formats::cssm::{ATLAS_RESOLUTION_RANGE, CUBE_RESOLUTION_RANGE};

/// Near distance as a fraction of the scene diameter when none is given (§3.2.1: "a small value
/// for the near plane"): a larger one lifts the cube maps over thin geometry, which costs
/// agreement on interiors; a smaller one buys a little more agreement for more runs. The
/// measurements that chose it are in reports/visibility.md and reports/defaults.md.
pub const DEFAULT_NEAR_FRACTION: f32 = 0.0005;

/// Cube resolution of the pilot bakes of [`Traversal::Piloted`] (at most the bake's own): a
/// sixteenth of the rays of a cube-32 bake, and still fine enough to tell which of two orders of a
/// chart makes fewer runs (the compression report's `piloted` rows measure what it picks).
pub const PILOT_CUBE_RESOLUTION: u32 = 8;

/// The options of [`BakeOptions`] a [`BakeError::Parameter`] can be about, so that a caller can
/// name them its own way (the command line: `--atlas`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BakeParameter {
    /// [`BakeOptions::atlas_resolution`].
    AtlasResolution,
    /// [`BakeOptions::cube_resolution`].
    CubeResolution,
    /// [`BakeOptions::near`], or the default near distance for the scene.
    Near,
}

impl BakeParameter {
    /// The parameter in words, as errors name it.
    pub fn name(self) -> &'static str {
        match self {
            BakeParameter::AtlasResolution => "atlas resolution",
            BakeParameter::CubeResolution => "cube resolution",
            BakeParameter::Near => "near distance",
        }
    }
}

/// Errors of the bake.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// A parameter out of range: "cube resolution 4 is out of range 8..=128".
    #[error("{} {value} {problem}", parameter.name())]
    Parameter {
        /// Which parameter.
        parameter: BakeParameter,
        /// Its value.
        value: String,
        /// What is wrong with it: "is out of range 8..=128".
        problem: String,
    },
    /// The scene cannot be baked.
    #[error("scene: {0}")]
    Scene(String),
    /// The atlas could not be built.
    #[error("atlas: {0}")]
    Atlas(String),
    /// The GPU could not bake ([`BakeDevice::Gpu`]): none could be opened, this build has no
    /// GPU support, or the device failed.
    #[error("GPU: {0}")]
    Gpu(String),
}

/// Where the depth cube maps' rays are cast.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BakeDevice {
    /// On the CPU's cores, by [`BakeOptions::cube_renderer`].
    #[default]
    Cpu,
    /// On the first GPU wgpu finds (Mesa's lavapipe where there is none), by a compute BVH
    /// traversal; needs the crate's `gpu` feature. The pilot of [`Traversal::Piloted`] stays on
    /// the CPU. A GPU may round a ray through an edge otherwise than the CPU, so the file may
    /// differ from the CPU's in a few pixels (reports/bake.md, "The bake on the GPU").
    Gpu,
}

impl BakeDevice {
    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            BakeDevice::Cpu => "cpu",
            BakeDevice::Gpu => "gpu",
        }
    }
}

impl std::fmt::Display for BakeDevice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for BakeDevice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "cpu" => Ok(BakeDevice::Cpu),
            "gpu" => Ok(BakeDevice::Gpu),
            other => Err(format!("unknown device '{other}': expected cpu or gpu")),
        }
    }
}

/// What to bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeOptions {
    /// Atlas width and height in texels (32..=1024).
    pub atlas_resolution: u32,
    /// Cube-map face resolution N (8..=128).
    pub cube_resolution: u32,
    /// Texel traversal order (default: Hilbert).
    pub traversal: Traversal,
    /// How chart-by-chart traversals pick the next chart (beyond the paper; see
    /// [`traverse::ChartOrder`]).
    pub chart_order: traverse::ChartOrder,
    /// Near distance in scene units; `None`: [`DEFAULT_NEAR_FRACTION`] of the scene diameter.
    pub near: Option<f32>,
    /// Which code of its interval a run stores (beyond the paper; see [`compress::RunValue`]).
    pub run_value: compress::RunValue,
    /// Lossy: merge runs of at most this many maps into their neighbours (0: lossless, the
    /// paper's compression; see [`compress::CompressOptions`]).
    pub merge_short_runs: u32,
    /// Which intersection closes each pixel's interval (beyond the paper; see
    /// [`cubemap::SecondLayer`]).
    pub second_layer: cubemap::SecondLayer,
    /// Which renderer draws the depth cube maps; the maps are byte-identical either way (see
    /// [`cubemap::CubeRenderer`]).
    pub cube_renderer: cubemap::CubeRenderer,
    /// Where the depth maps' rays are cast ([`BakeDevice`]).
    pub device: BakeDevice,
    /// Where each texel's cube-map pixels sit ([`PixelGrid`]): the paper's centred grid by
    /// default; [`PixelGrid::Staggered`] (beyond the paper) agrees better with exact ray casts
    /// on detailed interiors for more runs, and costs runs for nothing on simple scenes at fine
    /// atlases (reports/visibility.md, "Staggered pixel grids").
    pub pixel_grid: PixelGrid,
    /// How every texel's cube map lies in the world ([`CubeFrame`]): turned by default, so that
    /// the vertical and horizontal edges of interiors cross the pixel grids obliquely (beyond the
    /// paper: more agreement with exact ray casts for as many runs, reports/visibility.md,
    /// "Turned cube maps"); [`CubeFrame::World`] is the paper's.
    pub cube_frame: CubeFrame,
}

impl Default for BakeOptions {
    fn default() -> Self {
        Self {
            atlas_resolution: 64,
            cube_resolution: 32,
            // The report's best variant at the same accuracy (reports/compression.md, Options
            // table, `best`: 66.7 : 1 against the paper's 37.8 : 1 and Hilbert's 41.0 : 1 on the
            // Cornell box at atlas 128, cube 64, with the agreement over the pairs that exchange
            // light 0.06 point from the paper's): the piloted order and the exchange layer. The
            // paper's method is `--traversal spiral --second-layer any`.
            traversal: Traversal::Piloted,
            chart_order: traverse::ChartOrder::Nearest,
            near: None,
            run_value: compress::RunValue::Middle,
            merge_short_runs: 0,
            second_layer: cubemap::SecondLayer::Exchange,
            cube_renderer: cubemap::CubeRenderer::Auto,
            device: BakeDevice::Cpu,
            pixel_grid: PixelGrid::Centred,
            cube_frame: CubeFrame::Turned,
        }
    }
}

impl BakeOptions {
    /// Checks what can be checked without the scene: the atlas and cube resolutions
    /// ([`ATLAS_RESOLUTION_RANGE`], [`CUBE_RESOLUTION_RANGE`]) and a near distance, if given,
    /// finite and positive ([`bake`] checks it against the scene's diameter too). [`bake`]
    /// calls it first; a caller can call it before loading a scene.
    ///
    /// ```
    /// use cssm_bake::{BakeOptions, BakeError, BakeParameter};
    ///
    /// let options = BakeOptions { cube_resolution: 4, ..Default::default() };
    /// let Err(e @ BakeError::Parameter { parameter: BakeParameter::CubeResolution, .. }) = options.check() else {
    ///     panic!("cube 4 is out of range");
    /// };
    /// assert_eq!(e.to_string(), "cube resolution 4 is out of range 8..=128");
    /// assert!(BakeOptions::default().check().is_ok());
    /// ```
    pub fn check(&self) -> Result<(), BakeError> {
        check_range(
            BakeParameter::AtlasResolution,
            self.atlas_resolution,
            &ATLAS_RESOLUTION_RANGE,
        )?;
        check_range(
            BakeParameter::CubeResolution,
            self.cube_resolution,
            &CUBE_RESOLUTION_RANGE,
        )?;
        match self.near {
            Some(near) => check_near(near, None),
            None => Ok(()),
        }
    }
}

/// `value` of `parameter` inside `range`.
pub(crate) fn check_range(
    parameter: BakeParameter,
    value: u32,
    range: &std::ops::RangeInclusive<u32>,
) -> Result<(), BakeError> {
    if range.contains(&value) {
        return Ok(());
    }
    Err(BakeError::Parameter {
        parameter,
        value: value.to_string(),
        problem: format!("is out of range {}..={}", range.start(), range.end()),
    })
}

/// A near distance: finite, positive and, where the scene diameter `far` is known, below it.
fn check_near(near: f32, far: Option<f32>) -> Result<(), BakeError> {
    if near.is_finite() && near > 0.0 && far.is_none_or(|far| near < far) {
        return Ok(());
    }
    Err(BakeError::Parameter {
        parameter: BakeParameter::Near,
        value: near.to_string(),
        problem: match far {
            Some(far) => format!("must be positive and below the scene diameter {far}"),
            None => "must be positive and finite".into(),
        },
    })
}

/// Figures of one bake.
#[derive(Clone, Debug, Default)]
pub struct BakeStats {
    /// Number of defined texels = depth maps.
    pub defined_texels: u64,
    /// Number of atlas charts.
    pub charts: u32,
    /// Rays cast (pixels that were not don't-care).
    pub rays: u64,
    /// 2 bytes per cube-map pixel.
    pub uncompressed_bytes: u64,
    /// GPU-resident random-access run data.
    pub gpu_bytes: u64,
    /// Number of runs.
    pub runs: u64,
    /// Time spent unwrapping and rasterising the atlas.
    pub atlas_time: Duration,
    /// Time spent in the traversal.
    pub traversal_time: Duration,
    /// Time spent rendering and compressing depth maps.
    pub maps_time: Duration,
    /// Time spent building the texel hierarchy (§4.2).
    pub hierarchy_time: Duration,
    /// Coherent shadow maps of the rigid objects: how many.
    pub csms: u64,
    /// Their uncompressed size (2 bytes per pixel of every map).
    pub csm_uncompressed_bytes: u64,
    /// Their run data in memory.
    pub csm_gpu_bytes: u64,
    /// Time spent baking them.
    pub csm_time: Duration,
    /// The GPU that cast the depth maps' rays ([`BakeDevice::Gpu`]), as its driver names it.
    pub gpu: Option<String>,
}

impl BakeStats {
    /// Uncompressed / GPU-resident size: the ratio of the paper's tables.
    pub fn ratio_gpu(&self) -> f64 {
        self.uncompressed_bytes as f64 / self.gpu_bytes.max(1) as f64
    }
}

/// A baked CSSM with its figures.
pub struct Baked {
    /// The file contents.
    pub file: CssmFile,
    /// Figures.
    pub stats: BakeStats,
}

/// A stage of a bake, in the order they run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// xatlas cuts the surface into charts (§3.2.3).
    Charts,
    /// xatlas flattens each chart.
    Parameterize,
    /// The charts packed onto the page, at shrinking then bisected scales until the largest
    /// that fits ([`Progress::done`] counts the attempts).
    Pack,
    /// The coherent order of the texels (§3.2.3), piloted on small cube maps.
    Order,
    /// Depth cube maps ray cast and compressed (§3.2.1, §3.1).
    Maps,
    /// The coherent shadow maps of the rigid objects (§3.1, §3.3): [`Progress::done`] counts
    /// their depth maps. Only in scenes with `[[objects]]`.
    Csm,
}

impl Stage {
    /// The stage in a few words, for a progress display.
    pub fn describe(self) -> &'static str {
        match self {
            Stage::Charts => "atlas: charts",
            Stage::Parameterize => "atlas: flattening charts",
            Stage::Pack => "atlas: packing",
            Stage::Order => "texel order",
            Stage::Maps => "depth maps",
            Stage::Csm => "coherent shadow maps of the moving objects",
        }
    }
}

/// How far a bake is: its stage and, where the stage can tell, how much of it is done.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// The stage running.
    pub stage: Stage,
    /// Work done: percent for [`Stage::Charts`] and [`Stage::Parameterize`], attempts for
    /// [`Stage::Pack`], depth maps for [`Stage::Maps`] and [`Stage::Csm`].
    pub done: u64,
    /// Work in all, 0 where the stage cannot tell ([`Stage::Pack`], [`Stage::Order`]).
    pub total: u64,
}

/// Bakes `scene`, telling `progress` as every stage starts and moves on. `progress` may be
/// called from xatlas' worker threads during the atlas stages, one call at a time.
///
/// ```no_run
/// # fn demo(scene: &cssm_formats::Scene) -> Result<(), cssm_bake::BakeError> {
/// let baked = cssm_bake::bake(scene, &cssm_bake::BakeOptions::default(), &mut |p| {
///     eprintln!("{}: {}/{}", p.stage.describe(), p.done, p.total)
/// })?;
/// # let _ = baked; Ok(()) }
/// ```
pub fn bake(
    scene: &Scene,
    options: &BakeOptions,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> Result<Baked, BakeError> {
    let (file, stats) = bake_slice(scene, options, None, progress)?;
    Ok(Baked { file, stats })
}

/// A chunk of a chunked bake ([`bake_chunk`]) and the statistics of its slice.
#[derive(Debug)]
pub struct BakedChunk {
    /// The chunk, ready for [`cssm_formats::cssm::write_chunk_atomic`].
    pub chunk: cssm_formats::cssm::CssmChunk,
    /// Statistics of the chunk's slice (its maps, rays and runs; the atlas and the traversal
    /// are the whole bake's, which every chunk computes).
    pub stats: BakeStats,
}

/// Bakes chunk `spec` of `scene` for a batch farm: the atlas, the traversal and the hierarchy
/// of the whole bake (each chunk computes the same ones), and the depth maps of the chunk's
/// slice of whole segments only ([`cssm_formats::cssm::ChunkSpec::maps`]).
/// [`cssm_formats::cssm::merge_chunks`] joins the chunks into the file [`bake`] gives, byte for
/// byte once written with `coding`.
///
/// ```no_run
/// # fn demo(scene: &cssm_formats::Scene) -> Result<(), Box<dyn std::error::Error>> {
/// use cssm_formats::cssm::{ChunkSpec, FileCoding, write_chunk_atomic};
/// let spec: ChunkSpec = "3/8".parse()?;
/// let options = cssm_bake::BakeOptions::default();
/// let baked = cssm_bake::bake_chunk(scene, &options, spec, FileCoding::default(), &mut |_| {})?;
/// write_chunk_atomic("scene.chunk-3-of-8".as_ref(), &baked.chunk)?;
/// # Ok(()) }
/// ```
pub fn bake_chunk(
    scene: &Scene,
    options: &BakeOptions,
    spec: cssm_formats::cssm::ChunkSpec,
    coding: cssm_formats::cssm::FileCoding,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> Result<BakedChunk, BakeError> {
    let (mut file, stats) = bake_slice(scene, options, Some(spec), progress)?;
    let runs = std::mem::take(&mut file.runs);
    let chunk = cssm_formats::cssm::CssmChunk::new(spec, coding, file, runs)
        .map_err(|e| BakeError::Scene(format!("chunk {spec}: {e}")))?;
    Ok(BakedChunk { chunk, stats })
}

/// The geometry each texel's depth cube map sees (§3.3): in a scene without rigid objects, the
/// whole scene; with them, a texel on the static part sees the static part alone and a texel on
/// a rigid object sees that object alone (its CSSM tests self-occlusion; every other object is
/// tested with its coherent shadow map, wherever the objects have moved).
struct TexelGeometry {
    bvhs: Vec<raycast::SceneBvh>,
    /// Index into `bvhs` of every object's geometry.
    bvh_of_object: Vec<usize>,
}

impl TexelGeometry {
    /// The geometry of `scene` turned into the cube frame `frame`.
    fn new(scene: &Scene, frame: CubeFrame) -> Self {
        let rigid = |o: &cssm_formats::SceneObject| o.kind == cssm_formats::ObjectKind::Rigid;
        if !scene.objects.iter().any(rigid) {
            let bvh = match frame {
                CubeFrame::World => raycast::SceneBvh::new(scene),
                CubeFrame::Turned => raycast::SceneBvh::new(&Scene::from_triangles(
                    scene.positions.iter().map(|&p| frame.to_cube(p)).collect(),
                    scene.triangles.clone(),
                )),
            };
            return Self {
                bvhs: vec![bvh],
                bvh_of_object: vec![0; scene.objects.len()],
            };
        }
        let turn = glam::Affine3A::from_mat3(frame.rotation());
        // The static objects (all but the rigid ones) stand together: they never move apart.
        let mut fixed = Scene::from_triangles(Vec::new(), Vec::new());
        let mut bvhs = Vec::new();
        let mut bvh_of_object = Vec::with_capacity(scene.objects.len());
        for (i, o) in scene.objects.iter().enumerate() {
            let mesh = scene.object_mesh(i, turn);
            if rigid(o) {
                bvh_of_object.push(bvhs.len());
                bvhs.push(raycast::SceneBvh::new(&mesh));
            } else {
                bvh_of_object.push(usize::MAX);
                let base = fixed.positions.len() as u32;
                fixed.positions.extend(mesh.positions);
                fixed
                    .triangles
                    .extend(mesh.triangles.iter().map(|t| t.map(|v| v + base)));
            }
        }
        if !fixed.triangles.is_empty() {
            fixed.triangle_materials = vec![0; fixed.triangles.len()];
            fixed.objects = vec![cssm_formats::SceneObject::whole_static(
                fixed.triangles.len(),
            )];
            for b in bvh_of_object.iter_mut().filter(|b| **b == usize::MAX) {
                *b = bvhs.len();
            }
            bvhs.push(raycast::SceneBvh::new(&fixed));
        }
        Self {
            bvhs,
            bvh_of_object,
        }
    }

    /// A cube-map renderer over each BVH, as `choice` says, on `grid`.
    fn renderers(&self, choice: cubemap::CubeRenderer, grid: PixelGrid) -> TexelRenderers<'_> {
        TexelRenderers {
            renderers: self
                .bvhs
                .iter()
                .map(|bvh| cubemap::Renderer::new(bvh, choice, grid))
                .collect(),
            of_object: &self.bvh_of_object,
        }
    }
}

/// The renderers of [`TexelGeometry`]'s geometries.
struct TexelRenderers<'a> {
    renderers: Vec<cubemap::Renderer<'a>>,
    of_object: &'a [usize],
}

impl TexelRenderers<'_> {
    /// The renderer of what the cube map of `texel` sees.
    fn seen_from(&self, texel: &cssm_formats::Texel) -> &cubemap::Renderer<'_> {
        &self.renderers[self.of_object[texel.object as usize]]
    }
}

/// Renders the cube maps of texels `ids` into `slots` (`6 * n * n` intervals each), in parallel;
/// returns the rays cast.
#[allow(clippy::too_many_arguments)]
fn render_maps(
    renderer: &TexelRenderers,
    texels: &[cssm_formats::Texel],
    ids: &[u32],
    n: u32,
    near: f32,
    quantizer: &DepthQuantizer,
    second_layer: cubemap::SecondLayer,
    slots: &mut [cubemap::Interval],
) -> u64 {
    slots
        .par_chunks_mut((6 * n * n) as usize)
        .zip(ids.par_iter())
        .map(|(out, &texel)| {
            let texel = &texels[texel as usize];
            renderer
                .seen_from(texel)
                .render(texel, n, near, quantizer, second_layer, out)
        })
        .sum()
}

/// The pilot of [`Traversal::Piloted`]: bakes the chart's texels at `options`' cube resolution,
/// compresses them in each of `orders` (permutations of the same texels) with `options`'
/// compressor settings, and returns the index of the order with the fewest runs (the first of
/// equals). A chart of up to `cached_maps` texels ([`PILOT_CACHED_MAPS`] in the bake) is rendered
/// once and its maps reused for every order; a larger one is rendered again for each order,
/// batch by batch, so memory stays bounded however large the chart.
fn fewest_runs(
    renderer: &TexelRenderers,
    texels: &[cssm_formats::Texel],
    orders: &[&[u32]],
    near: f32,
    quantizer: &DepthQuantizer,
    options: &BakeOptions,
    cached_maps: usize,
) -> usize {
    let Some(&first) = orders.first() else {
        return 0;
    };
    let n = options.cube_resolution;
    let pixels = (6 * n * n) as usize;
    let render = |ids: &[u32], slots: &mut [cubemap::Interval]| {
        render_maps(
            renderer,
            texels,
            ids,
            n,
            near,
            quantizer,
            options.second_layer,
            slots,
        );
    };
    // Small charts (nearly all of them): every map once, found by texel.
    let cache = (first.len() <= cached_maps).then(|| {
        let mut maps = vec![cubemap::DONT_CARE; first.len() * pixels];
        render(first, &mut maps);
        let slot: std::collections::HashMap<u32, usize> =
            first.iter().enumerate().map(|(k, &t)| (t, k)).collect();
        (slot, maps)
    });
    let mut batch = vec![cubemap::DONT_CARE; first.len().min(PILOT_BATCH_MAPS) * pixels];
    let mut runs = |order: &[u32]| {
        let mut compressor = compress::Compressor::with_options(
            pixels as u32,
            order.len() as u32,
            compress::CompressOptions {
                run_value: options.run_value,
                merge_short_runs: options.merge_short_runs,
                // The stored code does not change where runs end.
                near_codes: 0.0,
            },
        );
        for ids in order.chunks(PILOT_BATCH_MAPS) {
            let slots = &mut batch[..ids.len() * pixels];
            match &cache {
                Some((slot, maps)) => {
                    for (out, texel) in slots.chunks_mut(pixels).zip(ids) {
                        let k = slot[texel];
                        out.copy_from_slice(&maps[k * pixels..(k + 1) * pixels]);
                    }
                }
                None => render(ids, slots),
            }
            compressor.push(slots);
        }
        compressor.finish().runs.len()
    };
    let counts: Vec<usize> = orders.iter().map(|order| runs(order)).collect();
    (0..counts.len()).min_by_key(|&i| counts[i]).unwrap_or(0)
}

/// Maps per batch the pilot hands its compressor.
const PILOT_BATCH_MAPS: usize = 256;

/// Largest chart whose pilot maps are rendered once for all orders (6 MiB at cube 8).
const PILOT_CACHED_MAPS: usize = 4096;

#[cfg(test)]
pub(crate) mod tests {
    use cssm_formats::Scene;
    use glam::Vec3;

    /// The pilot keeps the order that compresses into fewer runs, whether it renders the chart
    /// once or once per order: texels along a line under a ceiling, half of them also under a
    /// slab, walked in a row or hopping between the two halves.
    #[test]
    fn pilot_keeps_the_order_with_fewer_runs() {
        let scene = Scene::from_triangles(
            vec![
                Vec3::new(-3.0, -1.0, 1.0),
                Vec3::new(0.0, -1.0, 1.0),
                Vec3::new(0.0, 1.0, 1.0),
                Vec3::new(-3.0, 1.0, 1.0),
                Vec3::new(-3.0, -1.0, 3.0),
                Vec3::new(3.0, -1.0, 3.0),
                Vec3::new(3.0, 1.0, 3.0),
                Vec3::new(-3.0, 1.0, 3.0),
            ],
            vec![[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]],
        );
        let geometry = super::TexelGeometry::new(&scene, super::CubeFrame::World);
        let renderer = geometry.renderers(
            super::cubemap::CubeRenderer::Bvh,
            super::PixelGrid::Staggered,
        );
        let texels: Vec<cssm_formats::Texel> = (0..40u16)
            .map(|i| cssm_formats::Texel {
                position: [-1.5 + 0.075 * f32::from(i), 0.0, 0.0],
                normal: [0.0, 0.0, 1.0],
                area: 1.0,
                material: 0,
                chart: 0,
                object: 0,
                x: i,
                y: 0,
            })
            .collect();
        let in_a_row: Vec<u32> = (0..40).collect();
        let hopping: Vec<u32> = (0..20).flat_map(|i| [i, i + 20]).collect();
        let options = super::BakeOptions {
            cube_resolution: 8,
            ..Default::default()
        };
        let quantizer = super::DepthQuantizer::new(0.01, 10.0);
        for cached_maps in [usize::MAX, 0] {
            let pick = |orders: &[&[u32]]| {
                super::fewest_runs(
                    &renderer,
                    &texels,
                    orders,
                    0.01,
                    &quantizer,
                    &options,
                    cached_maps,
                )
            };
            assert_eq!(
                pick(&[&hopping, &in_a_row]),
                1,
                "cached up to {cached_maps}"
            );
            assert_eq!(
                pick(&[&in_a_row, &hopping]),
                0,
                "cached up to {cached_maps}"
            );
        }
    }
}
