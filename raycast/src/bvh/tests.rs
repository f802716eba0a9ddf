//! Tests of [`SceneBvh`]'s queries: layered scenes with known answers, and random triangle soups
//! against every triangle tested one by one.

use cssm_formats::Scene;
use glam::Vec3;

use super::*;

fn two_planes() -> Scene {
    // Two parallel quads at z = 1 and z = 3.
    let positions = vec![
        Vec3::new(-1.0, -1.0, 1.0),
        Vec3::new(1.0, -1.0, 1.0),
        Vec3::new(1.0, 1.0, 1.0),
        Vec3::new(-1.0, 1.0, 1.0),
        Vec3::new(-1.0, -1.0, 3.0),
        Vec3::new(1.0, -1.0, 3.0),
        Vec3::new(1.0, 1.0, 3.0),
        Vec3::new(-1.0, 1.0, 3.0),
    ];
    cssm_formats::Scene::from_triangles(positions, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
}

#[test]
fn dual_hit_finds_both_layers_even_through_a_shared_edge() {
    let bvh = SceneBvh::new(&two_planes());
    let h = bvh.dual_hit(Vec3::new(0.3, 0.2, 0.0), Vec3::Z, 1e-3);
    assert!(
        (h.first - 1.0).abs() < 1e-5 && (h.second - 3.0).abs() < 1e-5,
        "{h:?}"
    );
    // Through the diagonal shared by both triangles of each quad.
    let h = bvh.dual_hit(Vec3::new(0.25, 0.25, 0.0), Vec3::Z, 1e-3);
    assert!(
        (h.first - 1.0).abs() < 1e-5 && (h.second - 3.0).abs() < 1e-5,
        "{h:?}"
    );
    let h = bvh.dual_hit(Vec3::new(0.0, 0.0, 2.0), Vec3::Z, 1e-3);
    assert!(
        (h.first - 1.0).abs() < 1e-5 && h.second.is_infinite(),
        "{h:?}"
    );
    let h = bvh.dual_hit(Vec3::new(5.0, 0.0, 0.0), Vec3::Z, 1e-3);
    assert!(h.first.is_infinite() && h.second.is_infinite());
    assert!(!bvh.segment_clear(Vec3::ZERO, Vec3::new(0.0, 0.0, 2.0)));
    assert!(bvh.segment_clear(Vec3::new(0.0, 0.0, 1.5), Vec3::new(0.0, 0.0, 2.5)));
}

/// A slab (front face at z = 1 facing -z, back face at z = 1.2 facing +z) and a wall at
/// z = 3 facing -z, all unit quads around the z axis.
fn slab_and_wall() -> Scene {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for (z, faces_minus_z) in [(1.0, true), (1.2, false), (3.0, true)] {
        let base = positions.len() as u32;
        for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            positions.push(Vec3::new(x, y, z));
        }
        // Counter-clockwise seen from +z is a +z normal.
        if faces_minus_z {
            triangles.extend([[base, base + 2, base + 1], [base, base + 3, base + 2]]);
        } else {
            triangles.extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
        }
    }
    cssm_formats::Scene::from_triangles(positions, triangles)
}

#[test]
fn front_dual_hit_skips_surfaces_facing_away() {
    let bvh = SceneBvh::new(&slab_and_wall());
    let near = |a: f32, b: f32| (a - b).abs() < 1e-5;
    // From below: the slab's front, then its back (facing away), then the wall.
    let any = bvh.dual_hit(Vec3::new(0.3, 0.2, 0.0), Vec3::Z, 1e-3);
    assert!(near(any.first, 1.0) && near(any.second, 1.2), "{any:?}");
    let facing = bvh.front_dual_hit(Vec3::new(0.3, 0.2, 0.0), Vec3::Z, 1e-3);
    assert!(
        near(facing.first, 1.0) && near(facing.second, 3.0) && facing.first_faces,
        "{facing:?}"
    );
    // Through the quads' shared diagonal, the same.
    let facing = bvh.front_dual_hit(Vec3::new(0.25, 0.25, 0.0), Vec3::Z, 1e-3);
    assert!(
        near(facing.first, 1.0) && near(facing.second, 3.0),
        "{facing:?}"
    );
    // From above: the wall's back comes first (whatever it faces, the first hit is the
    // first), then the slab's back face, which faces this origin.
    let down = bvh.front_dual_hit(Vec3::new(0.3, 0.2, 5.0), -Vec3::Z, 1e-3);
    assert!(
        near(down.first, 2.0) && near(down.second, 3.8) && !down.first_faces,
        "{down:?}"
    );
    // From inside the slab: only its back face ahead, facing away.
    let inside = bvh.front_dual_hit(Vec3::new(0.3, 0.2, 1.1), Vec3::Z, 1e-3);
    assert!(
        near(inside.first, 0.1) && near(inside.second, 1.9) && !inside.first_faces,
        "{inside:?}"
    );
    let out = bvh.front_dual_hit(Vec3::new(0.3, 0.2, 3.5), Vec3::Z, 1e-3);
    assert!(out.first.is_infinite() && out.second.is_infinite());
}

/// The BVH's pruned traversal meets every hit that matters: on random triangle soups its
/// answers equal [`reduce_hits`] over every triangle tested one by one.
#[test]
fn bvh_answers_equal_brute_force_on_random_soups() {
    let mut rng = crate::SplitMix64(11);
    let mut r = || rng.next_f64() as f32;
    for soup in 0..40 {
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for t in 0..(4 + soup * 3) as u32 {
            // A grid of quads sharing edges, and free triangles.
            let base = Vec3::new(r() * 4.0 - 2.0, r() * 4.0 - 2.0, r() * 4.0 - 2.0);
            let (e1, e2) = (
                Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 2.0,
                Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 2.0,
            );
            positions.extend([base, base + e1, base + e2, base + e1 + e2]);
            let b = 4 * t;
            triangles.push([b, b + 1, b + 2]);
            triangles.push([b + 2, b + 1, b + 3]);
        }
        let scene = Scene::from_triangles(positions, triangles);
        let bvh = SceneBvh::new(&scene);
        let (tris, normals) = bvh.triangles_by_scene_index();
        for _ in 0..400 {
            let origin = Vec3::new(r() * 4.0 - 2.0, r() * 4.0 - 2.0, r() * 4.0 - 2.0);
            // Axis-aligned and general directions.
            let dir = match (r() * 4.0) as u32 {
                0 => Vec3::Z * if r() < 0.5 { 1.0 } else { -1.0 },
                _ => Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5),
            };
            if dir == Vec3::ZERO {
                continue;
            }
            let wt = WatertightRay::new(origin, dir);
            let hits: Vec<(f32, bool)> = tris
                .iter()
                .zip(normals)
                .map(|(tri, n)| (wt.intersect(tri), n.dot(dir) < 0.0))
                .collect();
            let any: Vec<_> = hits.iter().map(|&(t, _)| (t, true)).collect();
            let expected = reduce_hits(&any, 1e-3);
            let got = bvh.dual_hit(origin, dir, 1e-3);
            assert_eq!((got.first, got.second), (expected.first, expected.second));
            assert_eq!(
                bvh.front_dual_hit(origin, dir, 1e-3),
                reduce_hits(&hits, 1e-3)
            );
        }
    }
}
