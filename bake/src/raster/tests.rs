//! The rasteriser against the BVH's renderer ([`cubemap::render`]), interval for interval: the
//! Cornell box's atlas texels, random texels on it, and random triangle soups built to hit the
//! test's edge cases.

use std::cell::RefCell;

use cssm_formats::{
    Texel,
    cube::{self, DepthQuantizer, PixelGrid},
};
use glam::Vec3;

use super::*;
use crate::cubemap::{self, DONT_CARE, SecondLayer};
use crate::raycast::{SplitMix64, SurfaceSampler};

fn cornell() -> cssm_formats::Scene {
    cssm_formats::Scene::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box"),
    )
    .unwrap()
}

#[test]
fn cornell_atlas_texels_match_the_bvh() {
    let scene = cornell();
    let bvh = SceneBvh::new(&scene);
    let raster = RasterScene::new(&bvh);
    let far = scene.diameter();
    let near = 5e-4 * far;
    let quantizer = DepthQuantizer::new(near, far);
    let atlas = crate::atlas::build(&scene, 64, &mut |_| {}).unwrap();
    // At 64 a ray through the vertical edge of the tall block exactly at its box's corner
    // once found the BVH missing a hit (`SceneBvh`'s widened boxes): every texel, every
    // layer, a third of them each.
    let n = 64;
    let mut bad = 0;
    for (k, texel) in atlas.texels.iter().enumerate() {
        {
            // Both grids, each with every layer (the texels' cells give a staggered grid's
            // four offsets).
            let layer = SecondLayer::ALL[k % 3];
            let grid = PixelGrid::ALL[(k / 3) % 2];
            let mut a = vec![DONT_CARE; (6 * n * n) as usize];
            let mut b = a.clone();
            cubemap::render(&bvh, texel, grid, n, near, &quantizer, layer, &mut a);
            render(&raster, texel, grid, n, near, &quantizer, layer, &mut b);
            for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                if x != y && bad < 10 {
                    bad += 1;
                    eprintln!(
                        "texel {k} {texel:?} {layer} {grid} pixel {i} {:?}: {x:?} vs {y:?}",
                        cube::split_pixel(n, i as u32)
                    );
                }
            }
        }
    }
    assert_eq!(bad, 0);
}

/// Random small triangle soups seen from random texels, with every second layer: quads
/// sharing their diagonal, triangles across the texel's tangent plane and through its cube's
/// centre, edge-on triangles in planes through the centre, a texel lying on a triangle of the
/// soup (so pixels straddle its plane), and the texel's cube centre on a triangle's plane.
#[test]
fn random_soups_match_the_bvh() {
    let rng = RefCell::new(SplitMix64(5));
    let r = || rng.borrow_mut().next_f64() as f32;
    for case in 0..300 {
        let rand_vec = |scale: f32| Vec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 2.0 * scale;
        let texel_pos = rand_vec(1.0);
        let normal = rand_vec(1.0).normalize_or(Vec3::Z);
        let near = 0.01;
        let centre = texel_pos + normal * near;
        let mut positions: Vec<Vec3> = Vec::new();
        let mut triangles = Vec::new();
        let mut add = |corners: [Vec3; 3], positions: &mut Vec<Vec3>| {
            let b = positions.len() as u32;
            positions.extend(corners);
            triangles.push([b, b + 1, b + 2]);
        };
        // The texel's own triangle, and its neighbour across a shared edge.
        let (t1, t2) = (
            normal.any_orthonormal_pair().0 * 0.3,
            normal.any_orthonormal_pair().1 * 0.3,
        );
        add(
            [texel_pos - t1 - t2, texel_pos + t1 - t2, texel_pos + t2],
            &mut positions,
        );
        add(
            [texel_pos + t1 - t2, texel_pos + t1 + t2, texel_pos + t2],
            &mut positions,
        );
        for _ in 0..(2 + case % 12) {
            match (r() * 6.0) as u32 {
                // A quad of two triangles sharing a diagonal.
                0 => {
                    let (o, e1, e2) = (rand_vec(2.0), rand_vec(1.0), rand_vec(1.0));
                    add([o, o + e1, o + e2], &mut positions);
                    add([o + e2, o + e1, o + e1 + e2], &mut positions);
                }
                // Edge-on: in a plane through the cube's centre.
                1 => {
                    let (d1, d2) = (rand_vec(1.0), rand_vec(1.0));
                    let (a, b, c) = (0.2 + r(), 0.2 + r(), 0.2 + r());
                    add(
                        [centre + d1 * a, centre + d2 * b, centre + (d1 + d2) * c],
                        &mut positions,
                    );
                }
                // Through the cube's centre (crossing its tangent plane).
                2 => {
                    let (e1, e2) = (rand_vec(0.5), rand_vec(0.5));
                    add([centre - e1 - e2, centre + e1, centre + e2], &mut positions);
                }
                // With the cube's centre on its plane, not inside it.
                3 => {
                    let e1 = rand_vec(0.5);
                    let e2 = e1.cross(rand_vec(1.0));
                    let o = centre + e1 * 1.5;
                    add([o, o + e1, o + e2], &mut positions);
                }
                // Just below the tangent plane through the cube's centre, by 1e-7 to 1e-3
                // of its distance: the rays cast along the plane graze it, and the
                // rasteriser's culling of triangles below the plane must keep it.
                4 => {
                    let (u, v) = normal.any_orthonormal_pair();
                    let corner = |_| {
                        let (a, b) = (r() * 2.0 - 1.0, r() * 2.0 - 1.0);
                        let along = u * a + v * b;
                        let drop = 10f32.powf(-7.0 + 4.0 * r());
                        centre + along - normal * (along.length() * drop)
                    };
                    add(std::array::from_fn(corner), &mut positions);
                }
                _ => add(
                    [rand_vec(2.0), rand_vec(2.0), rand_vec(2.0)],
                    &mut positions,
                ),
            }
        }
        let scene = cssm_formats::Scene::from_triangles(positions, triangles);
        let bvh = SceneBvh::new(&scene);
        let raster = RasterScene::new(&bvh);
        let quantizer = DepthQuantizer::new(near, 8.0);
        let texel = Texel {
            position: texel_pos.to_array(),
            normal: normal.to_array(),
            area: 1.0,
            material: 0,
            chart: 0,
            object: 0,
            // Every offset of a staggered grid, case after case.
            x: (case % 2) as u16,
            y: (case / 2 % 2) as u16,
        };
        let grid = PixelGrid::ALL[case / 4 % 2];
        for n in [8u32, 16] {
            for layer in SecondLayer::ALL {
                let mut a = vec![DONT_CARE; (6 * n * n) as usize];
                let mut b = a.clone();
                let ra = cubemap::render(&bvh, &texel, grid, n, near, &quantizer, layer, &mut a);
                let rb = render(&raster, &texel, grid, n, near, &quantizer, layer, &mut b);
                assert_eq!(ra, rb);
                for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                    assert_eq!(
                        x,
                        y,
                        "case {case} n {n} {layer} {grid} pixel {i} {:?}",
                        cube::split_pixel(n, i as u32)
                    );
                }
            }
        }
    }
}

#[test]
fn cornell_texels_match_the_bvh() {
    let scene = cornell();
    let bvh = SceneBvh::new(&scene);
    let raster = RasterScene::new(&bvh);
    let sampler = SurfaceSampler::new(&scene);
    let mut rng = SplitMix64(3);
    let far = scene.diameter();
    let near = 5e-4 * far;
    let quantizer = DepthQuantizer::new(near, far);
    for n in [8u32, 16, 64] {
        for case in 0..200 {
            let p = sampler.point([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
            let texel = Texel {
                position: p.position.to_array(),
                normal: p.normal.to_array(),
                area: 1.0,
                material: 0,
                chart: 0,
                object: 0,
                x: (case % 2) as u16,
                y: (case / 2 % 2) as u16,
            };
            let grid = PixelGrid::ALL[case / 4 % 2];
            for layer in SecondLayer::ALL {
                let mut a = vec![DONT_CARE; (6 * n * n) as usize];
                let mut b = a.clone();
                let ra = cubemap::render(&bvh, &texel, grid, n, near, &quantizer, layer, &mut a);
                let rb = render(&raster, &texel, grid, n, near, &quantizer, layer, &mut b);
                assert_eq!(ra, rb);
                for (i, (x, y)) in a.iter().zip(&b).enumerate() {
                    assert_eq!(
                        x,
                        y,
                        "n {n} case {case} {layer} {grid} pixel {i} {:?}",
                        cube::split_pixel(n, i as u32)
                    );
                }
            }
        }
    }
}
