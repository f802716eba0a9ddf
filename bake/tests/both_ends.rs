//! What each end of a query says of where the occluder is (`visibility::EndAnswer`), which the
//! two ends' combination (`visibility::combine_ends`) weighs them by.

use cssm_bake::{BakeOptions, bake};
use cssm_formats::{
    Scene,
    cube::{self, DEPTH_MAX, DepthQuantizer},
    visibility::{EndAnswer, QueryOptions, VisibilityQuery, combine_ends},
};

#[test]
fn a_blocked_end_says_how_near_its_occluder_is() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box");
    let scene = Scene::load(&dir).expect("the built-in Cornell box");
    let options = BakeOptions {
        atlas_resolution: 32,
        cube_resolution: 8,
        ..Default::default()
    };
    let file = bake(&scene, &options, &mut |_| {}).expect("bake").file;
    let query = VisibilityQuery::new(&file, QueryOptions::default());
    let p = &file.params;
    let (n, quantizer) = (p.cube_resolution, DepthQuantizer::new(p.near, p.far));
    // The default turned cube frame: pixel directions come out of the cube frame.
    let frame = file.cube_frame;
    let mut tested = 0;
    for (t, texel) in file.texels.iter().enumerate().step_by(3) {
        let offset = file.pixel_grid.offset(texel.x, texel.y);
        let normal = texel.nrm();
        let centre = query.cube_centre(t as u32);
        for pixel in 0..6 * n * n {
            let dir = frame.to_world(cube::pixel_direction_at(n, pixel, offset));
            let code = query.depth_code(t as u32, pixel);
            // Pixels cast through their centre, with a stored depth well inside the range:
            // a point along the ray beyond the stored depth reads this pixel alone (see
            // pixel_grid.rs) and is blocked.
            if cube::pixel_is_dont_care_at(n, pixel, frame.to_cube(normal), offset)
                || dir.dot(normal) < 0.05
                || !(64..=DEPTH_MAX / 8).contains(&code)
            {
                continue;
            }
            let stored = quantizer.depth(code);
            for beyond in [1.5f32, 4.0] {
                let answer =
                    query.answer_oriented(t as u32, centre + dir * (beyond * stored), None);
                assert!(answer.visible < 1e-3, "{answer:?}");
                let expected = 1.0 - 1.0 / beyond;
                assert!(
                    (answer.nearness - expected).abs() < 2e-3,
                    "texel {t} pixel {pixel}: nearness {} for an occluder at 1/{beyond} of the \
                     way, expected {expected}",
                    answer.nearness
                );
            }
            let before = query.answer_oriented(t as u32, centre + dir * (0.5 * stored), None);
            assert_eq!(before.nearness, 0.0, "nothing blocks a visible point");
            tested += 1;
        }
    }
    assert!(tested > 500, "{tested} pixels tested");
}

#[test]
fn the_end_nearer_the_occluder_counts_more() {
    let clear = EndAnswer {
        visible: 1.0,
        nearness: 0.0,
    };
    let blocked = |nearness| EndAnswer {
        visible: 0.0,
        nearness,
    };
    // Nothing blocked, or blocked where the occluder sits at the receiver: the mean.
    assert_eq!(combine_ends(clear, clear), 1.0);
    assert_eq!(combine_ends(clear, blocked(0.0)), 0.5);
    // The nearer the occluder to the blocked end, the more that end counts, either way round.
    let mut last = 0.5;
    for nearness in [0.1, 0.5, 0.9] {
        let v = combine_ends(clear, blocked(nearness));
        assert!(v < last, "{v} after {last}");
        assert_eq!(v, combine_ends(blocked(nearness), clear));
        last = v;
    }
    // Between the two answers, always.
    let half = EndAnswer {
        visible: 0.5,
        nearness: 0.3,
    };
    let v = combine_ends(half, blocked(0.6));
    assert!((0.0..=0.5).contains(&v), "{v}");
}
