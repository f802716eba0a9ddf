//! Tests of the filters on the CPU: `FilterParams`' layout against `filters.wgsl`, the
//! representative pixel, the twins' invariants (a constant stays constant, radius 0 is the
//! identity, a depth edge is not crossed) and the options' check.

use glam::{Vec3, Vec4};

use super::{CpuGuide, FilterOptions, blur, gpu::FilterParams, low_size, representative, upsample};
use crate::RuntimeError;

#[test]
fn filter_params_layout_matches_wgsl() {
    use std::mem::{offset_of, size_of};
    let module = crate::shaders::tests::module(super::SHADER);
    crate::shaders::tests::check_struct(
        &module,
        "FilterParams",
        size_of::<FilterParams>(),
        &[
            ("full_size", offset_of!(FilterParams, full_size)),
            ("low_size", offset_of!(FilterParams, low_size)),
            ("factor", offset_of!(FilterParams, factor)),
            ("layers", offset_of!(FilterParams, layers)),
            ("radius", offset_of!(FilterParams, radius)),
            ("spatial_sigma", offset_of!(FilterParams, spatial_sigma)),
            ("depth_sigma", offset_of!(FilterParams, depth_sigma)),
            ("normal_power", offset_of!(FilterParams, normal_power)),
            ("guide_buffers", offset_of!(FilterParams, guide_buffers)),
            ("guide_offset", offset_of!(FilterParams, guide_offset)),
        ],
    );
}

#[test]
fn representative_is_the_block_centre_clamped_to_the_image() {
    // Factor 1: the pixel itself.
    assert_eq!(representative((0, 0), 1, (5, 3)), (0, 0));
    assert_eq!(representative((4, 2), 1, (5, 3)), (4, 2));
    // Factor 2: the lower-right of the four centre pixels; the last column of an odd width
    // has only one full-res column, which it stands for.
    assert_eq!(representative((0, 0), 2, (5, 3)), (1, 1));
    assert_eq!(low_size((5, 3), 2), (3, 2));
    assert_eq!(representative((2, 1), 2, (5, 3)), (4, 2));
    // Factor 3 and 4, clamped at the border.
    assert_eq!(representative((1, 0), 3, (7, 7)), (4, 1));
    assert_eq!(low_size((7, 7), 3), (3, 3));
    assert_eq!(representative((2, 2), 3, (7, 7)), (6, 6));
    assert_eq!(representative((0, 0), 4, (1, 1)), (0, 0));
    assert_eq!(low_size((1, 1), 4), (1, 1));
    assert_eq!(representative((1, 0), 4, (6, 3)), (5, 2));
}

/// A deterministic pseudo-random number in [0, 1).
fn hash(i: u32) -> f32 {
    let mut x = i.wrapping_mul(0x9E37_79B9) ^ 0x85EB_CA6B;
    x ^= x >> 16;
    x = x.wrapping_mul(0x7FEB_352D);
    x ^= x >> 15;
    (x >> 8) as f32 / (1u32 << 24) as f32
}

/// A guide of random positions and unit normals (some facing away from others), a fraction
/// `holes` of the pixels uncovered.
fn random_guide(width: u32, height: u32, holes: f32) -> CpuGuide {
    let n = (width * height) as usize;
    let mut position = Vec::with_capacity(n);
    let mut normal = Vec::with_capacity(n);
    for i in 0..n as u32 {
        let r = |k: u32| hash(8 * i + k);
        let covered = if r(0) < holes { 0.0 } else { 1.0 };
        position.push([
            r(1) * 2.0 - 1.0,
            r(2) * 2.0 - 1.0,
            -1.0 - 3.0 * r(3),
            covered,
        ]);
        let v = Vec3::new(r(4) - 0.5, r(5) - 0.5, r(6)).normalize();
        normal.push([v.x, v.y, v.z, 0.0]);
    }
    CpuGuide {
        width,
        height,
        position,
        normal,
        eye: Vec3::ZERO,
        low: None,
    }
}

fn close(a: Vec4, b: Vec4, tolerance: f32) -> bool {
    (a - b).abs().max_element() <= tolerance * b.abs().max_element().max(1e-6)
}

#[test]
fn a_constant_signal_stays_constant() {
    let value = Vec4::new(0.25, 1.5, 3.0, 1.0);
    for holes in [0.0, 0.3] {
        let guide = random_guide(23, 17, holes);
        for factor in 1..=4 {
            for radius in [0, 1, 8] {
                let options = FilterOptions {
                    factor,
                    radius,
                    ..Default::default()
                };
                let (lw, lh) = low_size((23, 17), factor);
                let input = vec![value; (2 * lw * lh) as usize];
                let blurred = blur(&input, 2, &guide, &options);
                for (i, v) in blurred.iter().enumerate() {
                    let j = i as u32 % (lw * lh);
                    let low = representative((j % lw, j / lw), factor, (23, 17));
                    if radius == 0 || guide.at(low).covered {
                        assert!(close(*v, value, 1e-5), "blur {factor} {radius}: {v}");
                    } else {
                        assert_eq!(*v, Vec4::ZERO);
                    }
                }
                let full = upsample(&blurred, 2, &guide, &options);
                for (i, v) in full.iter().enumerate() {
                    let j = i as u32 % (23 * 17);
                    let covered = guide.at((j % 23, j / 23)).covered;
                    if !covered {
                        assert_eq!(*v, Vec4::ZERO);
                    } else if holes == 0.0 {
                        assert!(close(*v, value, 1e-5), "upsample {factor} {radius}: {v}");
                    } else {
                        // Zero where none of the 2x2 samples is covered.
                        let ok = close(*v, value, 1e-5) || *v == Vec4::ZERO;
                        assert!(ok, "upsample {factor} {radius}: {v}");
                    }
                }
            }
        }
    }
}

#[test]
fn radius_zero_is_the_identity() {
    let guide = random_guide(19, 11, 0.3);
    let options = FilterOptions {
        factor: 3,
        radius: 0,
        ..Default::default()
    };
    let (lw, lh) = low_size((19, 11), 3);
    let input: Vec<Vec4> = (0..2 * lw * lh)
        .map(|i| Vec4::new(hash(i), hash(i + 1000), hash(i + 2000), hash(i + 3000)))
        .collect();
    assert_eq!(blur(&input, 2, &guide, &options), input);
    // At factor 1 the up-sampling, too, is the identity on covered pixels.
    let options = FilterOptions {
        factor: 1,
        ..options
    };
    let input: Vec<Vec4> = (0..19 * 11).map(|i| Vec4::splat(hash(i))).collect();
    let out = upsample(&blur(&input, 1, &guide, &options), 1, &guide, &options);
    for (i, (o, v)) in out.iter().zip(&input).enumerate() {
        let covered = guide.position[i][3] > 0.0;
        assert_eq!(*o, if covered { *v } else { Vec4::ZERO }, "pixel {i}");
    }
}

/// Two flat regions facing the eye, the left at distance ~1 with value 1, the right at
/// distance ~10 with value 5: neither the blur nor the up-sampling mixes them.
#[test]
fn a_depth_edge_is_not_crossed() {
    let (w, h) = (16u32, 8u32);
    let mut position = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let d = if x < w / 2 { 1.0 } else { 10.0 };
            position.push([(x as f32 - 8.0) * 0.01, (y as f32 - 4.0) * 0.01, -d, 1.0]);
        }
    }
    let guide = CpuGuide {
        width: w,
        height: h,
        position,
        normal: vec![[0.0, 0.0, 1.0, 0.0]; (w * h) as usize],
        eye: Vec3::ZERO,
        low: None,
    };
    let expected = |x: u32| Vec4::splat(if x < w / 2 { 1.0 } else { 5.0 });
    for factor in [1, 2] {
        let options = FilterOptions {
            factor,
            ..Default::default()
        };
        let (lw, lh) = low_size((w, h), factor);
        let input: Vec<Vec4> = (0..lw * lh)
            .map(|i| expected(representative((i % lw, i / lw), factor, (w, h)).0))
            .collect();
        let blurred = blur(&input, 1, &guide, &options);
        for (b, v) in blurred.iter().zip(&input) {
            assert!(close(*b, *v, 1e-6), "blur, factor {factor}: {b} for {v}");
        }
        let full = upsample(&blurred, 1, &guide, &options);
        for (i, v) in full.iter().enumerate() {
            let x = i as u32 % w;
            assert!(close(*v, expected(x), 1e-6), "upsample at {x}: {v}");
        }
    }
}

#[test]
fn check_refuses_values_out_of_range() {
    assert!(FilterOptions::default().check().is_ok());
    let bad = [
        (
            FilterOptions {
                factor: 0,
                ..Default::default()
            },
            "factor",
        ),
        (
            FilterOptions {
                factor: 5,
                ..Default::default()
            },
            "factor",
        ),
        (
            FilterOptions {
                radius: 17,
                ..Default::default()
            },
            "radius",
        ),
        (
            FilterOptions {
                spatial_sigma: 0.0,
                ..Default::default()
            },
            "spatial sigma",
        ),
        (
            FilterOptions {
                spatial_sigma: f32::NAN,
                ..Default::default()
            },
            "spatial sigma",
        ),
        (
            FilterOptions {
                depth_sigma: -1.0,
                ..Default::default()
            },
            "depth sigma",
        ),
        (
            FilterOptions {
                depth_sigma: f32::INFINITY,
                ..Default::default()
            },
            "depth sigma",
        ),
        (
            FilterOptions {
                normal_power: -0.5,
                ..Default::default()
            },
            "normal power",
        ),
    ];
    for (options, name) in bad {
        match options.check() {
            Err(RuntimeError::Unsupported(msg)) => assert!(msg.contains(name), "{msg}"),
            other => panic!("{options:?}: {other:?}"),
        }
    }
    let edge = FilterOptions {
        factor: 4,
        radius: 0,
        normal_power: 0.0,
        ..Default::default()
    };
    assert!(edge.check().is_ok());
}
