//! `lightcuts`' final gather in texture space (`gather=atlas`, lightcuts/mod.rs): the far field
//! over the atlas and each pixel's near field against their CPU twins, and the split between
//! them against the whole gather.

use super::*;
use radiosity::glossy32;

/// The texture-space form (`gather=atlas`, the default): the far-field pass over the atlas and
/// each pixel's bicubic lookup of it plus its own near field, against the CPU twin computing
/// the far field with `radiosity::cpu::far_field`; and, on the same frame, the two forms
/// against each other, which split the same transfer differently and stay close; and on the
/// glossy box, whose floor's pixels walk for their lobe.
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
    let apart = relative_rmse(&atlas, &walk, &vec![true; walk.len()]);
    eprintln!("gather=atlas against gather=walk: relative RMSE {apart:.4}");
    assert!(rmse < 0.01, "relative RMSE {rmse}");
    assert!(coarse < 0.01, "threshold 0.5: relative RMSE {coarse}");
    assert!(glossy < 0.01, "glossy floor: relative RMSE {glossy}");
    assert!(apart > 1e-4 && apart < 0.2, "atlas against walk: {apart}");
}

/// The texture-space final gather splits every transfer between the atlas's far field and the
/// pixel's near field by distance alone (`transfer::near_split_weight`): at a texel's centre,
/// with the oracle refining every lit node (threshold 0, so both walks reach the same leaves),
/// the CPU twins' far field plus near field is the whole gather, texel for texel; and the near
/// field from the texels' near lists is the walked one.
#[test]
fn far_and_near_fields_add_up_to_the_whole_gather() {
    use cssm_runtime::{
        gpu_types::GpuMaterial,
        lightcuts::cpu::{Receiver, TwinGather, gather_planes},
        radiosity::cpu::{Traversal, TwinScene, gather_texel_split},
    };
    let (scene, file) = cornell32();
    let query = VisibilityQuery::new(file, QueryOptions::default());
    let twin = TwinScene::baked(&query);
    let atlas = solve_atlas(scene, file, 0, Default::default()).expect("radiosity");
    let radiance = vec3s(&atlas.node_radiance);
    let traversal = Traversal {
        threshold: 0.0,
        exposure: 1.0,
    };
    let radius = cssm_runtime::lightcuts::near_radius(&file.hierarchy, 4.0);
    let zeros = vec![glam::Vec3::ZERO; file.texels.len()];
    let nodes = &file.hierarchy.nodes;
    let (mut worst, mut near_share, mut worst_list) = (0.0f32, 0.0f32, 0.0f32);
    // The near lists (`lightcuts/near.rs`) hold every leaf the walk reaches with light to give.
    let lists = cssm_runtime::lightcuts::near_lists(file, 4.0);
    for t in (0..file.texels.len() as u32).step_by(97) {
        let texel = &file.texels[t as usize];
        let (p, n) = (texel.pos(), texel.nrm());
        let whole = |near: f32| {
            let mut none = cssm_formats::visibility::QueryWork::default();
            let (e, _) = gather_texel_split(
                &twin, nodes, &radiance, &traversal, near, t, p, n, 1.0, &mut none,
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
        let near = |lists| {
            gather_planes(
                &twin,
                &radiance,
                TwinGather::Atlas {
                    far: &zeros,
                    near_radius: radius,
                    lists,
                },
                0.0,
                1.0,
                None,
                &receiver,
                &GpuMaterial::default(),
            )
            .irradiance
        };
        let (walked, listed) = (near(None), near(lists.as_ref()));
        let (all, far) = (whole(0.0), whole(radius));
        let scale = all.max_element().max(1e-6);
        worst = worst.max((far + walked - all).abs().max_element() / scale);
        worst_list = worst_list.max((listed - walked).abs().max_element() / scale);
        let near = walked;
        near_share = near_share.max(near.max_element() / scale);
    }
    eprintln!(
        "far + near against the whole gather: largest difference {:.2e} of the texel's light; \
         the near field up to {:.1}% of it; near lists against the walk {:.2e}",
        worst,
        100.0 * near_share,
        worst_list
    );
    assert!(worst < 1e-4, "far + near differs by {worst}");
    assert!(worst_list < 1e-4, "the near lists differ by {worst_list}");
    assert!(near_share > 0.05, "no texel's near field mattered");
}
