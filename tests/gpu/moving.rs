//! The moving objects' query on the GPU (`moving.wgsl`, §3.3) against its CPU reference
//! (`cssm_formats::moving::MovingQuery`): the Cornell box with a rigid block, baked once, queried
//! between posed surface points with the block in several places. Then the block's atlas
//! texels moving with it (`posed.wgsl`): the direct light into the atlas, the radiosity over the
//! refitted hierarchy and the final gather against their CPU twins over the posed scene.

use cssm_bake::BakeOptions;
use cssm_formats::{ObjectKind, Scene, moving::MovingQuery, visibility::QueryOptions};
use cssm_raycast::{SplitMix64, SurfaceSampler};
use cssm_runtime::{
    load::CssmGpu,
    visibility::moving::{MovingEnd, MovingGpu, MovingPair, MovingQueryKernel},
};
use glam::{Affine3A, Quat, Vec3};

use super::{GI_SHADOW, block_scene, block_scene_of, gpu, materials, relative_rmse, vec3s};

#[test]
fn gpu_moving_query_matches_cpu_reference() {
    let gpu = gpu();
    let dir = tempfile::tempdir().unwrap();
    let scene = block_scene(
        dir.path(),
        [150.0, 0.0, 150.0],
        ([278.0, 540.0, 279.5], [0.0, -1.0, 0.0]),
    );
    let options = BakeOptions {
        atlas_resolution: 32,
        cube_resolution: 8,
        ..Default::default()
    };
    let file = cssm_bake::bake(&scene, &options, &mut |_| {}).unwrap().file;
    let query_options = QueryOptions::default();
    let mut query = MovingQuery::new(&file, &scene, query_options).unwrap();
    let mut cssm = CssmGpu::new(&gpu.device, &gpu.queue, &file, query_options).expect("upload");
    let scene_gpu =
        cssm_runtime::load::SceneGpu::new(&gpu.device, &gpu.queue, &scene, Some(&file)).unwrap();
    let moving = MovingGpu::new(&gpu.device, &file, &scene, &scene_gpu.motion)
        .expect("upload the moving objects");
    let t0 = std::time::Instant::now();
    let kernel = MovingQueryKernel::new(gpu, &cssm, &moving);
    eprintln!("kernel built in {:.1} s", t0.elapsed().as_secs_f32());
    // The searches as loops, as every driver but llvmpipe runs them (CSSM_SEARCH_LOOP).
    cssm.search_loop = true;
    let looped = MovingQueryKernel::new(gpu, &cssm, &moving);
    cssm.search_loop = false;

    // The block where it was baked, then lifted, turned and carried across the room.
    let block = scene
        .objects
        .iter()
        .position(|o| o.kind == ObjectKind::Rigid)
        .unwrap();
    let placed = |translation: Vec3, turn_deg: f32| -> Vec<Affine3A> {
        let mut poses: Vec<Affine3A> = scene.objects.iter().map(|o| o.transform).collect();
        poses[block] = Affine3A::from_rotation_translation(
            Quat::from_rotation_y(turn_deg.to_radians()),
            translation,
        );
        poses
    };
    let poses = [
        scene.objects.iter().map(|o| o.transform).collect(),
        placed(Vec3::new(250.0, 200.0, 250.0), 45.0),
        placed(Vec3::new(400.0, 80.0, 100.0), -20.0),
    ];
    for (p, pose) in poses.iter().enumerate() {
        query.set_poses(pose).unwrap();
        for (index, &t) in pose.iter().enumerate() {
            moving.set_pose(&gpu.queue, index, t);
        }
        let posed = scene.posed(pose).unwrap();
        let sampler = SurfaceSampler::new(&posed);
        let mut rng = SplitMix64(17 + p as u64);
        let ends: Vec<_> = (0..20_000)
            .map(|_| {
                let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
                let end = |s: cssm_raycast::SurfacePoint| {
                    MovingEnd::new(
                        s.triangle as u32,
                        s.bary,
                        s.position,
                        s.normal,
                        posed.object_of(s.triangle) as u32,
                    )
                };
                (end(sampler.point(r())), end(sampler.point(r())))
            })
            .collect();
        let pairs: Vec<MovingPair> = ends.iter().map(|&(a, b)| MovingPair { a, b }).collect();
        let answers = kernel
            .run(gpu, &cssm, &moving, &pairs, None)
            .expect("GPU queries");
        let looped_answers = looped
            .run(gpu, &cssm, &moving, &pairs, None)
            .expect("GPU queries, looped");
        assert!(
            looped_answers == answers,
            "pose {p}: the looped searches answer otherwise"
        );
        let (mut differ, mut worst, mut across, mut shadowed_by_csm) = (0, 0.0f32, 0, 0);
        for (pair, &gpu_answer) in pairs.iter().zip(&answers) {
            let cssm_query = query.cssm();
            let senders = |e: &MovingEnd| cssm_query.sender_texels(e.triangle as usize, e.bary);
            let (sa, sb) = (senders(&pair.a), senders(&pair.b));
            let end = |e: &MovingEnd, senders| cssm_formats::moving::ObjectPoint {
                senders,
                position: e.position.into(),
                normal: e.normal.into(),
                object: e.object,
            };
            let (a, b) = (end(&pair.a, &sa), end(&pair.b, &sb));
            let cpu = query.visibility_between(&a, &b);
            across += usize::from(pair.a.object != pair.b.object);
            match cpu {
                None => assert_eq!(gpu_answer, -1.0, "GPU found texels where the CPU did not"),
                Some(cpu) => {
                    // Static pairs the block's CSM shadows: the second step is exercised.
                    if pair.a.object == 0 && pair.b.object == 0 {
                        let csm = query.csms()[0];
                        let to_object = query.placements()[csm.object as usize].to_object;
                        let v = csm.visibility(
                            to_object.transform_point3(a.position),
                            to_object.transform_point3(b.position),
                        );
                        shadowed_by_csm += usize::from(v < 0.5);
                    }
                    differ += usize::from((cpu >= 0.5) != (gpu_answer >= 0.5));
                    worst = worst.max((cpu - gpu_answer).abs());
                }
            }
        }
        eprintln!(
            "pose {p}: GPU vs CPU moving query: {differ} of {} decisions differ, largest \
             difference {worst}; {across} pairs across objects, {shadowed_by_csm} static pairs \
             the block's CSM shadows",
            pairs.len()
        );
        assert!(
            across > 100 && shadowed_by_csm > 100,
            "pose {p}: too few pairs exercise the query"
        );
        assert!(
            differ as f64 <= 1e-3 * pairs.len() as f64,
            "pose {p}: {differ} of {} decisions differ (allowed: 0.1%)",
            pairs.len()
        );
    }
}

/// The block scene lit from above, its block three times as large and wound outwards, baked
/// small, with the block's pose that turns it upside down, lifts it into the air and shrinks it
/// (turned 180 degrees about x, its far corner 200 units up, scale 2.5 instead of 3: its texels'
/// areas shrink by (5/6)^2): the face lit as loaded (its top) faces the floor, and the face
/// that lay on the floor faces the light.
struct FlippedBlock {
    scene: Scene,
    file: cssm_formats::CssmFile,
    block: usize,
    pose: Affine3A,
}

fn flipped_block() -> &'static FlippedBlock {
    static FIXTURE: std::sync::OnceLock<FlippedBlock> = std::sync::OnceLock::new();
    FIXTURE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let scene = block_scene_of(
            dir.path(),
            [150.0, 0.0, 150.0],
            ([278.0, 540.0, 279.5], [0.0, -1.0, 0.0]),
            3.0,
            true,
        );
        let options = BakeOptions {
            atlas_resolution: 32,
            cube_resolution: 8,
            ..Default::default()
        };
        let file = cssm_bake::bake(&scene, &options, &mut |_| {}).unwrap().file;
        let block = scene
            .objects
            .iter()
            .position(|o| o.kind == ObjectKind::Rigid)
            .unwrap();
        let pose = Affine3A::from_scale_rotation_translation(
            Vec3::splat(2.5),
            Quat::from_rotation_x(std::f32::consts::PI) * Quat::from_rotation_y(30f32.to_radians()),
            Vec3::new(250.0, 200.0, 250.0),
        );
        FlippedBlock {
            scene,
            file,
            block,
            pose,
        }
    })
}

impl FlippedBlock {
    /// Every object's pose, the block flipped.
    fn poses(&self) -> Vec<Affine3A> {
        let mut poses: Vec<Affine3A> = self.scene.objects.iter().map(|o| o.transform).collect();
        poses[self.block] = self.pose;
        poses
    }

    /// Every object's motion since loading (pose times the inverse of the loaded transform),
    /// as `Renderer::set_object_transform` writes it.
    fn motions(&self) -> Vec<Affine3A> {
        self.poses()
            .iter()
            .zip(&self.scene.objects)
            .map(|(pose, o)| *pose * o.transform.inverse())
            .collect()
    }

    /// The GPU's atlas direct light and `iterations` bounces, the block flipped when `flip`.
    fn solve(&self, flip: bool, iterations: u32) -> cssm_runtime::radiosity::AtlasRadiosity {
        let gpu = gpu();
        let placed = if flip {
            vec![(self.block, self.pose)]
        } else {
            Vec::new()
        };
        let solved = cssm_runtime::radiosity::atlas_radiosity_posed(
            &gpu.device,
            &gpu.queue,
            &self.scene,
            &self.file,
            GI_SHADOW,
            iterations,
            cssm_runtime::radiosity::RadiosityOptions::default(),
            &placed,
        )
        .expect("radiosity");
        gpu.wait().expect("GPU");
        solved
    }
}

/// Texels whose atlas neighbours in the same chart agree with them on lit or not (away from
/// shadow and cone edges, where the shadow map and the exact rays may differ).
fn away_from_edges(file: &cssm_formats::CssmFile, lit: &[bool]) -> Vec<bool> {
    let r = file.params.atlas_resolution as i64;
    let mut grid = vec![u32::MAX; (r * r) as usize];
    for (i, t) in file.texels.iter().enumerate() {
        grid[(i64::from(t.y) * r + i64::from(t.x)) as usize] = i as u32;
    }
    file.texels
        .iter()
        .enumerate()
        .map(|(i, t)| {
            [(-1, 0), (1, 0), (0, -1), (0, 1)].iter().all(|(dx, dy)| {
                let (x, y) = (i64::from(t.x) + dx, i64::from(t.y) + dy);
                if x < 0 || y < 0 || x >= r || y >= r {
                    return true;
                }
                let n = grid[(y * r + x) as usize];
                n == u32::MAX
                    || file.texels[n as usize].chart != t.chart
                    || lit[n as usize] == lit[i]
            })
        })
        .collect()
}

/// A moved object's atlas texels are lit where it stands (§3.3, `direct/atlas.wgsl` through
/// `posed.wgsl`): the GPU's direct light into the atlas with the block flipped matches the CPU
/// twin over the posed texels in the posed scene, and the block's faces swap light and dark
/// (which texels left where they were baked could not do).
#[test]
fn moved_object_texels_are_lit_where_it_stands() {
    let fixture = flipped_block();
    let (scene, file) = (&fixture.scene, &fixture.file);
    let as_loaded = vec3s(&fixture.solve(false, 0).direct);
    let flipped = vec3s(&fixture.solve(true, 0).direct);

    let posed_scene = scene.posed(&fixture.poses()).unwrap();
    let texels = cssm_formats::moving::posed_texels(&file.texels, &fixture.motions());
    let bvh = cssm_raycast::SceneBvh::new(&posed_scene);
    let twin = cssm_runtime::direct::cpu::render_atlas(
        &posed_scene,
        &materials(&posed_scene),
        &texels,
        &bvh,
    );
    let lit: Vec<bool> = twin.iter().map(|e| e.length_squared() > 0.0).collect();
    let keep = away_from_edges(file, &lit);
    let kept = keep.iter().filter(|&&k| k).count();
    let rmse = relative_rmse(&flipped, &twin, &keep);
    eprintln!(
        "atlas direct light, block flipped: GPU vs CPU twin relative RMSE {:.4}% over {kept} of {} \
         texels",
        100.0 * rmse,
        keep.len()
    );
    assert!(kept > keep.len() / 2, "too few texels compared");
    assert!(rmse < 0.05, "relative RMSE {rmse}");

    // The block's faces by their normal as baked: the top is lit as loaded and dark flipped,
    // the bottom (on the floor) the other way round. Left where they were baked, the texels
    // would keep the light they had as loaded.
    let block = fixture.block as u32;
    let face = |sign: f32| -> Vec<usize> {
        (0..file.texels.len())
            .filter(|&i| file.texels[i].object == block && file.texels[i].normal[1] * sign > 0.9)
            .collect()
    };
    let (top, bottom) = (face(1.0), face(-1.0));
    let lit_share = |light: &[Vec3], texels: &[usize]| {
        texels
            .iter()
            .filter(|&&i| light[i].max_element() > 0.0)
            .count() as f64
            / texels.len() as f64
    };
    let shares = [
        lit_share(&as_loaded, &top),
        lit_share(&as_loaded, &bottom),
        lit_share(&flipped, &top),
        lit_share(&flipped, &bottom),
    ];
    eprintln!(
        "block texels lit (top, bottom of {} and {}): as loaded {:.2} {:.2}, flipped {:.2} {:.2}",
        top.len(),
        bottom.len(),
        shares[0],
        shares[1],
        shares[2],
        shares[3]
    );
    assert!(
        !top.is_empty() && !bottom.is_empty(),
        "the block has texels on both faces"
    );
    assert!(shares[0] > 0.9 && shares[1] < 0.1, "as loaded: {shares:?}");
    // Flipped, the bottom's texels at the face's edges lie in the shadow of its sides.
    assert!(shares[2] < 0.1 && shares[3] > 0.5, "flipped: {shares:?}");
}

/// The radiosity with a moved object (`radiosity/gather.wgsl` through `posed.wgsl`, the
/// hierarchy refitted, `moving_visibility_between`) matches its CPU twin over the same posed
/// texels, refitted hierarchy and moving objects' query, within `radiosity_matches_cpu_twin`'s
/// tolerance.
#[test]
fn moved_object_radiosity_matches_cpu_twin() {
    use cssm_runtime::radiosity::{RadiosityOptions, cpu};
    let fixture = flipped_block();
    let (scene, file) = (&fixture.scene, &fixture.file);
    let gpu_result = fixture.solve(true, 2);
    let direct = vec3s(&gpu_result.direct);
    let albedo = vec3s(&cssm_runtime::radiosity::texel_albedo(
        &super::materials(scene),
        file,
    ));
    let mut query = MovingQuery::new(file, scene, QueryOptions::default()).unwrap();
    query.set_poses(&fixture.poses()).unwrap();
    let twin_scene = cpu::TwinScene::moving(&query, &fixture.motions(), &[]);
    let options = RadiosityOptions::default();
    let traversal = cpu::Traversal {
        threshold: options.threshold,
        exposure: options.exposure,
    };
    let twin = cpu::radiosity_over(&twin_scene, &direct, &albedo, &traversal, 2);
    // The refitted hierarchy is not the baked one: the twin gathers over the moved bounds.
    assert_ne!(twin_scene.hierarchy.nodes, file.hierarchy.nodes);
    let all = vec![true; direct.len()];
    let rmse = relative_rmse(&vec3s(&gpu_result.irradiance), &twin.texel_irradiance, &all);
    let nodes = relative_rmse(
        &vec3s(&gpu_result.node_radiance),
        &twin.node_radiance,
        &vec![true; twin.node_radiance.len()],
    );
    // The block's texels gather light where it stands: flipped, its top faces the floor.
    let block_irradiance: f32 = file
        .texels
        .iter()
        .zip(&twin.texel_irradiance)
        .filter(|(t, _)| t.object == fixture.block as u32)
        .map(|(_, e)| e.max_element())
        .sum();
    eprintln!(
        "radiosity, block flipped, {} texels, 2 bounces: GPU vs CPU twin relative RMSE {:.5}% \
         (irradiance), {:.5}% (node radiance); the block's texels' irradiance sum {block_irradiance}",
        direct.len(),
        100.0 * rmse,
        100.0 * nodes
    );
    assert!(block_irradiance > 0.0);
    assert!(rmse < 1e-3 && nodes < 1e-3, "{rmse} {nodes}");
}

/// The final gather with a moved object (`lightcuts/final_gather.wgsl` through `posed.wgsl`,
/// the renderer's `set_object_transform`: moved raster, texels, refitted hierarchy and
/// placements) matches its CPU twin over the posed scene's receivers and the posed texels,
/// within `final_gather_matches_cpu_twin`'s tolerance.
#[test]
fn moved_object_final_gather_matches_cpu_twin() {
    use cssm_runtime::{
        common::{compose::Component, readback::render_image},
        lightcuts::cpu::gather_pixel,
        radiosity::cpu::TwinScene,
    };
    let fixture = flipped_block();
    let (scene, file) = (&fixture.scene, &fixture.file);
    let (w, h) = (64, 48);
    let options = super::RenderOptions {
        width: w,
        height: h,
        shadow_resolution: GI_SHADOW,
        bounces: 1,
        component: Component::Indirect,
        ..Default::default()
    };
    let gpu = gpu();
    let method = cssm_runtime::method::find("lightcuts").unwrap();
    let mut renderer = cssm_runtime::Renderer::new(
        &gpu.device,
        &gpu.queue,
        scene,
        Some(file),
        method,
        &options.values(method),
        &options.settings(),
    )
    .expect("renderer");
    renderer
        .set_object_transform(fixture.block, fixture.pose)
        .expect("the block moves");
    let image = render_image(&mut renderer, 1).expect("frame");
    gpu.wait().expect("GPU");

    // The twin: the nodes' light from the same posed atlas (0 bounces: one bounce in all, the
    // final gather's), receivers seen in the posed scene.
    let radiance = vec3s(&fixture.solve(true, 0).node_radiance);
    let posed_scene = scene.posed(&fixture.poses()).unwrap();
    let mut query = MovingQuery::new(file, scene, QueryOptions::default()).unwrap();
    query.set_poses(&fixture.poses()).unwrap();
    let twin_scene = TwinScene::moving(
        &query,
        &fixture.motions(),
        &cssm_runtime::radiosity::emitting_materials(scene),
    );
    let mut held = Default::default();
    let form = super::radiosity::twin_gather(
        scene,
        &twin_scene,
        &radiance,
        cssm_runtime::radiosity::RadiosityOptions {
            threshold: options.threshold,
            exposure: options.exposure,
        },
        options.gather,
        &mut held,
    );
    let seen = super::cpu_receivers(&posed_scene, file, w, h);
    let keep = super::interior(&posed_scene, &seen, w, h);
    let block_triangles = &scene.objects[fixture.block].triangles;
    let mut block_pixels = 0;
    let twin: Vec<Vec3> = seen
        .iter()
        .enumerate()
        .map(|(pixel, s)| match s {
            Some((r, t)) => {
                block_pixels += usize::from(keep[pixel] && block_triangles.contains(t));
                let m = &scene.materials[scene.triangle_materials[*t as usize] as usize];
                let material = cssm_runtime::gpu_types::GpuMaterial {
                    kd: m.kd,
                    ns: m.ns,
                    ks: m.ks,
                    ..Default::default()
                };
                gather_pixel(
                    &twin_scene,
                    &radiance,
                    form,
                    options.threshold,
                    options.exposure,
                    None,
                    r,
                    &material,
                )
                .0
            }
            None => Vec3::ZERO,
        })
        .collect();
    let rmse = relative_rmse(&vec3s(&image.radiance), &twin, &keep);
    eprintln!(
        "final gather {w}x{h}, block flipped: GPU vs CPU twin relative RMSE {:.4}% over {} \
         interior pixels ({block_pixels} on the block)",
        100.0 * rmse,
        keep.iter().filter(|&&k| k).count()
    );
    assert!(
        block_pixels > 20,
        "the camera sees too little of the moved block"
    );
    assert!(rmse < 0.01, "relative RMSE {rmse}");
}

/// Placing an object refits the hierarchy the GPU traverses (`FrameContext::place_object`,
/// `radiosity::MovingTexels`): its nodes read back are the CPU refit over the posed texels, no
/// longer the baked ones, the root's area is the shrunk block's, and every texel of the moved
/// block lies in the root's sphere (§4.3: the oracle's bounds hold where the texels are now).
#[test]
fn placing_an_object_refits_the_gpu_hierarchy() {
    use cssm_runtime::{
        frame::{FrameContext, FrameSettings},
        gpu_types::{GpuHierarchyNode, GpuNode},
    };
    let fixture = flipped_block();
    let (scene, file) = (&fixture.scene, &fixture.file);
    let gpu = gpu();
    let settings = FrameSettings {
        width: 1,
        height: 1,
        shadow_resolution: 256,
        ..FrameSettings::default()
    };
    let mut ctx =
        FrameContext::new(&gpu.device, &gpu.queue, scene, Some(file), settings, false).unwrap();
    ctx.place_object(fixture.block, fixture.pose).unwrap();
    let cssm = ctx.cssm().unwrap();
    let bytes = cssm_runtime::common::readback::read_buffer(
        &gpu.device,
        &gpu.queue,
        &cssm.hierarchy.nodes,
        0,
        (file.hierarchy.nodes.len() * std::mem::size_of::<GpuHierarchyNode>()) as u64,
    )
    .unwrap();
    let on_gpu: &[GpuHierarchyNode] = bytemuck::cast_slice(&bytes);
    let nodes: Vec<GpuNode> = on_gpu.iter().map(|n| n.node).collect();
    let posed = cssm_formats::moving::posed_texels(&file.texels, &fixture.motions());
    let emitting = cssm_runtime::radiosity::emitting_materials(scene);
    let mut refitted = file.hierarchy.clone();
    refitted.refit(&posed);
    assert_eq!(nodes, refitted.nodes);
    assert_ne!(nodes, file.hierarchy.nodes);
    // The spreads (the normals' moments turn with the block) are refitted with them.
    assert_eq!(
        on_gpu,
        cssm_runtime::radiosity::gpu_nodes(&refitted, &posed, &emitting).as_slice()
    );
    assert_ne!(
        on_gpu,
        cssm_runtime::radiosity::gpu_nodes(&refitted, &file.texels, &emitting).as_slice()
    );
    let root = &nodes[0];
    // The block shrank from scale 3 to 2.5: its texels' areas by (5/6)^2.
    let block = fixture.block as u32;
    let expected_area: f64 = file
        .texels
        .iter()
        .map(|t| f64::from(t.area) * if t.object == block { 25.0 / 36.0 } else { 1.0 })
        .sum();
    assert!(
        (f64::from(root.area) - expected_area).abs() < 1e-4 * expected_area,
        "root area {} against {expected_area}",
        root.area
    );
    for t in posed.iter().filter(|t| t.object == fixture.block as u32) {
        let outside = t.pos().distance(Vec3::from(root.center)) - root.radius;
        assert!(outside <= 1e-3, "texel {t:?} outside the root by {outside}");
    }
}
