//! The radiosity's cached links (`radiosity/links.rs`, issue 49 item 1): the cuts and
//! visibilities built on the GPU for one solution, the bounces multiplied over them, the cuts
//! found stale after a light move and re-cut, against their CPU twins; and the products
//! against the walk they replace.

use super::*;
use radiosity::{GI_SHADOW, cornell32, vec3s};

/// One renderer's radiosity through four solves (`atlas_radiosity_lights`): the first walks;
/// the second, same light, multiplies the links built for the first one's result; the third,
/// the light moved, multiplies the same links and flags the receivers whose cut went stale;
/// the fourth, same light, re-cuts those first. Each against its CPU twin
/// (`radiosity::cpu::{build_links, radiosity_with_links, recut_links}` from the GPU's node
/// radiance before it): as many links, the same irradiance and node radiance, as many stale
/// receivers and overflows. The links' answer also stays close to the walk's. `lightcuts`'
/// far field runs after each solve (`radiosity::FarField`), its own links through the same
/// four steps ([`far_links_follow_their_twin`]).
#[test]
fn cached_links_match_cpu_twin_through_a_light_move() {
    use cssm_runtime::radiosity::{self, RadiosityOptions, cpu};
    let (scene, file) = cornell32();
    // A coarse oracle, whose cuts hold clusters a moved light can make too bright.
    let options = RadiosityOptions {
        threshold: 0.1,
        ..Default::default()
    };
    let first = scene.lights.clone();
    let mut moved = first.clone();
    // Close to a wall, facing it (the scene's units are millimetres): a bright spot where
    // the first light's cuts hold coarse nodes.
    moved[0].position += glam::Vec3::new(200.0, -250.0, 0.0);
    moved[0].direction = glam::Vec3::new(1.0, -0.2, 0.1).normalize();
    let gpu = gpu();
    // lightcuts' far field at its default near field, the emitters apart.
    let split = cpu::FarSplit {
        near_radius: cssm_runtime::lightcuts::near_radius(&file.hierarchy, 4.0),
        emitters_apart: true,
    };
    let solves = radiosity::atlas_radiosity_lights(
        &gpu.device,
        &gpu.queue,
        scene,
        file,
        GI_SHADOW,
        2,
        (options, true, Some(split)),
        &[first.clone(), first, moved.clone(), moved],
    )
    .expect("radiosity");
    gpu.wait().expect("GPU");
    let albedo = vec3s(&radiosity::texel_albedo(&materials(scene), file));
    let query = VisibilityQuery::new(file, QueryOptions::default());
    let twin_scene = cpu::TwinScene::baked(&query, &[]);
    let traversal = cpu::Traversal {
        threshold: options.threshold,
        exposure: options.exposure,
    };
    let node_radiance = |k: usize| vec3s(&solves[k].solved.node_radiance);
    let whole = (&traversal, cpu::FarSplit::WHOLE);
    let mut links = cpu::build_links(&twin_scene, &node_radiance(0), &albedo, whole);
    let texels = vec![true; file.texels.len()];
    let nodes = vec![true; file.hierarchy.nodes.len()];
    let against_twin = |k: usize, twin: &cpu::CpuRadiosity| {
        let solved = &solves[k].solved;
        (
            relative_rmse(&vec3s(&solved.irradiance), &twin.texel_irradiance, &texels),
            relative_rmse(&vec3s(&solved.node_radiance), &twin.node_radiance, &nodes),
        )
    };
    // Solve 1: the links of solve 0's light.
    let count = solves[1]
        .links
        .expect("the links are built at the second solve");
    let twin_1 = cpu::radiosity_with_links(
        &twin_scene,
        &links,
        (&vec3s(&solves[1].solved.direct), &albedo),
        &traversal,
        2,
    );
    let (rmse_1, nodes_1) = against_twin(1, &twin_1.0);
    let walk_gap = relative_rmse(
        &vec3s(&solves[1].solved.irradiance),
        &vec3s(&solves[0].solved.irradiance),
        &texels,
    );
    // Solve 2: the light moved, the same links; its stale receivers are read before solve 3.
    let twin_2 = cpu::radiosity_with_links(
        &twin_scene,
        &links,
        (&vec3s(&solves[2].solved.direct), &albedo),
        &traversal,
        2,
    );
    let (rmse_2, nodes_2) = against_twin(2, &twin_2.0);
    let stale_twin = twin_2.1.iter().filter(|&&s| s).count() as u32;
    // Solve 3: the stale receivers re-cut for solve 2's result first.
    let overflow_twin = cpu::recut_links(
        &twin_scene,
        &mut links,
        &twin_2.1,
        &node_radiance(2),
        (&albedo, &traversal, cpu::FarSplit::WHOLE),
    );
    let twin_3 = cpu::radiosity_with_links(
        &twin_scene,
        &links,
        (&vec3s(&solves[3].solved.direct), &albedo),
        &traversal,
        2,
    );
    let (rmse_3, nodes_3) = against_twin(3, &twin_3.0);
    let (stale, overflow) = solves[3].stale_before;
    let twin_count = cpu::build_links(&twin_scene, &node_radiance(0), &albedo, whole).count();
    eprintln!(
        "cached links, {} texels, 2 bounces: {count} links on the GPU ({:.1} a texel, {:.2} MB \
         with slots and table), {} in the twin; GPU vs twin relative RMSE (irradiance, node \
         radiance): same light {:.5}% {:.5}%, light moved {:.5}% {:.5}%, re-cut {:.5}% \
         {:.5}%; links vs walk {:.4}%; stale after the move {stale} (twin {stale_twin}), \
         overflows {overflow} (twin {overflow_twin})",
        file.texels.len(),
        count as f64 / file.texels.len() as f64,
        links.bytes() as f64 / 1e6,
        twin_count,
        100.0 * rmse_1,
        100.0 * nodes_1,
        100.0 * rmse_2,
        100.0 * nodes_2,
        100.0 * rmse_3,
        100.0 * nodes_3,
        100.0 * walk_gap,
    );
    let twin_count = cpu::build_links(&twin_scene, &node_radiance(0), &albedo, whole).count();
    assert!(
        count.abs_diff(twin_count) as f64 <= 0.002 * twin_count as f64,
        "{count} links on the GPU, {twin_count} in the twin"
    );
    assert_eq!(
        solves[2].stale_before,
        (0, 0),
        "no cut is stale for its own light"
    );
    assert!(stale > 0, "moving the light made no cut stale");
    assert!(
        stale.abs_diff(stale_twin) <= 2 + stale_twin / 100,
        "stale: {stale} on the GPU, {stale_twin} in the twin"
    );
    assert_eq!(overflow, overflow_twin);
    for (what, e) in [
        ("same light", rmse_1.max(nodes_1)),
        ("light moved", rmse_2.max(nodes_2)),
        ("re-cut", rmse_3.max(nodes_3)),
    ] {
        assert!(e < 1e-3, "{what}: GPU vs twin {e}");
    }
    // The cuts differ (made for the final light, not each bounce's), the answer hardly.
    assert!(walk_gap < 0.02, "links against the walk: {walk_gap}");
    let twin_scene = cpu::TwinScene::baked(&query, &radiosity::emitting_materials(scene));
    far_links_follow_their_twin(&solves, &twin_scene, (&albedo, &traversal, split));
}

/// The far fields of [`cached_links_match_cpu_twin_through_a_light_move`]'s four solves
/// against their twins: the first walked (`cpu::far_field`); the second the product of the
/// links built for the first solve's node radiance, then of the same links after the light
/// moved, then re-cut where that product found them stale (`cpu::far_field_with_links`,
/// `cpu::recut_links`), each from the GPU's node radiance.
fn far_links_follow_their_twin(
    solves: &[cssm_runtime::radiosity::LinkedSolve],
    twin: &cssm_runtime::radiosity::cpu::TwinScene,
    (albedo, traversal, split): (
        &[glam::Vec3],
        &cssm_runtime::radiosity::cpu::Traversal,
        cssm_runtime::radiosity::cpu::FarSplit,
    ),
) {
    use cssm_runtime::radiosity::cpu;
    let far = |k: usize| solves[k].far.as_ref().expect("a far field");
    let radiance = |k: usize| vec3s(&solves[k].solved.node_radiance);
    let texels = vec![true; albedo.len()];
    let gap =
        |k: usize, twin: &[glam::Vec3]| relative_rmse(&vec3s(&far(k).irradiance), twin, &texels);
    let walked = gap(
        0,
        &cpu::far_field(twin, &radiance(0), albedo, traversal, split),
    );
    let mut links = cpu::build_links(twin, &radiance(0), albedo, (traversal, split));
    let twin_count = links.count();
    let count = far(1)
        .links
        .expect("the far field's links are built at the second solve");
    let product = |k: usize, links: &cpu::Links| {
        cpu::far_field_with_links(twin, links, &radiance(k), albedo, traversal)
    };
    let (twin_1, _) = product(1, &links);
    let same_light = gap(1, &twin_1);
    let against_walk = gap(
        1,
        &cpu::far_field(twin, &radiance(1), albedo, traversal, split),
    );
    let (twin_2, stale_2) = product(2, &links);
    let moved = gap(2, &twin_2);
    let stale_twin = stale_2.iter().filter(|&&s| s).count() as u32;
    let overflow_twin = cpu::recut_links(
        twin,
        &mut links,
        &stale_2,
        &radiance(2),
        (albedo, traversal, split),
    );
    let recut = gap(3, &product(3, &links).0);
    let (stale, overflow) = far(3).stale_before;
    eprintln!(
        "far field: walked vs twin {:.5}%; {count} links ({} in the twin); links vs twin: \
         same light {:.5}%, light moved {:.5}%, re-cut {:.5}%; links vs walk {:.4}%; stale \
         after the move {stale} (twin {stale_twin}), overflows {overflow} (twin \
         {overflow_twin})",
        100.0 * walked,
        twin_count,
        100.0 * same_light,
        100.0 * moved,
        100.0 * recut,
        100.0 * against_walk,
    );
    assert!(
        count.abs_diff(twin_count) as f64 <= 0.002 * twin_count as f64,
        "far field: {count} links on the GPU, {twin_count} in the twin"
    );
    assert!(stale > 0, "moving the light made no far-field cut stale");
    assert!(
        stale.abs_diff(stale_twin) <= 2 + stale_twin / 100,
        "far field stale: {stale} on the GPU, {stale_twin} in the twin"
    );
    assert_eq!(overflow, overflow_twin);
    for (what, e) in [
        ("walked", walked),
        ("same light", same_light),
        ("light moved", moved),
        ("re-cut", recut),
    ] {
        assert!(e < 1e-3, "far field, {what}: GPU vs twin {e}");
    }
    assert!(
        against_walk < 0.02,
        "far-field links against the walk: {against_walk}"
    );
}

/// The product over the links built for a node radiance is the walk's gather over that
/// radiance, receiver for receiver (the same cut, the transfer's radiance factored out), and
/// no cut is stale for the light it was made for: the CPU twins of `product.wgsl` and
/// `gather.wgsl`, at the default threshold and a coarse one.
#[test]
fn a_link_product_is_the_gather_it_caches() {
    use cssm_runtime::radiosity::{self, cpu};
    let (scene, file) = cornell32();
    let solved = radiosity::atlas_radiosity(
        &gpu().device,
        &gpu().queue,
        scene,
        file,
        GI_SHADOW,
        1,
        Default::default(),
    )
    .expect("radiosity");
    let radiance = vec3s(&solved.node_radiance);
    let albedo = vec3s(&radiosity::texel_albedo(&materials(scene), file));
    let query = VisibilityQuery::new(file, QueryOptions::default());
    let twin = cpu::TwinScene::baked(&query, &[]);
    let nodes = &file.hierarchy.nodes;
    let leaf_texels: Vec<u32> = nodes
        .iter()
        .filter(|n| n.count == 1)
        .map(|n| file.hierarchy.leaf_texels[n.first as usize])
        .collect();
    for threshold in [radiosity::DEFAULT_THRESHOLD, 0.5] {
        let traversal = cpu::Traversal {
            threshold,
            exposure: 1.0,
        };
        let links = cpu::build_links(
            &twin,
            &radiance,
            &albedo,
            (&traversal, cpu::FarSplit::WHOLE),
        );
        let (mut worst, mut stale) = (0.0f32, 0);
        for (leaf, &t) in leaf_texels.iter().enumerate().step_by(7) {
            let texel = &file.texels[t as usize];
            let rho = albedo[t as usize].max_element();
            let (walked, _) = cpu::gather_texel(
                &twin,
                nodes,
                &radiance,
                &traversal,
                t,
                texel.pos(),
                texel.nrm(),
                rho,
            );
            let product = cpu::link_product(&links, leaf, &radiance);
            let scale = walked.max_element().max(1e-6);
            worst = worst.max((product - walked).abs().max_element() / scale);
            stale += usize::from(cpu::cut_is_stale(&links, leaf, &radiance, rho, &traversal));
        }
        eprintln!(
            "threshold {threshold}: {} links, product against the gather: largest \
             difference {worst:.2e} of the texel's light; {stale} cuts stale",
            links.count()
        );
        assert!(worst < 1e-4, "threshold {threshold}: {worst}");
        assert!(
            stale <= 2,
            "threshold {threshold}: {stale} cuts stale for their own light"
        );
    }
}
