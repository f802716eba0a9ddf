//! `cssm bake --device gpu` (issue 25): the depth cube maps' rays cast on the GPU by the
//! runtime's compute kernel (`cssm_runtime::visibility::depth_maps`, a BVH traversal in WGSL),
//! batch after batch; the CPU turns each pixel's hits into its interval with the very code of
//! its own renderers ([`cubemap::render_with`]) and casts itself the few pixels the kernel
//! marks. The kernel's rays are the CPU's: the same cube centres (computed here), the same
//! directions and the same watertight test; GPUs may round a division or fuse a multiply-add
//! where the CPU does not, so a ray through an edge may decide otherwise (measured in
//! reports/bake.md, "The bake on the GPU").

use cssm_formats::{Texel, cube::DepthQuantizer};
use cssm_runtime::{
    Gpu,
    visibility::depth_maps::{DepthMapKernel, DepthMapSettings, DepthMapTexel, decode},
};
use rayon::prelude::*;

use crate::{BakeError, TexelGeometry, cubemap};

/// The GPU and one kernel per geometry the texels see ([`TexelGeometry`]).
pub(crate) struct GpuMaps<'a> {
    gpu: Gpu,
    kernels: Vec<DepthMapKernel>,
    geometry: &'a TexelGeometry,
}

fn gpu_error(e: impl std::fmt::Display) -> BakeError {
    BakeError::Gpu(e.to_string())
}

impl<'a> GpuMaps<'a> {
    /// The first GPU wgpu finds (lavapipe where there is none) with `geometry`'s BVHs on it.
    pub(crate) fn new(geometry: &'a TexelGeometry) -> Result<Self, BakeError> {
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

    /// Renders the cube maps of texels `ids` into `slots` (`6 * n * n` intervals each), as
    /// `render_maps` does on the CPU; returns the rays cast.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn render_maps(
        &self,
        texels: &[Texel],
        ids: &[u32],
        n: u32,
        near: f32,
        quantizer: &DepthQuantizer,
        second_layer: cubemap::SecondLayer,
        slots: &mut [cubemap::Interval],
    ) -> Result<u64, BakeError> {
        let pixels = 6 * n as usize * n as usize;
        let geometry_of =
            |id: u32| self.geometry.bvh_of_object[texels[id as usize].object as usize];
        // Each geometry's texels of the batch in one dispatch; `answer[k]` is map k's place in
        // its geometry's answers.
        let mut answers = Vec::with_capacity(self.kernels.len());
        let mut answer = vec![(0, 0); ids.len()];
        for (g, kernel) in self.kernels.iter().enumerate() {
            let mine: Vec<usize> = (0..ids.len())
                .filter(|&k| geometry_of(ids[k]) == g)
                .collect();
            let cast: Vec<DepthMapTexel> = mine
                .iter()
                .map(|&k| {
                    let texel = &texels[ids[k] as usize];
                    DepthMapTexel {
                        centre: cubemap::centre(texel, near).to_array(),
                        normal: texel.normal,
                        ..Default::default()
                    }
                })
                .collect();
            for (j, &k) in mine.iter().enumerate() {
                answer[k] = (g, j);
            }
            let settings = DepthMapSettings {
                resolution: n,
                min_hit: cubemap::min_hit(near, self.geometry.bvhs[g].magnitude()),
                separation: cubemap::separation(quantizer),
                every_hit_faces: second_layer == cubemap::SecondLayer::Any,
            };
            answers.push(kernel.run(&self.gpu, &cast, settings).map_err(gpu_error)?);
        }
        let rays = slots
            .par_chunks_mut(pixels)
            .zip(ids.par_iter())
            .zip(answer.par_iter())
            .map(|((out, &id), &(g, j))| {
                let texel = &texels[id as usize];
                let hits = &answers[g][j * pixels..(j + 1) * pixels];
                let cast =
                    cubemap::ray_caster(&self.geometry.bvhs[g], near, quantizer, second_layer);
                cubemap::render_with(texel, n, near, quantizer, second_layer, out, |p, c, d| {
                    decode(hits[p]).unwrap_or_else(|| cast(c, d))
                })
            })
            .sum();
        Ok(rays)
    }
}
