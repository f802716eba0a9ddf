//! The texel hierarchy (§4.2) of a real bake: the Cornell box at atlas 32, cube 8 gives a
//! hierarchy over its final texel table that validates and survives the file.

mod common;

use cssm_bake::bake;
use cssm_formats::{Hierarchy, cssm};

#[test]
fn cornell_bake_has_a_valid_hierarchy_that_survives_the_file() {
    let (scene, options) = common::cornell_small();
    let baked = bake(&scene, &options, &mut |_| {}).unwrap();
    let file = &baked.file;
    let n = file.texels.len();
    assert!(n > 100, "{n} texels");
    let h = &file.hierarchy;
    h.validate(n).unwrap();
    cssm::validate(file).unwrap();
    // Built from the final texel table, and deterministic.
    assert_eq!(*h, Hierarchy::build(&file.texels));
    let root = h.nodes[0];
    let area: f64 = file.texels.iter().map(|t| f64::from(t.area)).sum();
    assert!(
        (f64::from(root.area) - area).abs() < 1e-4 * area,
        "{} vs {area}",
        root.area
    );
    // The box faces point different ways: the root has no cone, its children's spheres are
    // smaller than its own.
    assert_eq!(root.cone_cos, -1.0);
    let (l, r) = h.children(0).unwrap();
    assert!(h.nodes[l].radius < root.radius && h.nodes[r].radius < root.radius);
    // Every texel's position lies in the root sphere.
    for t in &file.texels {
        let d = glam::Vec3::from(t.position).distance(glam::Vec3::from(root.center));
        assert!(d <= root.radius * (1.0 + 1e-6), "{d} > {}", root.radius);
    }
    // Both file codings carry it unchanged.
    for coding in [cssm::FileCoding::Packed, cssm::FileCoding::Plain] {
        let bytes = cssm::encode_with(file, coding).unwrap();
        let back = cssm::decode(&bytes).unwrap();
        assert_eq!(back.hierarchy, *h, "{coding}");
        assert_eq!(back, *file, "{coding}");
    }
}
