//! The query looks each pixel up where the bake cast it, on either pixel grid
//! (`cube::PixelGrid`) and in either cube frame (`cube::CubeFrame`): a receiver exactly along a
//! pixel's cast ray reads that pixel alone, and sees the depth the bake stored there.

use cssm_bake::{BakeOptions, bake};
use cssm_formats::{
    Scene,
    cube::{self, CubeFrame, DEPTH_MAX, DepthQuantizer, PixelGrid},
    visibility::{QueryOptions, VisibilityQuery},
};

#[test]
fn the_query_reads_each_pixel_where_the_bake_cast_it() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box");
    let scene = Scene::load(&dir).expect("the built-in Cornell box");
    let layouts = CubeFrame::ALL
        .into_iter()
        .flat_map(|frame| PixelGrid::ALL.map(|grid| (grid, frame)));
    for (grid, frame) in layouts {
        let options = BakeOptions {
            atlas_resolution: 32,
            cube_resolution: 8,
            pixel_grid: grid,
            cube_frame: frame,
            ..Default::default()
        };
        let file = bake(&scene, &options, &mut |_| {}).expect("bake").file;
        assert_eq!((file.pixel_grid, file.cube_frame), (grid, frame));
        let query = VisibilityQuery::new(&file, QueryOptions::default());
        let p = &file.params;
        let (n, quantizer) = (p.cube_resolution, DepthQuantizer::new(p.near, p.far));
        let (mut tested, mut between) = (0, 0);
        for (t, texel) in file.texels.iter().enumerate().step_by(7) {
            let offset = grid.offset(texel.x, texel.y);
            let normal = texel.nrm();
            let centre = query.cube_centre(t as u32);
            for pixel in 0..6 * n * n {
                // The pixel's direction in the world (its major component in the cube frame is
                // 1, so `stored` along it is the stored linear depth).
                let dir = frame.to_world(cube::pixel_direction_at(n, pixel, offset));
                let code = query.depth_code(t as u32, pixel);
                // Pixels cast through their centre (not along the plane), with a stored depth
                // well inside the range.
                if cube::pixel_is_dont_care_at(n, pixel, frame.to_cube(normal), offset)
                    || dir.dot(normal) < 0.05
                    || !(64..=DEPTH_MAX / 2).contains(&code)
                {
                    continue;
                }
                let stored = quantizer.depth(code);
                let before = query.visibility(t as u32, centre + dir * (0.5 * stored));
                let beyond = query.visibility(t as u32, centre + dir * (1.5 * stored));
                tested += 1;
                // The 2x2 filter's weights are the pixel's alone, give or take rounding; on
                // the wrong grid or in the wrong frame they would share the answer with a
                // neighbour, or read another direction's depth.
                between += usize::from(before < 0.999 || beyond > 0.001);
            }
        }
        assert!(tested > 1000, "{grid}, {frame}: {tested} pixels tested");
        assert_eq!(
            between, 0,
            "{grid}, {frame}: {between} of {tested} read a neighbour"
        );
    }
}
