//! The moving objects' query on the GPU (`moving.wgsl`, §3.3) against its CPU reference
//! (`cssm_formats::moving::MovingQuery`): the Cornell box with a rigid block, baked once, queried
//! between posed surface points with the block in several places.

use cssm_bake::BakeOptions;
use cssm_formats::{ObjectKind, moving::MovingQuery, visibility::QueryOptions};
use cssm_raycast::{SplitMix64, SurfaceSampler};
use cssm_runtime::{
    load::CssmGpu,
    visibility::moving::{MovingEnd, MovingGpu, MovingPair, MovingQueryKernel},
};
use glam::{Affine3A, Quat, Vec3};

use super::{block_scene, gpu};

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
    let cssm = CssmGpu::new(&gpu.device, &gpu.queue, &file, query_options).expect("upload");
    let moving = MovingGpu::new(&gpu.device, &file, &scene).expect("upload the moving objects");
    let t0 = std::time::Instant::now();
    let kernel = MovingQueryKernel::new(gpu, &cssm, &moving);
    eprintln!("kernel built in {:.1} s", t0.elapsed().as_secs_f32());

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
