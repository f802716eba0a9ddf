//! Property tests of the atlas traversals of §3.2.3 (and the Hilbert order beyond it) (`cssm_bake::traverse`) on random atlases:
//! random blob charts grown by flood fill, isolated cells (so some charts are split in the atlas
//! grid), noisy 3D positions, and texel slices in row-major or shuffled order.

use cssm_bake::traverse::{ChartOrder, gilbert_ranks, traverse, traverse_piloted, traverse_with};
use cssm_formats::{Texel, Traversal};
use proptest::prelude::*;
use std::time::Instant;

/// SplitMix64: a tiny deterministic generator for building atlases from one proptest seed.
struct SplitMix(u64);

impl SplitMix {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `0..n` (`n > 0`).
    fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    /// Uniform in `[-0.5, 0.5)`.
    fn noise(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    }
}

/// A random `w × h` atlas: `blobs` charts grown by a random flood fill from random seeds, plus
/// `isolated` random cells given to a random (possibly new) chart. Chart ids are made dense in
/// order of first appearance. Positions `(x, y, 10 chart)` plus noise of amplitude `noise`.
/// The texel slice is row-major unless `shuffle`.
fn random_atlas(
    seed: u64,
    w: usize,
    h: usize,
    blobs: usize,
    isolated: usize,
    noise: f32,
    shuffle: bool,
) -> Vec<Texel> {
    let mut rng = SplitMix(seed);
    let mut grid: Vec<Option<usize>> = vec![None; w * h];
    for chart in 0..blobs {
        let size = 1 + rng.below(w * h / blobs.max(1) + 1);
        let s = rng.below(w * h);
        if grid[s].is_some() {
            continue;
        }
        grid[s] = Some(chart);
        let mut frontier = vec![s];
        let mut grown = 1;
        while grown < size && !frontier.is_empty() {
            let k = rng.below(frontier.len());
            let c = frontier[k];
            let (x, y) = (c % w, c / w);
            let mut free = Vec::new();
            if x > 0 {
                free.push(c - 1);
            }
            if x + 1 < w {
                free.push(c + 1);
            }
            if y > 0 {
                free.push(c - w);
            }
            if y + 1 < h {
                free.push(c + w);
            }
            free.retain(|&n| grid[n].is_none());
            if free.is_empty() {
                frontier.swap_remove(k);
                continue;
            }
            let n = free[rng.below(free.len())];
            grid[n] = Some(chart);
            frontier.push(n);
            grown += 1;
        }
    }
    for _ in 0..isolated {
        let c = rng.below(w * h);
        grid[c] = Some(rng.below(blobs + 2));
    }
    // Dense chart ids in row-major order of first appearance.
    let mut dense = std::collections::BTreeMap::new();
    let mut texels = Vec::new();
    for y in 0..h {
        for x in 0..w {
            if let Some(c) = grid[y * w + x] {
                let next = dense.len() as u32;
                let chart = *dense.entry(c).or_insert(next);
                let position = [
                    x as f32 + noise * rng.noise(),
                    y as f32 + noise * rng.noise(),
                    10.0 * chart as f32 + noise * rng.noise(),
                ];
                texels.push(Texel {
                    position,
                    normal: [0.0, 0.0, 1.0],
                    area: 1.0,
                    material: 0,
                    chart,
                    object: 0,
                    x: x as u16,
                    y: y as u16,
                });
            }
        }
    }
    if shuffle {
        for i in (1..texels.len()).rev() {
            let j = rng.below(i + 1);
            texels.swap(i, j);
        }
    }
    texels
}

fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    let dx = a[0] - b[0];
    let dy = a[1] - b[1];
    let dz = a[2] - b[2];
    dx * dx + dy * dy + dz * dz
}

/// Row-major first texel: smallest `(y, x, index)`.
fn first_texel(texels: &[Texel]) -> u32 {
    (0..texels.len() as u32)
        .min_by_key(|&i| (texels[i as usize].y, texels[i as usize].x, i))
        .unwrap()
}

fn assert_permutation(texels: &[Texel], order: &[u32]) -> Result<(), TestCaseError> {
    prop_assert_eq!(order.len(), texels.len());
    let mut seen = vec![false; texels.len()];
    for &i in order {
        prop_assert!((i as usize) < texels.len(), "index {} out of range", i);
        prop_assert!(!seen[i as usize], "index {} emitted twice", i);
        seen[i as usize] = true;
    }
    Ok(())
}

/// The chart blocks of `order`: `(chart, start, end)`; fails unless every chart is one block.
fn chart_blocks(
    texels: &[Texel],
    order: &[u32],
) -> Result<Vec<(u32, usize, usize)>, TestCaseError> {
    let mut blocks: Vec<(u32, usize, usize)> = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        let c = texels[i as usize].chart;
        match blocks.last_mut() {
            Some(b) if b.0 == c => b.2 = k + 1,
            _ => blocks.push((c, k, k + 1)),
        }
    }
    let mut charts: Vec<u32> = blocks.iter().map(|b| b.0).collect();
    charts.sort_unstable();
    let n = charts.len();
    charts.dedup();
    prop_assert_eq!(charts.len(), n, "a chart is split into several blocks");
    Ok(blocks)
}

/// The chart order rule: first the row-major first texel's chart, then always the unvisited chart
/// whose row-major first texel is closest to the last texel of the previous block (ties: chart id).
/// With `enters_at_first`, every block also starts at that texel (Zig-Zag, Spiral; a Hilbert
/// block starts where its curve meets the chart first).
fn assert_chart_order(
    texels: &[Texel],
    order: &[u32],
    blocks: &[(u32, usize, usize)],
    enters_at_first: bool,
) -> Result<(), TestCaseError> {
    let charts = blocks.len();
    let mut entry = vec![u32::MAX; charts];
    for (i, t) in texels.iter().enumerate() {
        let e = &mut entry[t.chart as usize];
        if *e == u32::MAX
            || (t.y, t.x, i as u32) < (texels[*e as usize].y, texels[*e as usize].x, *e)
        {
            *e = i as u32;
        }
    }
    prop_assert_eq!(blocks[0].0, texels[first_texel(texels) as usize].chart);
    let mut done = vec![false; charts];
    for w in blocks.windows(2) {
        done[w[0].0 as usize] = true;
        // Every block starts at its chart's row-major first texel.
        if enters_at_first {
            prop_assert_eq!(order[w[1].1], entry[w[1].0 as usize]);
        }
        let last = texels[order[w[0].2 - 1] as usize].position;
        let expected = (0..charts as u32)
            .filter(|&c| !done[c as usize])
            .min_by(|&a, &b| {
                dist2(texels[entry[a as usize] as usize].position, last)
                    .total_cmp(&dist2(texels[entry[b as usize] as usize].position, last))
                    .then(a.cmp(&b))
            });
        prop_assert_eq!(Some(w[1].0), expected);
    }
    Ok(())
}

/// Zig-Zag inside each block: rows of the chart's bounding box top to bottom, alternately
/// left-to-right (even rows from the top) and right-to-left.
fn assert_zigzag_rows(
    texels: &[Texel],
    order: &[u32],
    blocks: &[(u32, usize, usize)],
) -> Result<(), TestCaseError> {
    for &(_, s, e) in blocks {
        let block = &order[s..e];
        let top = block.iter().map(|&i| texels[i as usize].y).min().unwrap();
        let mut expected = block.to_vec();
        expected.sort_by_key(|&i| {
            let t = &texels[i as usize];
            let x = i32::from(t.x);
            (t.y, if (t.y - top) % 2 == 0 { x } else { -x })
        });
        prop_assert_eq!(block, &expected[..]);
    }
    Ok(())
}

/// Spiral inside each block is a depth-first walk of the chart's 4-connected cells: every texel
/// is a 4-neighbour of an earlier texel of the block, unless all earlier texels' same-chart
/// neighbours are already visited, in which case it is the row-major first unvisited texel.
/// Returns (4-neighbour steps between consecutive texels, steps within blocks).
fn assert_spiral_walk(
    texels: &[Texel],
    order: &[u32],
    blocks: &[(u32, usize, usize)],
) -> Result<(usize, usize), TestCaseError> {
    let w = texels.iter().map(|t| t.x as usize).max().unwrap() + 1;
    let h = texels.iter().map(|t| t.y as usize).max().unwrap() + 1;
    let mut cell = vec![u32::MAX; w * h];
    for (i, t) in texels.iter().enumerate() {
        cell[t.y as usize * w + t.x as usize] = i as u32;
    }
    let neighbours = |i: u32| {
        let t = &texels[i as usize];
        let (x, y) = (t.x as usize, t.y as usize);
        let mut out = Vec::with_capacity(4);
        if x > 0 {
            out.push(cell[y * w + x - 1]);
        }
        if x + 1 < w {
            out.push(cell[y * w + x + 1]);
        }
        if y > 0 {
            out.push(cell[(y - 1) * w + x]);
        }
        if y + 1 < h {
            out.push(cell[(y + 1) * w + x]);
        }
        out.retain(|&n| n != u32::MAX && texels[n as usize].chart == t.chart);
        out
    };
    let mut visited = vec![false; texels.len()];
    let (mut adjacent, mut steps) = (0, 0);
    for &(_, s, e) in blocks {
        for k in s..e {
            let i = order[k];
            if k > s {
                steps += 1;
                let prev = &texels[order[k - 1] as usize];
                let t = &texels[i as usize];
                if prev.x.abs_diff(t.x) + prev.y.abs_diff(t.y) == 1 {
                    adjacent += 1;
                }
                let touches_visited = neighbours(i).iter().any(|&n| visited[n as usize]);
                if !touches_visited {
                    // A restart: the visited region must be exhausted …
                    for &j in &order[s..k] {
                        prop_assert!(
                            neighbours(j).iter().all(|&n| visited[n as usize]),
                            "restart at {} while {} still has a free neighbour",
                            i,
                            j
                        );
                    }
                    // … and the restart cell is the row-major first unvisited texel of the chart.
                    let first_free = order[k..e]
                        .iter()
                        .min_by_key(|&&j| (texels[j as usize].y, texels[j as usize].x, j))
                        .unwrap();
                    prop_assert_eq!(i, *first_free);
                }
            }
            visited[i as usize] = true;
        }
    }
    Ok((adjacent, steps))
}

/// Greedy: from the row-major first texel, always the nearest unvisited texel (ties: index).
fn assert_greedy(texels: &[Texel], order: &[u32]) -> Result<(), TestCaseError> {
    prop_assert_eq!(order[0], first_texel(texels));
    let mut visited = vec![false; texels.len()];
    visited[order[0] as usize] = true;
    for pair in order.windows(2) {
        let q = texels[pair[0] as usize].position;
        let expected = (0..texels.len() as u32)
            .filter(|&i| !visited[i as usize])
            .min_by(|&a, &b| {
                dist2(texels[a as usize].position, q)
                    .total_cmp(&dist2(texels[b as usize].position, q))
                    .then(a.cmp(&b))
            })
            .unwrap();
        prop_assert_eq!(pair[1], expected);
        visited[pair[1] as usize] = true;
    }
    Ok(())
}

/// Hilbert inside each block: the block's texels in the order the generalised Hilbert curve over
/// the block's bounding rectangle meets them (`gilbert_ranks`, whose own unit test checks that it
/// visits every cell once in 4-neighbour steps); on a full square chart every step is a
/// 4-neighbour step.
fn assert_hilbert_blocks(
    texels: &[Texel],
    order: &[u32],
    blocks: &[(u32, usize, usize)],
) -> Result<(), TestCaseError> {
    for &(_, s, e) in blocks {
        let block = &order[s..e];
        let x0 = block.iter().map(|&i| texels[i as usize].x).min().unwrap();
        let y0 = block.iter().map(|&i| texels[i as usize].y).min().unwrap();
        let x1 = block.iter().map(|&i| texels[i as usize].x).max().unwrap();
        let y1 = block.iter().map(|&i| texels[i as usize].y).max().unwrap();
        let width = u32::from(x1 - x0) + 1;
        let rank = gilbert_ranks(width, u32::from(y1 - y0) + 1);
        let key = |i: u32| {
            let t = &texels[i as usize];
            let cell = u32::from(t.y - y0) * width + u32::from(t.x - x0);
            (rank[cell as usize], i)
        };
        for w in block.windows(2) {
            prop_assert!(key(w[0]) < key(w[1]), "block not in Hilbert order");
        }
    }
    Ok(())
}

#[test]
fn hilbert_on_a_full_square_steps_to_neighbours() {
    // One 16x16 chart: every step of the curve is a 4-neighbour step, from (0, 0) to (15, 0).
    let texels: Vec<Texel> = (0..16u16)
        .flat_map(|y| (0..16u16).map(move |x| (x, y)))
        .map(|(x, y)| Texel {
            position: [f32::from(x), f32::from(y), 0.0],
            normal: [0.0, 0.0, 1.0],
            area: 1.0,
            material: 0,
            chart: 0,
            object: 0,
            x,
            y,
        })
        .collect();
    let order = traverse(&texels, 16, Traversal::Hilbert);
    let cell = |i: u32| {
        (
            i32::from(texels[i as usize].x),
            i32::from(texels[i as usize].y),
        )
    };
    assert_eq!(cell(order[0]), (0, 0));
    assert_eq!(cell(*order.last().unwrap()), (15, 0));
    for w in order.windows(2) {
        let (a, b) = (cell(w[0]), cell(w[1]));
        assert_eq!((a.0 - b.0).abs() + (a.1 - b.1).abs(), 1, "{a:?} -> {b:?}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn traversals_are_valid(
        seed in any::<u64>(),
        w in 1usize..40,
        h in 1usize..40,
        blobs in 0usize..12,
        isolated in 0usize..20,
        noise in prop_oneof![Just(0.0f32), 0.0f32..0.9],
        shuffle in any::<bool>(),
    ) {
        let texels = random_atlas(seed, w, h, blobs, isolated, noise, shuffle);
        let res = w.max(h) as u32;
        for traversal in Traversal::ALL {
            let order = traverse(&texels, res, traversal);
            assert_permutation(&texels, &order)?;
            // Deterministic.
            prop_assert_eq!(&order, &traverse(&texels, res, traversal));
            if texels.is_empty() {
                continue;
            }
            match traversal {
                Traversal::Greedy => assert_greedy(&texels, &order)?,
                Traversal::Zigzag => {
                    let blocks = chart_blocks(&texels, &order)?;
                    assert_chart_order(&texels, &order, &blocks, true)?;
                    assert_zigzag_rows(&texels, &order, &blocks)?;
                }
                // Without a pilot, Piloted is the Hilbert order.
                Traversal::Hilbert | Traversal::Piloted => {
                    let blocks = chart_blocks(&texels, &order)?;
                    assert_chart_order(&texels, &order, &blocks, false)?;
                    assert_hilbert_blocks(&texels, &order, &blocks)?;
                }
                Traversal::Spiral => {
                    let blocks = chart_blocks(&texels, &order)?;
                    assert_chart_order(&texels, &order, &blocks, true)?;
                    let (adjacent, steps) = assert_spiral_walk(&texels, &order, &blocks)?;
                    if steps > 0 {
                        println!(
                            "spiral: {adjacent}/{steps} in-chart steps are 4-neighbour steps ({:.1}%)",
                            100.0 * adjacent as f64 / steps as f64
                        );
                    }
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// `ChartOrder::Ends`: still a permutation with every chart one block; each block is the
    /// chart's own walk (as the paper's chart order emits it) or that walk backwards; the first
    /// block is the row-major first texel's chart, forwards; and each next block starts at the
    /// unvisited chart end nearest to where the previous block ended.
    #[test]
    fn chart_order_ends_strings_whole_walks_together(
        seed in any::<u64>(),
        w in 1usize..30,
        h in 1usize..30,
        blobs in 0usize..12,
        isolated in 0usize..20,
        noise in prop_oneof![Just(0.0f32), 0.0f32..0.9],
        shuffle in any::<bool>(),
    ) {
        let texels = random_atlas(seed, w, h, blobs, isolated, noise, shuffle);
        let res = w.max(h) as u32;
        for traversal in [Traversal::Zigzag, Traversal::Spiral, Traversal::Hilbert] {
            let order = traverse_with(&texels, res, traversal, ChartOrder::Ends);
            assert_permutation(&texels, &order)?;
            prop_assert_eq!(&order, &traverse_with(&texels, res, traversal, ChartOrder::Ends));
            if texels.is_empty() {
                continue;
            }
            let paper = traverse(&texels, res, traversal);
            let walks: std::collections::HashMap<u32, Vec<u32>> = chart_blocks(&texels, &paper)?
                .into_iter()
                .map(|(c, s, e)| (c, paper[s..e].to_vec()))
                .collect();
            let blocks = chart_blocks(&texels, &order)?;
            prop_assert_eq!(blocks[0].0, texels[first_texel(&texels) as usize].chart);
            prop_assert_eq!(&order[blocks[0].1..blocks[0].2], &walks[&blocks[0].0][..]);
            let mut done = std::collections::HashSet::new();
            for pair in blocks.windows(2) {
                done.insert(pair[0].0);
                let block = &order[pair[1].1..pair[1].2];
                let walk = &walks[&pair[1].0];
                let reversed: Vec<u32> = walk.iter().rev().copied().collect();
                prop_assert!(block == &walk[..] || block == &reversed[..]);
                // The chosen end is the nearest of all unvisited ends.
                let last = texels[order[pair[0].2 - 1] as usize].position;
                let chosen = dist2(texels[block[0] as usize].position, last);
                for (c, wk) in &walks {
                    if done.contains(c) {
                        continue;
                    }
                    for end in [wk[0], wk[wk.len() - 1]] {
                        prop_assert!(chosen <= dist2(texels[end as usize].position, last));
                    }
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// `Traversal::Piloted` takes, chart by chart, the order its pilot picks: a pilot that always
    /// answers 0 gives the Hilbert traversal, one that always answers 1 the Spiral traversal
    /// (whichever the chart order), and one that picks by chart gives each chart the walk it
    /// picked.
    #[test]
    fn piloted_takes_the_pilots_choice_per_chart(
        seed in any::<u64>(),
        w in 1usize..30,
        h in 1usize..30,
        blobs in 0usize..12,
        isolated in 0usize..20,
        noise in prop_oneof![Just(0.0f32), 0.0f32..0.9],
    ) {
        let texels = random_atlas(seed, w, h, blobs, isolated, noise, false);
        let res = w.max(h) as u32;
        for chart_order in [ChartOrder::Nearest, ChartOrder::Ends] {
            let piloted = |pilot: &cssm_bake::traverse::Pilot| {
                traverse_piloted(&texels, res, Traversal::Piloted, chart_order, pilot)
            };
            let hilbert = traverse_with(&texels, res, Traversal::Hilbert, chart_order);
            let spiral = traverse_with(&texels, res, Traversal::Spiral, chart_order);
            prop_assert_eq!(&piloted(&|_| 0), &hilbert);
            prop_assert_eq!(&piloted(&|_| 1), &spiral);
            prop_assert_eq!(&traverse_with(&texels, res, Traversal::Piloted, chart_order), &hilbert);
            // Odd charts Spiral, even ones Hilbert.
            let by_chart = |orders: &[&[u32]]| (texels[orders[0][0] as usize].chart % 2) as usize;
            let mixed = piloted(&by_chart);
            assert_permutation(&texels, &mixed)?;
            if chart_order == ChartOrder::Nearest && !texels.is_empty() {
                let own = |order: &[u32]| -> Result<std::collections::HashMap<u32, Vec<u32>>, TestCaseError> {
                    Ok(chart_blocks(&texels, order)?
                        .into_iter()
                        .map(|(c, s, e)| (c, order[s..e].to_vec()))
                        .collect())
                };
                let (h, s) = (own(&hilbert)?, own(&spiral)?);
                for (c, block) in own(&mixed)? {
                    let want = if c % 2 == 1 { &s[&c] } else { &h[&c] };
                    prop_assert_eq!(&block, want, "chart {}", c);
                }
            }
        }
    }
}

#[test]
fn empty_input_gives_empty_output() {
    for traversal in Traversal::ALL {
        assert!(traverse(&[], 1024, traversal).is_empty());
    }
}

/// A synthetic 1024² atlas cut to its top `rows` rows: rectangular charts of `cw × ch` cells (with a margin),
/// each mapped onto a tilted square patch at a pseudo-random place of a 3D scene.
fn big_atlas(cw: usize, ch: usize, rows: u16) -> Vec<Texel> {
    let res = 1024usize;
    let mut rng = SplitMix(7);
    let mut texels = Vec::new();
    let mut chart = 0u32;
    for by in (0..res).step_by(ch + 1) {
        for bx in (0..res).step_by(cw + 1) {
            let origin = [
                rng.noise() * 100.0,
                rng.noise() * 100.0,
                rng.noise() * 100.0,
            ];
            let tilt = rng.noise();
            for y in by..(by + ch).min(res) {
                for x in bx..(bx + cw).min(res) {
                    let (u, v) = ((x - bx) as f32 * 0.01, (y - by) as f32 * 0.01);
                    texels.push(Texel {
                        position: [origin[0] + u, origin[1] + v * tilt, origin[2] + v],
                        normal: [0.0, 0.0, 1.0],
                        area: 1e-4,
                        material: 0,
                        chart,
                        object: 0,
                        x: x as u16,
                        y: y as u16,
                    });
                }
            }
            chart += 1;
        }
    }
    // Keep the top `rows` rows, like an atlas that is not full.
    texels.retain(|t| t.y < rows);
    let mut dense = vec![u32::MAX; chart as usize];
    let mut next = 0;
    texels.sort_by_key(|t| (t.y, t.x));
    for t in &mut texels {
        let d = &mut dense[t.chart as usize];
        if *d == u32::MAX {
            *d = next;
            next += 1;
        }
        t.chart = *d;
    }
    texels
}

/// Timing on ~700k texels; run with
/// `cargo test --release -p cssm-bake --test traverse_props -- --ignored --nocapture`.
#[test]
#[ignore = "timing; run in release"]
fn timing_700k_texels() {
    // ~700k texels each: 99 large charts, then ~25k small ones (Sibenik-like).
    for (cw, ch, rows) in [(100, 80, 700), (6, 5, 980)] {
        let texels = big_atlas(cw, ch, rows);
        let charts = texels.iter().map(|t| t.chart).max().unwrap() + 1;
        for traversal in Traversal::ALL {
            let start = Instant::now();
            let order = traverse(&texels, 1024, traversal);
            let elapsed = start.elapsed();
            assert_eq!(order.len(), texels.len());
            println!(
                "{traversal:>6}: {} texels, {charts} charts: {:.3} s",
                texels.len(),
                elapsed.as_secs_f64()
            );
        }
    }
}
