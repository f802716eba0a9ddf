//! The chart ordering of the chart-by-chart traversals (§3.2.3: on to the nearest unvisited
//! chart), and the k-d tree of nearest-remaining-point queries behind it and the Greedy walk.

use cssm_formats::Texel;

use super::{NONE, VisitChart, first_texel, sanitized_position};

/// Squared Euclidean distance, always summed in the same order so that the k-d tree's box bound
/// is exactly a lower bound in floating point.
#[inline]
fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    let dx = a[0] - b[0];
    let dy = a[1] - b[1];
    let dz = a[2] - b[2];
    dx * dx + dy * dy + dz * dz
}

/// Drives the chart-by-chart strategies of §3.2.3 ("one chart after the other is visited").
///
/// Groups the texels by chart (each chart's texels in row-major order), starts with the chart of
/// the row-major first texel, lets `visit_chart(chart_id, rows, out)` append that chart's order,
/// and then moves to the unvisited chart whose first texel is closest in 3D to the last texel
/// appended (ties: smaller chart id). The nearest-chart queries use a [`NearestSet`] over the
/// charts' first texels, so this costs `O(n log n + c log c)` for `n` texels and `c` charts.
///
/// `visit_chart` must append exactly the texels of `rows` (in any order).
pub(super) fn chart_by_chart(texels: &[Texel], visit_chart: &mut VisitChart) -> Vec<u32> {
    let n = texels.len();
    let (sorted, runs) = chart_runs(texels);
    let entries: Vec<[f32; 3]> = runs
        .iter()
        .map(|&(_, s, _)| sanitized_position(&texels[sorted[s] as usize]))
        .collect();
    let mut remaining = NearestSet::new(&entries);

    let first_chart = texels[first_texel(texels) as usize].chart;
    let mut current = runs
        .binary_search_by_key(&first_chart, |r| r.0)
        .expect("the first texel's chart has a run") as u32;
    let mut out = Vec::with_capacity(n);
    loop {
        let (chart, s, e) = runs[current as usize];
        let before = out.len();
        visit_chart(chart, &sorted[s..e], &mut out);
        debug_assert_eq!(
            out.len() - before,
            e - s,
            "a chart visit must emit its texels"
        );
        remaining.remove(current);
        let last = sanitized_position(&texels[*out.last().expect("charts are non-empty") as usize]);
        match remaining.nearest(last) {
            Some(next) => current = next,
            None => break,
        }
    }
    out
}

/// The chart order of [`ChartOrder::Ends`]: every chart's own walk is computed first (in chart
/// id order), then charts are strung together starting with the chart of the row-major first
/// texel (walked forwards), always moving to the unvisited chart with an end nearest to the last
/// texel emitted (ties: smaller chart id, then its first end), walked backwards when that end is
/// its last texel. `O(n log n + c log c)`.
///
/// [`ChartOrder::Ends`]: super::ChartOrder::Ends
pub(super) fn chart_by_chart_ends(texels: &[Texel], visit_chart: &mut VisitChart) -> Vec<u32> {
    let n = texels.len();
    let (sorted, runs) = chart_runs(texels);
    let mut walks = Vec::with_capacity(n);
    let mut ranges = Vec::with_capacity(runs.len());
    for &(chart, s, e) in &runs {
        let before = walks.len();
        visit_chart(chart, &sorted[s..e], &mut walks);
        debug_assert_eq!(
            walks.len() - before,
            e - s,
            "a chart visit must emit its texels"
        );
        ranges.push(before..walks.len());
    }
    // Point 2k is chart run k's first texel, point 2k + 1 its last.
    let pos = |i: u32| sanitized_position(&texels[i as usize]);
    let ends: Vec<[f32; 3]> = ranges
        .iter()
        .flat_map(|r| [pos(walks[r.start]), pos(walks[r.end - 1])])
        .collect();
    let mut remaining = NearestSet::new(&ends);
    let first_chart = texels[first_texel(texels) as usize].chart;
    let mut current = runs
        .binary_search_by_key(&first_chart, |r| r.0)
        .expect("the first texel's chart has a run");
    let mut backwards = false;
    let mut out = Vec::with_capacity(n);
    loop {
        let walk = &walks[ranges[current].clone()];
        if backwards {
            out.extend(walk.iter().rev());
        } else {
            out.extend_from_slice(walk);
        }
        remaining.remove(2 * current as u32);
        remaining.remove(2 * current as u32 + 1);
        let last = pos(*out.last().expect("charts are non-empty"));
        match remaining.nearest(last) {
            Some(end) => {
                current = (end / 2) as usize;
                backwards = end % 2 == 1;
            }
            None => break,
        }
    }
    out
}

/// All texels sorted by `(chart, y, x, index)` (charts become contiguous, each row-major), and
/// the runs of equal chart `(chart id, start, end)` in increasing chart id.
fn chart_runs(texels: &[Texel]) -> (Vec<u32>, Vec<(u32, usize, usize)>) {
    let n = texels.len();
    // All texels sorted by (chart, y, x, index): charts become contiguous runs, each row-major.
    let mut sorted: Vec<u32> = (0..n as u32).collect();
    sorted.sort_unstable_by_key(|&i| {
        let t = &texels[i as usize];
        (t.chart, t.y, t.x, i)
    });
    // Runs of equal chart id: (chart id, start, end) in increasing chart id.
    let mut runs: Vec<(u32, usize, usize)> = Vec::new();
    let mut start = 0;
    while start < n {
        let chart = texels[sorted[start] as usize].chart;
        let mut end = start + 1;
        while end < n && texels[sorted[end] as usize].chart == chart {
            end += 1;
        }
        runs.push((chart, start, end));
        start = end;
    }
    (sorted, runs)
}

/// Leaf size of the [`NearestSet`] k-d tree.
const LEAF_SIZE: usize = 8;

/// One node of the [`NearestSet`] k-d tree.
#[derive(Clone, Copy, Debug)]
struct KdNode {
    /// Lower corner of the bounding box of the node's points (as built; not shrunk on removal).
    lo: [f32; 3],
    /// Upper corner of the bounding box.
    hi: [f32; 3],
    /// Range `start..end` of the node's points in the tree's point order.
    start: u32,
    /// End of the point range.
    end: u32,
    /// Children (`NONE` for a leaf).
    children: [u32; 2],
    /// Parent (`NONE` for the root).
    parent: u32,
    /// Number of points of the node not yet removed.
    alive: u32,
}

/// A set of 3D points supporting "nearest remaining point" queries and removal: the spatial
/// structure behind the next-chart choice and the Greedy walk of §3.2.3.
///
/// A static k-d tree (median splits on the widest axis, leaves of up to [`LEAF_SIZE`] points) with
/// per-node counts of remaining points, so exhausted subtrees are skipped. Queries return the
/// point minimising `(squared distance, point index)`, which makes them deterministic and
/// independent of the tree layout. Points must be finite.
#[derive(Debug)]
pub(super) struct NearestSet {
    /// Nodes; node 0 is the root (absent when there are no points).
    nodes: Vec<KdNode>,
    /// Points in tree order.
    points: Vec<[f32; 3]>,
    /// Original index of each point in tree order.
    ids: Vec<u32>,
    /// Per tree-order slot: not yet removed.
    alive: Vec<bool>,
    /// Per original index: its tree-order slot.
    slot_of: Vec<u32>,
    /// Per tree-order slot: its leaf node.
    leaf_of: Vec<u32>,
    /// Reusable traversal stack of `(node, squared box distance)`.
    stack: Vec<(u32, f32)>,
}

impl NearestSet {
    /// Builds the set holding all of `points` (indices `0..points.len()`).
    pub(super) fn new(points: &[[f32; 3]]) -> Self {
        let n = points.len();
        let mut ids: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::with_capacity(2 * n / LEAF_SIZE + 2);
        let mut leaf_of = vec![NONE; n];
        if n > 0 {
            // Explicit work list instead of recursion: (node index, start, end).
            nodes.push(Self::make_node(points, &ids, 0, n, NONE));
            let mut work = vec![0u32];
            while let Some(node) = work.pop() {
                let KdNode {
                    lo, hi, start, end, ..
                } = nodes[node as usize];
                let (start, end) = (start as usize, end as usize);
                if end - start <= LEAF_SIZE {
                    leaf_of[start..end].fill(node);
                    continue;
                }
                let axis = (0..3)
                    .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])).then(b.cmp(&a)))
                    .expect("three axes");
                let mid = start + (end - start) / 2;
                ids[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
                    points[a as usize][axis]
                        .total_cmp(&points[b as usize][axis])
                        .then(a.cmp(&b))
                });
                let left = nodes.len() as u32;
                nodes.push(Self::make_node(points, &ids, start, mid, node));
                nodes.push(Self::make_node(points, &ids, mid, end, node));
                nodes[node as usize].children = [left, left + 1];
                work.push(left + 1);
                work.push(left);
            }
        }
        let mut slot_of = vec![NONE; n];
        for (slot, &id) in ids.iter().enumerate() {
            slot_of[id as usize] = slot as u32;
        }
        NearestSet {
            nodes,
            points: ids.iter().map(|&id| points[id as usize]).collect(),
            ids,
            alive: vec![true; n],
            slot_of,
            leaf_of,
            stack: Vec::new(),
        }
    }

    /// A node over `ids[start..end]` with its bounding box, no children, all points alive.
    fn make_node(
        points: &[[f32; 3]],
        ids: &[u32],
        start: usize,
        end: usize,
        parent: u32,
    ) -> KdNode {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for &id in &ids[start..end] {
            let p = points[id as usize];
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        KdNode {
            lo,
            hi,
            start: start as u32,
            end: end as u32,
            children: [NONE; 2],
            parent,
            alive: (end - start) as u32,
        }
    }

    /// Removes point `id` (no effect if already removed).
    pub(super) fn remove(&mut self, id: u32) {
        let slot = self.slot_of[id as usize] as usize;
        if !std::mem::replace(&mut self.alive[slot], false) {
            return;
        }
        let mut node = self.leaf_of[slot];
        while node != NONE {
            let n = &mut self.nodes[node as usize];
            n.alive -= 1;
            node = n.parent;
        }
    }

    /// Squared distance from `q` to the bounding box of `node` (0 inside); never larger than the
    /// [`dist2`] of `q` to any point of the node, also in floating point.
    #[inline]
    fn box_dist2(&self, node: u32, q: [f32; 3]) -> f32 {
        let n = &self.nodes[node as usize];
        let mut d = [0.0f32; 3];
        for a in 0..3 {
            d[a] = if q[a] < n.lo[a] {
                n.lo[a] - q[a]
            } else if q[a] > n.hi[a] {
                q[a] - n.hi[a]
            } else {
                0.0
            };
        }
        d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    }

    /// The remaining point minimising `(dist2(point, q), index)`, or `None` when empty.
    pub(super) fn nearest(&mut self, q: [f32; 3]) -> Option<u32> {
        if self.nodes.first().is_none_or(|root| root.alive == 0) {
            return None;
        }
        let mut best_d = f32::INFINITY;
        let mut best_id = NONE;
        let mut stack = std::mem::take(&mut self.stack);
        stack.clear();
        stack.push((0, 0.0));
        while let Some((node, bound)) = stack.pop() {
            // Equal bounds may still hold an equally near point with a smaller index.
            if bound > best_d {
                continue;
            }
            let n = self.nodes[node as usize];
            if n.children[0] == NONE {
                for slot in n.start as usize..n.end as usize {
                    if !self.alive[slot] {
                        continue;
                    }
                    let d = dist2(self.points[slot], q);
                    let id = self.ids[slot];
                    if d < best_d || (d == best_d && id < best_id) {
                        best_d = d;
                        best_id = id;
                    }
                }
                continue;
            }
            let [a, b] = n.children;
            let da = self.box_dist2(a, q);
            let db = self.box_dist2(b, q);
            // Push the farther child first so the nearer one is searched first.
            let (near, dn, far, df) = if db < da {
                (b, db, a, da)
            } else {
                (a, da, b, db)
            };
            if self.nodes[far as usize].alive > 0 && df <= best_d {
                stack.push((far, df));
            }
            if self.nodes[near as usize].alive > 0 && dn <= best_d {
                stack.push((near, dn));
            }
        }
        self.stack = stack;
        (best_id != NONE).then_some(best_id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::traverse::tests::{atlas, texel};
    use crate::traverse::traverse;
    use cssm_formats::Traversal;

    #[test]
    fn next_chart_is_the_closest_in_3d() {
        // Atlas order 0, 1, 2; in 3D chart 0 is at z = 0, chart 1 at z = 100, chart 2 at z = 1.
        let mut texels = atlas(&["0.1.2", "0.1.2"]);
        for t in &mut texels {
            t.position[2] = [0.0, 100.0, 1.0][t.chart as usize];
        }
        for t in [Traversal::Zigzag, Traversal::Spiral] {
            let order = traverse(&texels, 8, t);
            let charts: Vec<u32> = order.iter().map(|&i| texels[i as usize].chart).collect();
            assert_eq!(charts, [0, 0, 2, 2, 1, 1], "{t}");
        }
    }

    #[test]
    fn chart_ties_go_to_the_smaller_chart_id() {
        // Charts 1 and 2 are equally far from chart 0's last texel.
        let texels = vec![
            texel(0, 0, 0, [0.0, 0.0, 0.0]),
            texel(2, 0, 2, [0.0, 0.0, 5.0]),
            texel(4, 0, 1, [0.0, 0.0, -5.0]),
        ];
        for t in [Traversal::Zigzag, Traversal::Spiral] {
            assert_eq!(traverse(&texels, 8, t), vec![0, 2, 1], "{t}");
        }
    }

    #[test]
    fn nearest_set_matches_brute_force() {
        // Deterministic pseudo-random points with many exact ties (coarse coordinates).
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 33) % 7) as f32
        };
        let points: Vec<[f32; 3]> = (0..300).map(|_| [next(), next(), next()]).collect();
        let mut set = NearestSet::new(&points);
        let mut alive = vec![true; points.len()];
        let mut q = [3.0, 3.0, 3.0];
        for step in 0..points.len() {
            let expected = (0..points.len() as u32)
                .filter(|&i| alive[i as usize])
                .min_by(|&a, &b| {
                    dist2(points[a as usize], q)
                        .total_cmp(&dist2(points[b as usize], q))
                        .then(a.cmp(&b))
                });
            let got = set.nearest(q);
            assert_eq!(got, expected, "step {step}");
            let id = got.unwrap();
            alive[id as usize] = false;
            set.remove(id);
            set.remove(id); // idempotent
            q = [next() + 0.5, next(), next() - 0.25];
        }
        assert_eq!(set.nearest(q), None);
    }
}
