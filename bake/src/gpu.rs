//! `cssm bake --device gpu` (issue 25): the depth cube maps' rays cast on the GPU by the
//! runtime's compute kernel (`cssm_runtime::visibility::depth_maps`, a BVH traversal in WGSL),
//! batch after batch; the CPU turns each pixel's hits into its interval with the very code of
//! its own renderers ([`cubemap::render_with`]) and casts itself the few pixels the kernel
//! marks. The kernel's rays are the CPU's: the same cube centres (computed here), the same
//! directions and the same watertight test; GPUs may round a division or fuse a multiply-add
//! where the CPU does not, so a ray through an edge may decide otherwise (measured in
//! reports/bake.md, "The bake on the GPU").

use cssm_formats::{
    Texel,
    cube::{DepthQuantizer, PixelGrid},
};
use cssm_runtime::{
    Gpu,
    visibility::depth_maps::{
        DepthMapBuffers, DepthMapKernel, DepthMapSettings, DepthMapTexel, PixelHits, decode,
    },
};
use rayon::prelude::*;

use crate::{BakeError, TexelGeometry, cubemap};

/// The GPU and one kernel per geometry the texels see ([`TexelGeometry`]).
pub(crate) struct GpuMaps<'a> {
    gpu: Gpu,
    kernels: Vec<DepthMapKernel>,
    geometry: &'a TexelGeometry,
    /// Where every texel's pixels sit.
    grid: PixelGrid,
}

fn gpu_error(e: impl std::fmt::Display) -> BakeError {
    BakeError::Gpu(e.to_string())
}

impl<'a> GpuMaps<'a> {
    /// The first GPU wgpu finds (lavapipe where there is none) with `geometry`'s BVHs on it,
    /// casting each texel's pixels on `grid`.
    pub(crate) fn new(geometry: &'a TexelGeometry, grid: PixelGrid) -> Result<Self, BakeError> {
        let gpu = Gpu::new_headless().map_err(gpu_error)?;
        let kernels = geometry
            .bvhs
            .iter()
            .map(|bvh| {
                let (triangles, normals) = bvh.triangles_by_scene_index();
                DepthMapKernel::new(&gpu, &triangles, normals, bvh.box_padding())
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(gpu_error)?;
        Ok(Self {
            gpu,
            kernels,
            geometry,
            grid,
        })
    }

    /// The adapter, as the runtime describes it.
    pub(crate) fn describe(&self) -> String {
        self.gpu.describe()
    }

    /// Maps per batch at cube resolution `n`: as many as one readback holds.
    pub(crate) fn batch_maps(&self, n: u32) -> usize {
        DepthMapKernel::max_texels(&self.gpu, n)
    }

    /// Renders the cube maps of texels `sequence` in order, `batch` maps at a time (at most
    /// [`GpuMaps::batch_maps`]), handing each batch's intervals (`6 * n * n` per map) to `each`
    /// with the number of maps done so far; returns the rays cast. The GPU casts the next batch
    /// while the CPU finishes this one and `each` compresses it.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn render_in_order(
        &self,
        texels: &[Texel],
        sequence: &[u32],
        n: u32,
        near: f32,
        quantizer: &DepthQuantizer,
        second_layer: cubemap::SecondLayer,
        batch: usize,
        each: &mut dyn FnMut(usize, &[cubemap::Interval]),
    ) -> Result<u64, BakeError> {
        let pixels = 6 * n as usize * n as usize;
        let batch = batch.min(sequence.len()).max(1);
        let mut slots = vec![cubemap::DONT_CARE; batch * pixels];
        let mut rays = 0;
        std::thread::scope(|scope| {
            // One batch cast ahead: at most three batches' answers in memory (the one being
            // finished, the one waiting, the one being cast).
            let (send, receive) = std::sync::mpsc::sync_channel(1);
            scope.spawn(move || {
                let mut buffers = DepthMapBuffers::default();
                for ids in sequence.chunks(batch) {
                    let cast =
                        self.cast(&mut buffers, texels, ids, n, near, quantizer, second_layer);
                    let failed = cast.is_err();
                    if send.send(cast).is_err() || failed {
                        break;
                    }
                }
            });
            let mut done = 0;
            for ids in sequence.chunks(batch) {
                let cast = receive
                    .recv()
                    .map_err(|_| BakeError::Gpu("the GPU thread stopped".into()))??;
                let out = &mut slots[..ids.len() * pixels];
                rays += self.finish(&cast, texels, ids, n, near, quantizer, second_layer, out);
                done += ids.len();
                each(done, out);
            }
            Ok(rays)
        })
    }

    /// The GPU's answers for texels `ids`: each geometry's texels in one dispatch.
    #[allow(clippy::too_many_arguments)]
    fn cast(
        &self,
        buffers: &mut DepthMapBuffers,
        texels: &[Texel],
        ids: &[u32],
        n: u32,
        near: f32,
        quantizer: &DepthQuantizer,
        second_layer: cubemap::SecondLayer,
    ) -> Result<Cast, BakeError> {
        let geometry_of =
            |id: u32| self.geometry.bvh_of_object[texels[id as usize].object as usize];
        let mut answers = Vec::with_capacity(self.kernels.len());
        let mut place = vec![(0, 0); ids.len()];
        for (g, kernel) in self.kernels.iter().enumerate() {
            let mine: Vec<usize> = (0..ids.len())
                .filter(|&k| geometry_of(ids[k]) == g)
                .collect();
            let cast: Vec<DepthMapTexel> = mine
                .iter()
                .map(|&k| {
                    let texel = &texels[ids[k] as usize];
                    let offset = self.grid.offset(texel.x, texel.y);
                    DepthMapTexel {
                        centre: cubemap::centre(texel, near).to_array(),
                        grid_u: offset.x,
                        normal: texel.normal,
                        grid_v: offset.y,
                    }
                })
                .collect();
            for (j, &k) in mine.iter().enumerate() {
                place[k] = (g, j);
            }
            let settings = DepthMapSettings {
                resolution: n,
                min_hit: cubemap::min_hit(near, self.geometry.bvhs[g].magnitude()),
                separation: cubemap::separation(quantizer),
                every_hit_faces: second_layer == cubemap::SecondLayer::Any,
            };
            answers.push(
                kernel
                    .run_with(&self.gpu, buffers, &cast, settings)
                    .map_err(gpu_error)?,
            );
        }
        Ok(Cast { answers, place })
    }

    /// The intervals of texels `ids` from their answers `cast` (`6 * n * n` per map into
    /// `slots`), in parallel; the pixels the kernel handed back are cast here. Returns the rays.
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &self,
        cast: &Cast,
        texels: &[Texel],
        ids: &[u32],
        n: u32,
        near: f32,
        quantizer: &DepthQuantizer,
        second_layer: cubemap::SecondLayer,
        slots: &mut [cubemap::Interval],
    ) -> u64 {
        let pixels = 6 * n as usize * n as usize;
        slots
            .par_chunks_mut(pixels)
            .zip(ids.par_iter())
            .zip(cast.place.par_iter())
            .map(|((out, &id), &(g, j))| {
                let texel = &texels[id as usize];
                let hits = &cast.answers[g][j * pixels..(j + 1) * pixels];
                let ray =
                    cubemap::ray_caster(&self.geometry.bvhs[g], near, quantizer, second_layer);
                let hit = |p: usize, c, d| decode(hits[p]).unwrap_or_else(|| ray(c, d));
                cubemap::render_with(texel, self.grid, n, near, quantizer, second_layer, out, hit)
            })
            .sum()
    }
}

/// One batch's answers from the GPU: each geometry's, and for every map of the batch its
/// geometry and its place among that geometry's maps.
struct Cast {
    answers: Vec<Vec<PixelHits>>,
    place: Vec<(usize, usize)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Batches in flight one behind the other give the maps of one CPU batch, in order: the
    /// Cornell box's texels in batches of 7 maps (the last one short) against the CPU.
    #[test]
    fn batches_in_flight_keep_the_order() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box");
        let scene = cssm_formats::Scene::load(&dir).expect("the built-in Cornell box");
        let atlas = crate::atlas::build(&scene, 32, &mut |_| {}).expect("atlas");
        let geometry = TexelGeometry::new(&scene, cssm_formats::cube::CubeFrame::World);
        // A staggered grid: the kernel's rays follow each texel's offset as the CPU's do.
        let grid = PixelGrid::Staggered;
        let maps = GpuMaps::new(&geometry, grid).expect("a GPU (lavapipe where there is none)");
        let (n, near) = (8, 0.5);
        let quantizer = DepthQuantizer::new(near, scene.diameter());
        let layer = cubemap::SecondLayer::Exchange;
        let sequence: Vec<u32> = (0..atlas.texels.len() as u32).rev().step_by(3).collect();
        let pixels = 6 * 8 * 8;
        let mut gpu = Vec::new();
        let mut counts = Vec::new();
        maps.render_in_order(
            &atlas.texels,
            &sequence,
            n,
            near,
            &quantizer,
            layer,
            7,
            &mut |done, slots| {
                counts.push(done);
                gpu.extend_from_slice(slots);
            },
        )
        .expect("GPU bake");
        let batches = sequence.len().div_ceil(7);
        assert_eq!(counts.len(), batches);
        assert_eq!(counts.last(), Some(&sequence.len()));
        let renderers = geometry.renderers(cubemap::CubeRenderer::Bvh, grid);
        let mut cpu = vec![cubemap::DONT_CARE; sequence.len() * pixels];
        crate::render_maps(
            &renderers,
            &atlas.texels,
            &sequence,
            n,
            near,
            &quantizer,
            layer,
            &mut cpu,
        );
        let differ = gpu.iter().zip(&cpu).filter(|(g, c)| g != c).count();
        // Lavapipe rounds as the CPU does; a GPU may decide a ray through an edge otherwise.
        assert!(
            differ * 1000 <= cpu.len(),
            "{differ} of {} pixels differ",
            cpu.len()
        );
        if maps.describe().contains("llvmpipe") {
            assert_eq!(differ, 0);
        }
    }
}
