//! Greedy traversal (§3.2.3): nearest unvisited texel first.

use cssm_formats::Texel;

use super::chart_order::NearestSet;
use super::{first_texel, sanitized_position};

/// Greedy traversal (§3.2.3: "a traversal that greedily walks a number of random samples that
/// were distributed evenly across the surface"), here over the texel positions themselves.
///
/// Starts at the row-major first texel and repeatedly moves to the nearest unvisited texel in 3D
/// (ties: smaller texel index), using a [`NearestSet`]; `O(n log n)` in practice.
pub(super) fn greedy_order(texels: &[Texel]) -> Vec<u32> {
    let points: Vec<[f32; 3]> = texels.iter().map(sanitized_position).collect();
    let mut set = NearestSet::new(&points);
    let mut out = Vec::with_capacity(texels.len());
    let mut current = first_texel(texels);
    loop {
        out.push(current);
        set.remove(current);
        match set.nearest(points[current as usize]) {
            Some(next) => current = next,
            None => break,
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use crate::traverse::tests::texel;
    use crate::traverse::traverse;
    use cssm_formats::{Texel, Traversal};

    #[test]
    fn greedy_walks_nearest_first() {
        // On a line: start at the row-major first texel (x = 5), then nearest-first.
        let xs = [5.0, 0.0, 6.0, 2.0, 9.0, 5.5];
        let texels: Vec<Texel> = xs
            .iter()
            .enumerate()
            .map(|(i, &x)| texel(i as u16, 0, 0, [x, 0.0, 0.0]))
            .collect();
        let order = traverse(&texels, 8, Traversal::Greedy);
        // 5 -> 5.5 -> 6 -> 9 (3 away, 2 is 4 away) -> 2 -> 0.
        assert_eq!(order, vec![0, 5, 2, 4, 3, 1]);
    }

    #[test]
    fn greedy_ties_go_to_the_smaller_index() {
        let texels = vec![
            texel(0, 0, 0, [0.0, 0.0, 0.0]),
            texel(1, 0, 0, [1.0, 0.0, 0.0]),
            texel(2, 0, 0, [-1.0, 0.0, 0.0]),
            texel(3, 0, 0, [0.0, 1.0, 0.0]),
        ];
        assert_eq!(traverse(&texels, 4, Traversal::Greedy), vec![0, 1, 3, 2]);
    }
}
