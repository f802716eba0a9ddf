//! The small hand-built `.cssm` file the container's tests use, shared by the integration
//! tests (`tests/container.rs`) and the crate's unit tests (`src/cssm/write.rs`), which see
//! the crate by the same name.

use cssm_formats::cssm::{BakeParams, CssmFile, RunData, SceneRef};
use cssm_formats::{Hierarchy, Texel, Traversal};

/// A small hand-built file: 2 texels (so a 3-node hierarchy: root 0, leaves 1 and 2), cube 8
/// (384 pixels), one run per pixel except pixel 5, which changes depth at map 1.
pub fn sample() -> CssmFile {
    let n = 8u32;
    let pixel_count = 6 * n * n;
    let mut offsets = vec![0u32];
    let mut runs = Vec::new();
    for p in 0..pixel_count {
        runs.push(p & 0xFFFF);
        if p == 5 {
            runs.push((1 << 16) | 0xABCD);
        }
        offsets.push(runs.len() as u32);
    }
    let texel = |x: u16, y: u16| Texel {
        position: [x as f32, y as f32, 0.5],
        normal: [0.0, 0.0, 1.0],
        area: 0.25,
        material: 0,
        chart: 0,
        object: 0,
        x,
        y,
    };
    let texels = vec![texel(1, 2), texel(3, 4)];
    CssmFile {
        hierarchy: Hierarchy::build(&texels),
        params: BakeParams {
            atlas_resolution: 32,
            cube_resolution: n,
            near: 0.01,
            far: 10.0,
            traversal: Traversal::Zigzag,
        },
        scene: SceneRef {
            dir: "/tmp/scene".into(),
            name: "sample".into(),
            content_hash: [7; 32],
            triangle_count: 2,
        },
        texels,
        triangle_uvs: vec![[[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]]; 2],
        sequence: vec![1, 0],
        runs: RunData {
            map_count: 2,
            pixel_count,
            offsets,
            runs,
        },
        csms: Vec::new(),
        pixel_grid: Default::default(),
        cube_frame: Default::default(),
    }
}
