//! `lightcuts`' final gather in texture space (`gather=atlas`, lightcuts/mod.rs): the far field
//! over the atlas and each pixel's near field against their CPU twins, and the split between
//! them against the whole gather.

use super::*;
use radiosity::glossy32;

/// The texture-space form (`gather=atlas`, the default): the far-field pass over the atlas and
/// each pixel's bicubic lookup of it plus its own near field, against the CPU twin computing
/// the far field with `radiosity::cpu::far_field`; and, on the same frame, the two forms
/// against each other, which split the same transfer differently and stay close; on the
/// glossy box, whose floor's pixels walk for their lobe; and on the room lit by emitters,
/// whose light every pixel gathers itself.
#[test]
fn atlas_final_gather_matches_cpu_twin() {
    let (scene, file) = cornell32();
    let threshold = cssm_runtime::radiosity::DEFAULT_THRESHOLD;
    let (rmse, atlas) = final_gather_vs_twin(scene, file, 64, 48, threshold, false, "atlas");
    let (coarse, _) = final_gather_vs_twin(scene, file, 64, 48, 0.5, false, "atlas");
    let (_, walk) = final_gather_vs_twin(scene, file, 64, 48, threshold, false, "walk");
    // A glossy floor: its pixels also walk the hierarchy for their lobe, the oracle bounding
    // the lobe alone (`gather_pixel` with no albedo).
    let (glossy_scene, glossy_file) = glossy32();
    let (glossy, _) =
        final_gather_vs_twin(glossy_scene, glossy_file, 64, 48, threshold, false, "atlas");
    // The room lit by its emitters alone: every pixel walks the nodes holding emitters.
    let (room_scene, room_file) = super::emissive::room(false);
    let (room, _) = final_gather_vs_twin(room_scene, room_file, 64, 48, threshold, false, "atlas");
    let apart = relative_rmse(&atlas, &walk, &vec![true; walk.len()]);
    eprintln!("gather=atlas against gather=walk: relative RMSE {apart:.4}");
    assert!(rmse < 0.01, "relative RMSE {rmse}");
    assert!(coarse < 0.01, "threshold 0.5: relative RMSE {coarse}");
    assert!(glossy < 0.01, "glossy floor: relative RMSE {glossy}");
    assert!(room < 0.01, "emitters per pixel: relative RMSE {room}");
    assert!(apart > 1e-4 && apart < 0.2, "atlas against walk: {apart}");
}

/// The texture-space final gather splits every transfer between the atlas's far field and the
/// pixel's near field by distance alone (`transfer::near_split_weight`) and, with emitters
/// apart (the default), leaves every emitter's light to the pixel's walk over the nodes
/// holding emitters: at a texel's centre, with the oracle refining every lit node (threshold
/// 0, so every walk reaches the same leaves), the CPU twins' far field plus the pixel's part is
/// the whole gather, texel for texel, on the Cornell box (spot light) and on the room lit by
/// its emitters alone, emitters apart or not; and the near field from the texels' near lists
/// is the walked one.
#[test]
fn far_and_near_fields_add_up_to_the_whole_gather() {
    let (scene, file) = cornell32();
    let cornell = split_against_whole(scene, file, false);
    let (room_scene, room_file) = super::emissive::room(false);
    let room_far = split_against_whole(room_scene, room_file, false);
    let room = split_against_whole(room_scene, room_file, true);
    for (name, split) in [
        ("Cornell box", &cornell),
        ("room, emitters in the far field", &room_far),
        ("room, emitters per pixel", &room),
    ] {
        eprintln!(
            "{name}: far + the pixel's part against the whole gather: largest difference \
             {:.2e} of the texel's light; the pixel's part up to {:.1}% of it; near lists \
             against the walk {:.2e}",
            split.worst,
            100.0 * split.pixel_share,
            split.worst_list
        );
        assert!(
            split.worst < 1e-4,
            "{name}: far + near differs by {}",
            split.worst
        );
        assert!(
            split.worst_list < 1e-4,
            "{name}: the near lists differ by {}",
            split.worst_list
        );
    }
    assert!(cornell.pixel_share > 0.05, "no texel's near field mattered");
    // The lamp lights every texel the room's far field no longer holds.
    assert!(
        room.pixel_share > 0.5,
        "emitters per pixel: {}",
        room.pixel_share
    );
}

/// How far the texture-space split of [`split_against_whole`] is from the whole gather.
struct SplitAgainstWhole {
    /// The largest difference of far + the pixel's part from the whole, of the texel's light.
    worst: f32,
    /// The largest share of the pixel's part in a texel's light.
    pixel_share: f32,
    /// The largest difference of the pixel's part from the lists and from the walk.
    worst_list: f32,
}

/// Every 97th texel of `file` as a receiver: the twins' far field
/// plus the pixel's part (near field, and the emitters' walk when `emitters_apart`) against
/// the whole gather at threshold 0.
fn split_against_whole(scene: &Scene, file: &CssmFile, emitters_apart: bool) -> SplitAgainstWhole {
    use cssm_runtime::{
        gpu_types::GpuMaterial,
        lightcuts::cpu::{Receiver, TwinGather, gather_planes},
        radiosity::cpu::{FarSplit, Traversal, TwinScene, gather_texel_split},
    };
    let query = VisibilityQuery::new(file, QueryOptions::default());
    let twin = TwinScene::baked(&query, &cssm_runtime::radiosity::emitting_materials(scene));
    let atlas = solve_atlas(scene, file, 0, Default::default()).expect("radiosity");
    let radiance = vec3s(&atlas.node_radiance);
    let traversal = Traversal {
        threshold: 0.0,
        exposure: 1.0,
    };
    let radius = cssm_runtime::lightcuts::near_radius(&file.hierarchy, 4.0);
    let split = FarSplit {
        near_radius: radius,
        emitters_apart,
    };
    let zeros = vec![glam::Vec3::ZERO; file.texels.len()];
    let nodes = &file.hierarchy.nodes;
    let mut out = SplitAgainstWhole {
        worst: 0.0,
        pixel_share: 0.0,
        worst_list: 0.0,
    };
    // The near lists (`lightcuts/near.rs`) hold every leaf the walk reaches with light to give.
    let lists = cssm_runtime::lightcuts::near_lists(file, 4.0);
    for t in (0..file.texels.len() as u32).step_by(97) {
        let texel = &file.texels[t as usize];
        let (p, n) = (texel.pos(), texel.nrm());
        let whole = |split: FarSplit| {
            let mut none = cssm_formats::visibility::QueryWork::default();
            let (e, _) = gather_texel_split(
                &twin, nodes, &radiance, &traversal, split, t, p, n, 1.0, &mut none,
            );
            e
        };
        let receiver = Receiver {
            position: p,
            normal: n,
            view: n,
            albedo: glam::Vec3::ONE,
            atlas: glam::Vec2::new(texel.x as f32 + 0.5, texel.y as f32 + 0.5),
        };
        let pixel = |lists| {
            gather_planes(
                &twin,
                &radiance,
                TwinGather::Atlas {
                    far: &zeros,
                    near_radius: radius,
                    lists,
                    emitters_apart,
                },
                0.0,
                1.0,
                None,
                &receiver,
                &GpuMaterial::default(),
            )
            .irradiance
        };
        let (walked, listed) = (pixel(None), pixel(lists.as_ref()));
        let (all, far) = (whole(FarSplit::WHOLE), whole(split));
        let scale = all.max_element().max(1e-6);
        out.worst = out
            .worst
            .max((far + walked - all).abs().max_element() / scale);
        out.worst_list = out
            .worst_list
            .max((listed - walked).abs().max_element() / scale);
        out.pixel_share = out.pixel_share.max(walked.max_element() / scale);
    }
    out
}
