//! Tests of the hierarchy: random texel sets checked for every property the build promises
//! (`check`), refits, cuts, and the validation's refusal of broken trees.

use glam::DVec3;

use super::bounds::dvec;
use super::*;
use crate::texel::Texel;

/// SplitMix64: a tiny deterministic generator.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `[0, 1)`.
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// `n` random texels: positions in a unit cube (or on a few shared points when
/// `duplicates`), random unit normals (or a few shared ones), random areas, some zero.
pub(crate) fn random_texels(n: usize, seed: u64, duplicates: bool) -> Vec<Texel> {
    let mut rng = Rng(seed);
    let points: Vec<[f32; 3]> = (0..4)
        .map(|_| [rng.unit(), rng.unit(), rng.unit()])
        .collect();
    (0..n)
        .map(|i| {
            let position = if duplicates {
                points[rng.below(points.len())]
            } else {
                [rng.unit(), rng.unit(), rng.unit()]
            };
            let normal = if rng.below(3) == 0 {
                [[0.0, 1.0, 0.0], [0.0, 0.0, -1.0]][rng.below(2)]
            } else {
                let v = glam::Vec3::new(rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5);
                v.try_normalize().unwrap_or(glam::Vec3::X).to_array()
            };
            let area = if rng.below(10) == 0 {
                0.0
            } else {
                1e-4 * rng.unit()
            };
            Texel {
                position,
                normal,
                area,
                material: 0,
                chart: 0,
                object: 0,
                x: (i % 1024) as u16,
                y: (i / 1024) as u16,
            }
        })
        .collect()
}

/// Checks every documented property of `h` over `texels`.
pub(crate) fn check(h: &Hierarchy, texels: &[Texel]) {
    let n = texels.len();
    h.validate(n).unwrap();
    assert_eq!(h.nodes.len(), (2 * n).saturating_sub(1));
    let mut ancestors: Vec<usize> = Vec::new();
    for (i, node) in h.nodes.iter().enumerate() {
        // Ancestors of i: those whose node range [j, skip) contains i.
        while let Some(&j) = ancestors.last() {
            if (h.nodes[j].skip as usize) <= i {
                ancestors.pop();
            } else {
                break;
            }
        }
        let leaves = h.leaves(i);
        assert!(leaves.contains(&node.representative), "node {i}");
        let sum: f64 = leaves
            .iter()
            .map(|&t| f64::from(texels[t as usize].area))
            .sum();
        assert!(
            (f64::from(node.area) - sum).abs() <= 1e-5 * sum + 1e-12,
            "node {i}: area {} vs {sum}",
            node.area
        );
        assert!(node.normal_len() <= 1.0 + 1e-5, "node {i}");
        // The representative is the nearest leaf, ties to the lower index.
        let c = dvec(node.center);
        let d = |t: u32| dvec(texels[t as usize].position).distance_squared(c);
        for &t in leaves {
            let (dt, dr) = (d(t), d(node.representative));
            assert!(
                dr < dt || (dr == dt && node.representative <= t),
                "node {i}"
            );
        }
        if h.is_leaf(i) {
            let t = &texels[leaves[0] as usize];
            assert_eq!(node.center, t.position);
            assert_eq!(node.radius, (t.area / std::f32::consts::PI).sqrt());
            assert_eq!(node.normal, t.normal);
            assert_eq!(node.cone_cos, 1.0);
            assert_eq!(h.children(i), None);
        } else {
            let (l, r) = h.children(i).unwrap();
            assert_eq!(l, i + 1);
            for child in [l, r] {
                let ch = &h.nodes[child];
                let dist = dvec(ch.center).distance(c);
                assert!(
                    dist + f64::from(ch.radius) <= f64::from(node.radius) * (1.0 + 1e-6) + 1e-9,
                    "node {i} does not contain child {child}"
                );
            }
        }
        // Every leaf's disk lies in every ancestor's sphere, every leaf normal in its cone.
        if h.is_leaf(i) {
            let t = &texels[leaves[0] as usize];
            let disk = f64::from((t.area / std::f32::consts::PI).sqrt());
            let n = glam::Vec3::from(t.normal).normalize();
            for &j in ancestors.iter().chain([&i]) {
                let a = &h.nodes[j];
                let dist = dvec(t.position).distance(dvec(a.center));
                assert!(
                    dist + disk <= f64::from(a.radius) * (1.0 + 1e-6) + 1e-9,
                    "leaf {i} outside ancestor {j}"
                );
                if a.cone_cos > -1.0 {
                    let axis = glam::Vec3::from(a.normal).normalize();
                    assert!(
                        n.dot(axis) >= a.cone_cos - 1e-5,
                        "leaf {i} normal outside the cone of {j}: {} < {}",
                        n.dot(axis),
                        a.cone_cos
                    );
                }
            }
        }
        ancestors.push(i);
    }
    // The leaves of the root: all texels; the full cut is the leaves, the empty one the root.
    if n > 0 {
        assert_eq!(h.cut(|_, _| false), vec![0]);
        let all = h.cut(|_, _| true);
        assert_eq!(all.len(), n);
        assert!(all.iter().all(|&i| h.is_leaf(i)));
    }
}

impl HierarchyNode {
    fn normal_len(&self) -> f32 {
        glam::Vec3::from(self.normal).length()
    }
}

#[test]
fn refit_of_the_build_texels_is_the_build_and_moved_texels_keep_every_property() {
    let texels = random_texels(500, 7, false);
    let built = Hierarchy::build(&texels);
    let mut refitted = built.clone();
    refitted.refit(&texels);
    assert_eq!(refitted, built);
    // Half of the texels carried away and turned (a rigid object moving, §3.3): the same
    // tree, every bound recomputed around the texels where they are now.
    let turn = glam::Quat::from_rotation_z(1.0);
    let moved: Vec<Texel> = texels
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let mut m = *t;
            if i % 2 == 0 {
                m.position = (turn * t.pos() + glam::Vec3::new(5.0, -3.0, 2.0)).to_array();
                m.normal = (turn * t.nrm()).to_array();
            }
            m
        })
        .collect();
    refitted.refit(&moved);
    assert_eq!(refitted.leaf_texels, built.leaf_texels);
    for (a, b) in refitted.nodes.iter().zip(&built.nodes) {
        assert_eq!((a.skip, a.first, a.count), (b.skip, b.first, b.count));
    }
    assert_ne!(refitted.nodes[0].center, built.nodes[0].center);
    check(&refitted, &moved);
}

/// Leaf ranges of a cut partition `0..n` in order.
fn assert_partition(h: &Hierarchy, cut: &[usize]) {
    let mut next = 0;
    for &i in cut {
        assert_eq!(h.nodes[i].first, next, "cut node {i}");
        next += h.nodes[i].count;
    }
    assert_eq!(next as usize, h.leaf_texels.len());
}

#[test]
fn random_sets_have_every_property() {
    for (n, duplicates) in [
        (1, false),
        (2, false),
        (3, false),
        (17, false),
        (1000, false),
        (2, true),
        (17, true),
        (1000, true),
    ] {
        for seed in 0..3 {
            let texels = random_texels(n, seed, duplicates);
            let h = Hierarchy::build(&texels);
            check(&h, &texels);
        }
    }
}

#[test]
fn empty_input_gives_an_empty_hierarchy() {
    let h = Hierarchy::build(&[]);
    assert!(h.nodes.is_empty() && h.leaf_texels.is_empty());
    h.validate(0).unwrap();
    assert!(h.cut(|_, _| true).is_empty());
    assert!(h.validate(1).is_err());
}

#[test]
fn one_texel_is_a_leaf_root() {
    let texels = random_texels(1, 5, false);
    let h = Hierarchy::build(&texels);
    assert_eq!(h.nodes.len(), 1);
    assert_eq!(h.leaf_texels, vec![0]);
    let root = h.nodes[0];
    assert_eq!(
        (root.first, root.count, root.skip, root.representative),
        (0, 1, 1, 0)
    );
    assert_eq!(h.cut(|_, _| true), vec![0]);
}

#[test]
fn median_cut_splits_the_longest_axis() {
    // Eight texels on a line along y, given in scrambled order: the root splits at the
    // median y, the left half holding the four lowest.
    let ys = [5.0, 1.0, 7.0, 0.0, 3.0, 6.0, 2.0, 4.0];
    let texels: Vec<Texel> = ys
        .iter()
        .enumerate()
        .map(|(i, &y)| Texel {
            position: [0.1 * i as f32 % 0.3, y, 0.0],
            normal: [0.0, 0.0, 1.0],
            area: 1.0,
            material: 0,
            chart: 0,
            object: 0,
            x: i as u16,
            y: 0,
        })
        .collect();
    let h = Hierarchy::build(&texels);
    check(&h, &texels);
    let y_of = |t: &u32| ys[*t as usize];
    let order: Vec<f32> = h.leaf_texels.iter().map(y_of).collect();
    assert_eq!(order, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    let (l, r) = h.children(0).unwrap();
    assert_eq!((l, r), (1, 8));
    assert_eq!((h.nodes[r].first, h.nodes[r].count), (4, 4));
    // Same normals and areas: the mean normal is the normal, the cone a line.
    assert_eq!(h.nodes[0].normal, [0.0, 0.0, 1.0]);
    assert_eq!(h.nodes[0].cone_cos, 1.0);
    assert_eq!(h.nodes[0].area, 8.0);
}

#[test]
fn opposite_normals_have_no_cone() {
    let mut texels = random_texels(2, 1, false);
    texels[0].normal = [0.0, 0.0, 1.0];
    texels[1].normal = [0.0, 0.0, -1.0];
    texels[1].area = texels[0].area;
    let h = Hierarchy::build(&texels);
    check(&h, &texels);
    assert_eq!(h.nodes[0].cone_cos, -1.0);
    assert!(h.nodes[0].normal_len() < 1e-6);
}

#[test]
fn build_is_deterministic_and_independent_of_input_order_ties() {
    let texels = random_texels(500, 9, true);
    assert_eq!(Hierarchy::build(&texels), Hierarchy::build(&texels));
}

#[test]
fn cuts_partition_the_leaves() {
    let texels = random_texels(1000, 3, false);
    let h = Hierarchy::build(&texels);
    let mut rng = Rng(11);
    for _ in 0..50 {
        let receiver = DVec3::new(
            f64::from(rng.unit()),
            f64::from(rng.unit()),
            f64::from(rng.unit()),
        );
        let ratio = 0.05 + f64::from(rng.unit());
        let mut asked = Vec::new();
        let cut = h.cut(|i, node| {
            asked.push(i);
            f64::from(node.radius) > ratio * dvec(node.center).distance(receiver)
        });
        assert_partition(&h, &cut);
        assert!(
            asked.iter().all(|&i| !h.is_leaf(i)),
            "leaves are never refined"
        );
    }
    // A random oracle too.
    let cut = h.cut(|_, _| rng.below(2) == 0);
    assert_partition(&h, &cut);
}

#[test]
fn validate_refuses_broken_trees() {
    let texels = random_texels(17, 2, false);
    let good = Hierarchy::build(&texels);
    let refused = |h: &Hierarchy, needle: &str| {
        let err = h.validate(17).unwrap_err();
        assert!(err.contains(needle), "expected `{needle}` in: {err}");
    };
    let (l, r) = good.children(0).unwrap();
    let mut h = good.clone();
    h.nodes[l].skip += 1;
    refused(&h, &format!("node {l}: skip"));
    let mut h = good.clone();
    h.nodes[0].skip -= 1;
    refused(&h, "root node");
    let mut h = good.clone();
    h.nodes[r].first += 1;
    refused(&h, &format!("node {r}: leaves"));
    // The rightmost leaf moved onto its left neighbour's leaf: fine on its own, not as the
    // right child of its parent.
    let (last, parent) = (h.nodes.len() - 1, h.nodes.len() - 3);
    let mut h = good.clone();
    h.nodes[last].first -= 1;
    h.nodes[last].representative = h.leaf_texels[h.nodes[last].first as usize];
    refused(&h, &format!("node {parent}: right child {last}"));
    let mut h = good.clone();
    h.leaf_texels[3] = h.leaf_texels[4];
    refused(&h, "not a permutation");
    let mut h = good.clone();
    h.leaf_texels[3] = 17;
    refused(&h, "not a texel index");
    let mut h = good.clone();
    h.nodes.pop();
    refused(&h, "32 nodes, expected");
    let mut h = good.clone();
    h.leaf_texels.pop();
    refused(&h, "16 leaf_texels");
    let mut h = good.clone();
    h.nodes[5].radius = f32::NAN;
    refused(&h, "node 5: a non-finite value");
    let mut h = good.clone();
    h.nodes[5].radius = -1.0;
    refused(&h, "node 5: negative radius");
    let mut h = good.clone();
    h.nodes[6].area = -1.0;
    refused(&h, "node 6: negative area");
    let mut h = good.clone();
    h.nodes[7].cone_cos = 1.5;
    refused(&h, "node 7: cone_cos");
    let mut h = good.clone();
    h.nodes[7].representative = 99;
    refused(&h, "node 7: representative");
    let mut h = good.clone();
    h.nodes[0].representative = h.leaf_texels[0];
    h.nodes[r].representative = h.leaf_texels[0];
    refused(&h, &format!("node {r}: representative"));
    let mut h = good.clone();
    h.nodes[1].count = 0;
    refused(&h, "node 1: leaves");
    let mut h = good.clone();
    h.nodes[l].count = h.nodes[0].count;
    refused(
        &h,
        &format!("node {l}: 17 leaves need nodes up to 34, past the 33"),
    );
    let mut h = good.clone();
    let last = h.nodes.len() - 1;
    h.nodes[last].count = 2;
    h.nodes[last].first -= 1;
    h.nodes[last].skip += 2;
    refused(&h, &format!("node {last}: 2 leaves need nodes up to"));
    assert!(good.validate(16).is_err());
    good.validate(17).unwrap();
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

    #[test]
    fn random_texel_sets_have_every_property(
        n in 1usize..300,
        seed in proptest::prelude::any::<u64>(),
        duplicates in proptest::prelude::any::<bool>(),
    ) {
        let texels = random_texels(n, seed, duplicates);
        let h = Hierarchy::build(&texels);
        check(&h, &texels);
        let mut rng = Rng(seed ^ 0x5555);
        assert_partition(&h, &h.cut(|_, _| rng.below(3) != 0));
    }

    /// A hostile hierarchy (random words written over its nodes and leaf order) is
    /// refused or is a tree: validation never panics, and traversing whatever passes
    /// terminates with a partition of the leaves.
    #[test]
    fn validate_never_panics_and_what_passes_is_a_tree(
        n in 1usize..40,
        seed in proptest::prelude::any::<u64>(),
        writes in proptest::collection::vec(
            (proptest::prelude::any::<proptest::sample::Index>(), 0usize..17, 0u32..80),
            1..4,
        ),
    ) {
        let texels = random_texels(n, seed, false);
        let mut h = Hierarchy::build(&texels);
        for (at, field, value) in writes {
            if h.nodes.is_empty() {
                break;
            }
            let i = at.index(h.nodes.len());
            let node = &mut h.nodes[i];
            match field {
                0 => node.skip = value,
                1 => node.first = value,
                2 => node.count = value,
                3 => node.representative = value,
                4 => node.radius = f32::from_bits(value.wrapping_mul(0x0101_0101)),
                5 => node.cone_cos = value as f32 / 40.0 - 1.0,
                6 => h.leaf_texels[at.index(n)] = value,
                7 => {
                    h.nodes.truncate(value as usize);
                }
                _ => node.skip = node.skip.wrapping_add(value),
            }
        }
        if h.validate(n).is_ok() {
            let mut rng = Rng(seed);
            let mut steps = 0;
            let cut = h.cut(|_, _| {
                steps += 1;
                assert!(steps <= h.nodes.len(), "the traversal does not end");
                rng.below(2) == 0
            });
            assert_partition(&h, &cut);
        }
    }
}

/// Timing on 200,000 random texels (run with `--ignored --nocapture` in release) of the
/// build, the validation and a refit over the texels moved (what a moving object costs the
/// runtime per move): wall time, and on Linux the time the thread was on a CPU
/// (`/proc/thread-self/schedstat`), which a busy machine does not inflate.
#[test]
#[ignore]
fn build_time_200k() {
    let on_cpu_ns = || -> Option<u64> {
        let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
        s.split_whitespace().next()?.parse().ok()
    };
    let texels = random_texels(200_000, 1, false);
    let (t0, c0) = (std::time::Instant::now(), on_cpu_ns());
    let h = Hierarchy::build(&texels);
    let (built, c1) = (t0.elapsed(), on_cpu_ns());
    let t0 = std::time::Instant::now();
    h.validate(texels.len()).unwrap();
    let validated = t0.elapsed();
    // What a moving object costs the runtime per move (§3.3): the refit over moved texels.
    let moved: Vec<Texel> = texels
        .iter()
        .map(|t| Texel {
            position: (t.pos() + glam::Vec3::ONE).to_array(),
            ..*t
        })
        .collect();
    let mut refitted = h.clone();
    let (t0, c2) = (std::time::Instant::now(), on_cpu_ns());
    refitted.refit(&moved);
    let (refit, c3) = (t0.elapsed(), on_cpu_ns());
    let cpu = |a: Option<u64>, b: Option<u64>| match (a, b) {
        (Some(a), Some(b)) => format!(", {:.1} ms on the CPU", (b - a) as f64 / 1e6),
        _ => String::new(),
    };
    println!(
        "build of 200,000 texels: {:.1} ms{}; validate: {:.1} ms; refit: {:.1} ms{}",
        built.as_secs_f64() * 1e3,
        cpu(c0, c1),
        validated.as_secs_f64() * 1e3,
        refit.as_secs_f64() * 1e3,
        cpu(c2, c3)
    );
}
