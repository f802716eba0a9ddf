//! One bake, or one chunk's slice of it ([`bake_slice`]), as the outline of its steps (§3.2):
//! the atlas, the texels' coherent order, their depth cube maps streamed into the compressor,
//! the texel hierarchy, the moving objects' CSMs, and the file they make.

use super::*;

/// [`bake`], or with `chunk` the tables of the whole bake and the runs of the chunk's slice.
pub(crate) fn bake_slice(
    scene: &Scene,
    options: &BakeOptions,
    chunk: Option<cssm_formats::cssm::ChunkSpec>,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> Result<(CssmFile, BakeStats), BakeError> {
    options.check()?;
    let (near, far) = depth_range(scene, options)?;
    let mut stats = BakeStats::default();

    // 1. Atlas (§3.2.3).
    let atlas = build_atlas(scene, options, &mut stats, progress)?;

    // The depth maps' renderers, in the cube frame (the BVH build counts as the maps' time).
    let t0 = Instant::now();
    let frame = options.cube_frame;
    let geometry = TexelGeometry::new(scene, frame);
    let frame_texels = texels_in_frame(&atlas.texels, frame);
    let renderer = geometry.renderers(options.cube_renderer, options.pixel_grid);
    let gpu_maps = match options.device {
        BakeDevice::Cpu => None,
        BakeDevice::Gpu => {
            let maps = gpu::GpuMaps::new(&geometry, options.pixel_grid)?;
            stats.gpu = Some(maps.describe());
            Some(maps)
        }
    };
    let maps = MapSource {
        renderer: &renderer,
        gpu: gpu_maps.as_ref(),
        texels: &frame_texels,
        near,
        quantizer: DepthQuantizer::new(near, far),
    };
    let bvh_time = t0.elapsed();

    // 2. Coherent order of the texels (§3.2.3).
    let sequence = coherent_order(&maps, &atlas, options, &mut stats, progress);

    // 3. + 4. Depth cube maps, streamed in batches into the compressor (§3.2.1, §3.1).
    let t0 = Instant::now();
    let runs = maps_into_runs(&maps, &sequence, chunk, options, far, &mut stats, progress)?;
    stats.maps_time = bvh_time + t0.elapsed();
    stats.uncompressed_bytes = runs.uncompressed_bytes();
    stats.gpu_bytes = runs.gpu_bytes();
    stats.runs = runs.runs.len() as u64;

    // 5. The texel hierarchy over the final texel table (§4.2).
    let t0 = Instant::now();
    let hierarchy = Hierarchy::build(&atlas.texels);
    stats.hierarchy_time = t0.elapsed();

    // 6. A coherent shadow map per rigid object (§3.3), in its own space.
    let csms = object_csms(scene, &mut stats, progress);

    let file = CssmFile {
        params: BakeParams {
            atlas_resolution: atlas.resolution,
            cube_resolution: options.cube_resolution,
            near,
            far,
            traversal: options.traversal,
        },
        scene: SceneRef {
            dir: scene.path.to_string_lossy().into_owned(),
            name: scene.name.clone(),
            content_hash: scene.content_hash,
            triangle_count: scene.triangles.len() as u32,
        },
        texels: atlas.texels,
        triangle_uvs: atlas.triangle_uvs,
        sequence,
        hierarchy,
        runs,
        csms,
        pixel_grid: options.pixel_grid,
        cube_frame: frame,
    };
    Ok((file, stats))
}

/// The depth range of the maps: from the near distance (the option, or a fraction of the
/// scene's diameter) to the diameter.
fn depth_range(scene: &Scene, options: &BakeOptions) -> Result<(f32, f32), BakeError> {
    let far = scene.diameter();
    if !(far.is_finite() && far > 0.0) {
        return Err(BakeError::Scene("the scene has no extent".into()));
    }
    let near = options.near.unwrap_or(DEFAULT_NEAR_FRACTION * far);
    check_near(near, Some(far))?;
    Ok((near, far))
}

/// Step 1: the atlas (§3.2.3), refused when no texel is covered.
fn build_atlas(
    scene: &Scene,
    options: &BakeOptions,
    stats: &mut BakeStats,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> Result<atlas::Atlas, BakeError> {
    let t0 = Instant::now();
    let atlas = atlas::build(scene, options.atlas_resolution, progress)?;
    stats.atlas_time = t0.elapsed();
    stats.charts = atlas.chart_count;
    stats.defined_texels = atlas.texels.len() as u64;
    if atlas.texels.is_empty() {
        return Err(BakeError::Atlas(
            "no atlas texel is covered by the scene".into(),
        ));
    }
    Ok(atlas)
}

/// The texels as the renderers see them: turned into the cube frame, so that the maps are
/// those of cube maps turned against the world (the file keeps the world's texels).
fn texels_in_frame(
    texels: &[cssm_formats::Texel],
    frame: CubeFrame,
) -> std::borrow::Cow<'_, [cssm_formats::Texel]> {
    match frame {
        CubeFrame::World => std::borrow::Cow::Borrowed(texels),
        CubeFrame::Turned => texels
            .iter()
            .map(|t| cssm_formats::Texel {
                position: frame.to_cube(t.pos()).to_array(),
                normal: frame.to_cube(t.nrm()).to_array(),
                ..*t
            })
            .collect(),
    }
}

/// What renders the texels' depth cube maps: the CPU renderers, or the GPU's when the bake
/// runs there, over the texels in the cube frame.
struct MapSource<'a> {
    renderer: &'a TexelRenderers<'a>,
    gpu: Option<&'a gpu::GpuMaps<'a>>,
    texels: &'a [cssm_formats::Texel],
    near: f32,
    quantizer: DepthQuantizer,
}

/// Step 2: the coherent order of the texels (§3.2.3), the traversal piloted by the runs a small
/// cube resolution gives.
fn coherent_order(
    maps: &MapSource,
    atlas: &atlas::Atlas,
    options: &BakeOptions,
    stats: &mut BakeStats,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> Vec<u32> {
    let t0 = Instant::now();
    progress(Progress {
        stage: Stage::Order,
        done: 0,
        total: 0,
    });
    let pilot = |orders: &[&[u32]]| {
        let pilot_options = BakeOptions {
            cube_resolution: options.cube_resolution.min(PILOT_CUBE_RESOLUTION),
            ..options.clone()
        };
        fewest_runs(
            maps.renderer,
            maps.texels,
            orders,
            maps.near,
            &maps.quantizer,
            &pilot_options,
            PILOT_CACHED_MAPS,
        )
    };
    let sequence = traverse::traverse_piloted(
        &atlas.texels,
        atlas.resolution,
        options.traversal,
        options.chart_order,
        &pilot,
    );
    stats.traversal_time = t0.elapsed();
    sequence
}

/// Steps 3 and 4: the depth cube maps of `sequence` (of the chunk's slice of it), rendered in
/// batches and streamed into the compressor (§3.2.1, §3.1).
fn maps_into_runs(
    maps: &MapSource,
    sequence: &[u32],
    chunk: Option<cssm_formats::cssm::ChunkSpec>,
    options: &BakeOptions,
    far: f32,
    stats: &mut BakeStats,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> Result<cssm_formats::RunData, BakeError> {
    let n = options.cube_resolution;
    let near = maps.near;
    let pixel_count = 6 * n * n;
    // A chunk bakes its slice of whole segments: the compressor starts each segment afresh, so
    // its runs are those of the same segments in the whole bake.
    let slice = match chunk {
        Some(spec) => spec.maps(sequence.len() as u32),
        None => 0..sequence.len() as u32,
    };
    let slice = &sequence[slice.start as usize..slice.end as usize];
    let map_count = slice.len() as u32;
    let mut compressor = compress::Compressor::with_options(
        pixel_count,
        map_count,
        compress::CompressOptions {
            run_value: options.run_value,
            merge_short_runs: options.merge_short_runs,
            // Depth is `near + code / scale`, so the near distance is `near * scale` codes.
            near_codes: f64::from(near) * f64::from(cssm_formats::cube::DEPTH_MAX)
                / f64::from(far - near),
        },
    );
    let mut compressed = |done: usize, slots: &[cubemap::Interval]| {
        compressor.push(slots);
        progress(Progress {
            stage: Stage::Maps,
            done: done as u64,
            total: u64::from(map_count),
        });
    };
    match maps.gpu {
        Some(gpu_maps) => {
            stats.rays += gpu_maps.render_in_order(
                maps.texels,
                slice,
                n,
                near,
                &maps.quantizer,
                options.second_layer,
                gpu_maps.batch_maps(n),
                &mut compressed,
            )?;
        }
        None => {
            // Enough maps per batch to keep every core busy, small enough to stay in
            // cache-sized memory.
            let batch_maps = (4 * rayon::current_num_threads())
                .max(8)
                .min(map_count as usize)
                .max(1);
            let mut batch = vec![cubemap::DONT_CARE; batch_maps * pixel_count as usize];
            let mut done = 0;
            for ids in slice.chunks(batch_maps) {
                let slots = &mut batch[..ids.len() * pixel_count as usize];
                stats.rays += render_maps(
                    maps.renderer,
                    maps.texels,
                    ids,
                    n,
                    near,
                    &maps.quantizer,
                    options.second_layer,
                    slots,
                );
                done += ids.len();
                compressed(done, slots);
            }
        }
    }
    Ok(compressor.finish())
}

/// Step 6: a coherent shadow map per rigid object (§3.3), in its own space.
fn object_csms(
    scene: &Scene,
    stats: &mut BakeStats,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> Vec<cssm_formats::csm::CsmData> {
    let t0 = Instant::now();
    let csms = csm::bake_objects(scene, csm::CsmOptions::default(), &mut |done, total| {
        progress(Progress {
            stage: Stage::Csm,
            done,
            total,
        })
    });
    if !csms.is_empty() {
        stats.csm_time = t0.elapsed();
    }
    stats.csms = csms.len() as u64;
    stats.csm_uncompressed_bytes = csms.iter().map(|c| c.runs.uncompressed_bytes()).sum();
    stats.csm_gpu_bytes = csms.iter().map(|c| c.runs.gpu_bytes()).sum();
    csms
}
