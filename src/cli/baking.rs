//! `cssm bake`, `cssm merge` and `cssm inspect`: their flags, and `bake`'s turned into the bake
//! library's options.

use super::*;

#[derive(clap::Args)]
pub struct BakeArgs {
    /// The scene: a directory (scene.toml with OBJ/MTL or glTF meshes, or a directory of .obj,
    /// .gltf and .glb files), or one .obj, .gltf or .glb file. Default: the built-in Cornell box.
    scene: Option<PathBuf>,
    /// Output file. Default: <scene name>.cssm in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Atlas width and height in texels (32 to 1024).
    #[arg(long, default_value_t = 64)]
    atlas: u32,
    /// Cube-map face resolution N; each map has 6 x N x N pixels (8 to 128).
    #[arg(long, default_value_t = 32)]
    cube: u32,
    /// Order of the depth-map sequence: zigzag, spiral or greedy (§3.2.3); hilbert (chart by
    /// chart, a Hilbert curve inside each chart; beyond the paper: in reports/compression.md it
    /// compresses better than the paper's orders at the same accuracy); or piloted (per chart the
    /// Hilbert or the Spiral order, whichever a pilot bake of the chart at cube 8 compresses
    /// better; beyond the paper, and the default: a little better than hilbert for a little more
    /// bake time, part of the report's best variant).
    #[arg(long, default_value = "piloted")]
    traversal: Traversal,
    /// How the chart-by-chart traversals choose the next chart: nearest (§3.2.3: the chart whose
    /// first texel is nearest) or ends (the chart with an end, first or last texel, nearest;
    /// walked backwards from its last one; beyond the paper).
    #[arg(long, default_value = "nearest")]
    chart_order: bake::traverse::ChartOrder,
    /// Which depth a run stores inside the codes all its maps accept: middle (the middle code)
    /// or balanced (equal relative margins to the near and the far layer). Beyond the paper.
    #[arg(long, default_value = "middle")]
    run_value: bake::compress::RunValue,
    /// Lossy: merge runs of at most this many depth maps into their neighbours when those agree
    /// (0: lossless, as in the paper). Fewer runs, a few wrong depths; measure with `cssm check`.
    #[arg(long, default_value_t = 0)]
    merge_short_runs: u32,
    /// Which intersections bound each pixel's depth interval: any (the first and the second, as in
    /// the paper); facing (the second is the nearest one beyond the first whose surface faces the
    /// texel: surfaces facing away exchange no light with it, so their visibility never matters;
    /// beyond the paper); or exchange (as facing, and a first surface that faces away sets no
    /// lower bound; a pixel that meets no facing surface, nor do its neighbours, is don't care;
    /// beyond the paper, and the default: exact for every pair that exchanges light, the only
    /// visibility an image uses, in a much smaller file; reports/compression.md, best variant).
    #[arg(long, default_value = "exchange")]
    second_layer: bake::cubemap::SecondLayer,
    /// Which renderer draws the depth cube maps: raster (triangle by triangle, the watertight
    /// ray/triangle test on the pixels each triangle covers; fastest for scenes of few
    /// triangles), bvh (one BVH traversal per pixel), or auto (raster for scenes of at most
    /// N^2.5/5 triangles at cube resolution N, about where the two break even: 1,158 at cube 32,
    /// 6,553 at cube 64; bvh above; the default).
    /// The file is byte-identical either way; only the time differs (reports/bake.md).
    #[arg(long, default_value = "auto")]
    cube_renderer: bake::cubemap::CubeRenderer,
    /// Where each texel's cube-map pixels sit: centred (the paper's grid; the default) or
    /// staggered (each texel's grid shifted by an eighth of a pixel along both face axes, the
    /// signs set by its atlas column's and row's parity, so the neighbouring texels the query
    /// filters over see an occluder's edge at different places; beyond the paper: on detailed
    /// interiors it agrees better with exact ray casts for a few more runs, on simple scenes at
    /// fine atlases it costs runs for nothing; reports/visibility.md).
    #[arg(long, default_value = "centred", value_name = "GRID")]
    pixel_grid: formats::cube::PixelGrid,
    /// How every texel's cube map lies in the world: turned (the default: one fixed rotation
    /// that takes the world's up axis to the cube's diagonal, so the vertical and horizontal
    /// edges of rooms, columns and frames cross the pixel grid obliquely and the query's filter
    /// places them better; beyond the paper, for as many runs; reports/visibility.md) or world
    /// (the faces on the world's axes, as in the paper).
    #[arg(long, default_value = "turned", value_name = "FRAME")]
    cube_frame: formats::cube::CubeFrame,
    /// Where the depth maps' rays are cast: cpu (the default; --cube-renderer picks how), or gpu
    /// (a BVH traversal in a compute shader on the first GPU wgpu finds, Mesa's lavapipe where
    /// there is none; the CPU still orders the texels, quantises and compresses). A GPU may round
    /// a ray through an edge otherwise than the CPU, so a few pixels may differ from the CPU's
    /// file (reports/bake.md).
    #[arg(long, default_value = "cpu")]
    device: bake::BakeDevice,
    /// How the file stores the runs: packed (run lengths and depth differences as varints before
    /// zstd: a smaller file, the same data in memory) or plain (zstd only, the first format).
    #[arg(long, default_value = "packed")]
    file_coding: FileCoding,
    /// Distance the cube maps sit off the surface, in scene units. Default: 0.05% of the scene
    /// diameter.
    #[arg(long, value_parser = finite_f32)]
    near: Option<f32>,
    /// Bake only chunk I of N (I from 0 to N-1) for a batch farm: the depth maps of one
    /// contiguous slice of the traversal, into a chunk file (default name
    /// <scene>.chunk-I-of-N); `cssm merge` joins the N chunks into the file one bake writes.
    /// In a Slurm job array: --chunk $SLURM_ARRAY_TASK_ID/N; in a Kubernetes indexed Job:
    /// --chunk $JOB_COMPLETION_INDEX/N (docs/batch-bake.md).
    #[arg(long, value_name = "I/N")]
    chunk: Option<formats::cssm::ChunkSpec>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    json: bool,
}

/// `cssm bake`, checked.
pub struct BakeConfig {
    /// Scene directory or mesh file; `None`: the built-in Cornell box.
    pub scene: Option<PathBuf>,
    /// Output file; `None`: `<scene name>.cssm`.
    pub output: Option<PathBuf>,
    /// What to bake, checked by the bake library as far as it can without the scene.
    pub options: bake::BakeOptions,
    /// How the file codes the runs.
    pub file_coding: FileCoding,
    /// `--chunk I/N`: bake this chunk only.
    pub chunk: Option<formats::cssm::ChunkSpec>,
    /// `--json`.
    pub json: bool,
}

impl BakeArgs {
    /// The bake options, checked by the bake library before any scene is loaded (the near
    /// distance against the scene's size when it is); an error names the flag.
    pub fn config(self) -> Result<BakeConfig, String> {
        let options = bake::BakeOptions {
            atlas_resolution: self.atlas,
            cube_resolution: self.cube,
            traversal: self.traversal,
            chart_order: self.chart_order,
            near: self.near,
            run_value: self.run_value,
            merge_short_runs: self.merge_short_runs,
            second_layer: self.second_layer,
            cube_renderer: self.cube_renderer,
            device: self.device,
            pixel_grid: self.pixel_grid,
            cube_frame: self.cube_frame,
        };
        options.check().map_err(|e| cssm::flag_error(&e))?;
        Ok(BakeConfig {
            scene: self.scene,
            output: self.output,
            options,
            file_coding: self.file_coding,
            chunk: self.chunk,
            json: self.json,
        })
    }
}

#[derive(clap::Args)]
pub struct MergeArgs {
    /// The chunk files (cssm bake --chunk I/N), all N of them, in any order.
    #[arg(required = true, value_name = "CHUNKS")]
    pub chunks: Vec<PathBuf>,
    /// Output file. Default: <scene name>.cssm in the current directory.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
}

#[derive(clap::Args)]
pub struct InspectArgs {
    /// The .cssm file.
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}
