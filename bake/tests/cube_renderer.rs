//! Both renderers of the depth cube maps write the same file: the Cornell box baked with
//! `--cube-renderer raster` and `bvh` is byte-identical, for every second layer, and `auto`
//! rasterises it.

use cssm_bake::{
    BakeOptions, bake,
    cubemap::{CubeRenderer, SecondLayer},
};
use cssm_formats::{Scene, cssm};

fn cornell() -> Scene {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box");
    Scene::load(&dir).unwrap()
}

fn file(scene: &Scene, options: &BakeOptions, renderer: CubeRenderer) -> Vec<u8> {
    let options = BakeOptions {
        cube_renderer: renderer,
        ..options.clone()
    };
    cssm::encode(&bake(scene, &options, &mut |_| {}).unwrap().file).unwrap()
}

#[test]
fn cornell_files_are_byte_identical_with_either_renderer() {
    let scene = cornell();
    assert_eq!(
        CubeRenderer::Auto.resolve(scene.triangles.len(), 64),
        CubeRenderer::Raster
    );
    // Small bakes for every layer; the 64/64 for the default one (at cube 64 a ray
    // through the tall block's edge once showed the BVH missing a hit).
    let mut cases: Vec<(u32, u32, SecondLayer)> =
        SecondLayer::ALL.iter().map(|&l| (32, 16, l)).collect();
    cases.push((64, 64, BakeOptions::default().second_layer));
    for (atlas, cube, second_layer) in cases {
        let options = BakeOptions {
            atlas_resolution: atlas,
            cube_resolution: cube,
            second_layer,
            ..Default::default()
        };
        let raster = file(&scene, &options, CubeRenderer::Raster);
        let bvh = file(&scene, &options, CubeRenderer::Bvh);
        assert!(
            raster == bvh,
            "atlas {atlas} cube {cube} {second_layer}: files differ"
        );
        assert_eq!(file(&scene, &options, CubeRenderer::Auto), raster);
    }
}
