//! What the bake's integration tests share.

use cssm_bake::BakeOptions;
use cssm_formats::Scene;

/// The built-in Cornell box and the small bake the tests make of it (atlas 32, cube 8).
pub fn cornell_small() -> (Scene, BakeOptions) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box");
    let scene = Scene::load(&dir).unwrap();
    let options = BakeOptions {
        atlas_resolution: 32,
        cube_resolution: 8,
        ..Default::default()
    };
    (scene, options)
}
