//! The check of a hierarchy read from a file ([`Hierarchy::validate`]): node and leaf counts,
//! the leaf permutation, every node's values and its links to its children, so that the
//! stack-less traversal (§4.2.1) of a loaded tree visits every node once and stays in bounds.

use super::Hierarchy;

impl Hierarchy {
    /// Checks the hierarchy for a file of `texel_count` texels: `2 * texel_count - 1` nodes,
    /// `leaf_texels` a permutation of `0..texel_count`, and the tree well-formed: the root
    /// covers every leaf and ends at the node count, every inner node `i` has its left child at
    /// `i + 1` starting at its first leaf and its right child at the left child's skip holding
    /// the rest of its leaves and skipping to where it does, every leaf has count 1 and skips to
    /// `i + 1`; all floats finite, radius and area >= 0, `cone_cos` in [-1, 1], and each
    /// representative one of its node's leaves. The error names the node.
    ///
    /// Iterative and O(n); it allocates only one `u32` per texel.
    pub fn validate(&self, texel_count: usize) -> Result<(), String> {
        let n = texel_count as u64;
        let m = self.nodes.len() as u64;
        let expected = (2 * n).saturating_sub(1);
        if m != expected {
            return Err(format!(
                "{m} nodes, expected 2 * {n} texels - 1 = {expected}"
            ));
        }
        if self.leaf_texels.len() as u64 != n {
            return Err(format!(
                "{} leaf_texels for {n} texels",
                self.leaf_texels.len()
            ));
        }
        // Position of every texel in the leaf order, u32::MAX where not (yet) seen.
        let mut position = vec![u32::MAX; texel_count];
        for (k, &t) in self.leaf_texels.iter().enumerate() {
            match position.get_mut(t as usize) {
                None => return Err(format!("leaf_texels[{k}] = {t} is not a texel index")),
                Some(p) if *p != u32::MAX => {
                    return Err(format!(
                        "leaf_texels[{k}] = {t} repeats a texel: not a permutation"
                    ));
                }
                Some(p) => *p = k as u32,
            }
        }
        if let Some(root) = self.nodes.first() {
            if root.first != 0 || u64::from(root.count) != n || u64::from(root.skip) != m {
                return Err(format!(
                    "root node: first {}, count {}, skip {}; expected 0, {n}, {m}",
                    root.first, root.count, root.skip
                ));
            }
        }
        // First each node on its own (so that the error names the node that is wrong)...
        for (i, node) in self.nodes.iter().enumerate() {
            let err = |what: String| Err(format!("node {i}: {what}"));
            let floats = node.center.iter().chain(&node.normal).chain([
                &node.radius,
                &node.cone_cos,
                &node.area,
            ]);
            if floats.clone().any(|v| !v.is_finite()) {
                return err("a non-finite value".into());
            }
            // The padding is zero in every file a bake writes: anything else is corruption.
            if node._pad != [0; 3] {
                return err(format!("padding {:?} is not zero", node._pad));
            }
            if node.radius < 0.0 {
                return err(format!("negative radius {}", node.radius));
            }
            if node.area < 0.0 {
                return err(format!("negative area {}", node.area));
            }
            if !(-1.0..=1.0).contains(&node.cone_cos) {
                return err(format!("cone_cos {} outside [-1, 1]", node.cone_cos));
            }
            let (first, count) = (u64::from(node.first), u64::from(node.count));
            if count == 0 || first + count > n {
                return err(format!("leaves {first}..{} outside 0..{n}", first + count));
            }
            let skip = i as u64 + 2 * count - 1;
            if skip > m {
                return err(format!(
                    "{count} leaves need nodes up to {skip}, past the {m} nodes"
                ));
            }
            if u64::from(node.skip) != skip {
                return err(format!(
                    "skip {}, expected {skip} for {count} leaves",
                    node.skip
                ));
            }
            match position.get(node.representative as usize) {
                Some(&p) if (first..first + count).contains(&u64::from(p)) => {}
                _ => {
                    return err(format!(
                        "representative {} is not one of its leaves",
                        node.representative
                    ));
                }
            }
        }
        // ... then against its children. With the root's range fixed, these local checks make
        // the nodes a tree whose every subtree spans `2 * count - 1` nodes from its index and
        // whose children split its leaf range: every node is reached exactly once from the
        // root, and the leaves of every cut partition the leaf order.
        for (i, node) in self.nodes.iter().enumerate() {
            let err = |what: String| Err(format!("node {i}: {what}"));
            let (first, count) = (u64::from(node.first), u64::from(node.count));
            if count == 1 {
                continue;
            }
            // skip <= m and count >= 2, so both children exist.
            let Some(left) = self.nodes.get(i + 1) else {
                return err("no left child".into());
            };
            if left.first != node.first || left.count >= node.count {
                return err(format!(
                    "left child {} has leaves {}+{}, not a first part of {first}+{count}",
                    i + 1,
                    left.first,
                    left.count
                ));
            }
            let r = left.skip as usize;
            let Some(right) = self.nodes.get(r).filter(|_| r > i + 1) else {
                return err(format!("right child {r} (left child's skip) out of range"));
            };
            if u64::from(right.first) != first + u64::from(left.count)
                || right.count != node.count - left.count
                || right.skip != node.skip
            {
                return err(format!(
                    "right child {r} has leaves {}+{} and skip {}, expected {}+{} and skip {}",
                    right.first,
                    right.count,
                    right.skip,
                    first + u64::from(left.count),
                    node.count - left.count,
                    node.skip
                ));
            }
        }
        Ok(())
    }
}
