//! Spiral inside one chart (§3.2.3): the left-hand walk along the border of the unvisited region,
//! over a cell lookup of the atlas grid.

use cssm_formats::Texel;

use super::NONE;

/// Upper bound on the number of cells of the dense atlas lookup used by the Spiral walk (§3.2.3);
/// larger (or sparser) atlases use a sorted lookup instead. The effective limit is at least four
/// cells per texel.
pub(super) const DENSE_CELL_LIMIT: usize = 1 << 24;

/// Cell → texel lookup over the atlas grid for the Spiral walk (§3.2.3), which needs the
/// 4-neighbours of a texel.
///
/// Dense (one `u32` per cell of `max(resolution, max x + 1) × max(resolution, max y + 1)`) when
/// that is at most `max(dense_limit, 4 n)` cells, otherwise a sorted `(cell key, texel)` table
/// searched by bisection. If several texels claim one cell (which valid atlases never do), the
/// lookup keeps the smallest index; the others are still emitted by the Spiral's restarts.
#[derive(Debug)]
pub(super) enum CellIndex {
    /// Row-major grid of texel indices, [`NONE`] for undefined cells.
    Dense {
        /// Grid width in cells.
        width: u32,
        /// Grid height in cells.
        height: u32,
        /// `cells[y * width + x]`.
        cells: Vec<u32>,
    },
    /// `(y << 16 | x, texel)` sorted by key, one entry per key.
    Sparse(Vec<(u32, u32)>),
}

impl CellIndex {
    /// Builds the lookup for `texels` (see the type's docs for the dense / sparse choice).
    pub(super) fn new(texels: &[Texel], resolution: u32, dense_limit: usize) -> Self {
        let max_x = texels.iter().map(|t| u32::from(t.x)).max().unwrap_or(0);
        let max_y = texels.iter().map(|t| u32::from(t.y)).max().unwrap_or(0);
        let width = resolution.max(max_x + 1);
        let height = resolution.max(max_y + 1);
        let area = width as usize * height as usize;
        if area <= dense_limit.max(4 * texels.len()) {
            let mut cells = vec![NONE; area];
            for (i, t) in texels.iter().enumerate() {
                let c = &mut cells[t.y as usize * width as usize + t.x as usize];
                if *c == NONE {
                    *c = i as u32;
                }
            }
            CellIndex::Dense {
                width,
                height,
                cells,
            }
        } else {
            let mut table: Vec<(u32, u32)> = texels
                .iter()
                .enumerate()
                .map(|(i, t)| ((u32::from(t.y) << 16) | u32::from(t.x), i as u32))
                .collect();
            table.sort_unstable();
            table.dedup_by_key(|e| e.0);
            CellIndex::Sparse(table)
        }
    }

    /// Texel at cell `(x, y)`, if any (coordinates outside the grid give `None`).
    #[inline]
    fn get(&self, x: i32, y: i32) -> Option<u32> {
        if x < 0 || y < 0 {
            return None;
        }
        let (x, y) = (x as u32, y as u32);
        match self {
            CellIndex::Dense {
                width,
                height,
                cells,
            } => {
                if x >= *width || y >= *height {
                    return None;
                }
                let c = cells[y as usize * *width as usize + x as usize];
                (c != NONE).then_some(c)
            }
            CellIndex::Sparse(table) => {
                if x > 0xFFFF || y > 0xFFFF {
                    return None;
                }
                let key = (y << 16) | x;
                table
                    .binary_search_by_key(&key, |e| e.0)
                    .ok()
                    .map(|p| table[p].1)
            }
        }
    }
}

/// Headings of the Spiral walk, numbered counter-clockwise as seen on the atlas (rows grow
/// downwards): `+1` is a left turn. Offsets `(dx, dy)` for east, north, west, south.
const HEADING_OFFSETS: [(i32, i32); 4] = [(1, 0), (0, -1), (-1, 0), (0, 1)];
/// Heading east: the start heading of a Spiral walk, whose start cell (row-major first unvisited
/// cell) has no unvisited chart cell above it, i.e. on its left.
const EAST: u8 = 0;
/// Turn order of the Spiral walk relative to the current heading: left, straight, right, back.
const TURNS: [u8; 4] = [1, 0, 3, 2];

/// State of the Spiral strategy (§3.2.3) shared by all charts: visited flags and the path stack.
pub(super) struct SpiralWalker<'a> {
    /// The texel table.
    texels: &'a [Texel],
    /// Atlas cell lookup.
    cells: &'a CellIndex,
    /// Per texel: already emitted.
    visited: Vec<bool>,
    /// The visited path, `(texel, heading on arrival)`; its top is the current cell.
    stack: Vec<(u32, u8)>,
}

impl<'a> SpiralWalker<'a> {
    /// A walker with nothing visited.
    pub(super) fn new(texels: &'a [Texel], cells: &'a CellIndex) -> Self {
        SpiralWalker {
            texels,
            cells,
            visited: vec![false; texels.len()],
            stack: Vec::new(),
        }
    }

    /// Spiral inside one chart (§3.2.3): "moves along the border of each chart, marking each
    /// visited texel … walking along left hand side of the border as long as possible. If there is
    /// no free texel in the neighborhood, we step back recursively until a free neighbor is
    /// available."
    ///
    /// `rows` are the chart's texels in row-major order. The walk starts at the first one (a
    /// border texel) heading east, so the outside is on the left. From the current cell and
    /// heading it tries the 4-neighbours turning left, straight, right, then back, and moves to the
    /// first unvisited cell of the same chart, emitting it. When none is free it steps back along
    /// the visited path (a stack; stepped-back cells are not emitted again) and resumes from the
    /// first cell with a free neighbour, with the heading it had when it arrived there. When the
    /// path is exhausted but the chart still has unvisited texels (a chart split in the atlas
    /// grid), it restarts at the row-major first unvisited texel. Linear in the chart size.
    pub(super) fn spiral_chart(&mut self, rows: &[u32], out: &mut Vec<u32>) {
        let Some(&first) = rows.first() else {
            return;
        };
        let chart = self.texels[first as usize].chart;
        let mut cursor = 0;
        loop {
            while cursor < rows.len() && self.visited[rows[cursor] as usize] {
                cursor += 1;
            }
            let Some(&start) = rows.get(cursor) else {
                break;
            };
            self.visited[start as usize] = true;
            out.push(start);
            self.stack.push((start, EAST));
            while let Some(&(cur, heading)) = self.stack.last() {
                match self.free_neighbour(cur, heading, chart) {
                    Some((next, dir)) => {
                        self.visited[next as usize] = true;
                        out.push(next);
                        self.stack.push((next, dir));
                    }
                    None => {
                        self.stack.pop();
                    }
                }
            }
        }
    }

    /// First unvisited 4-neighbour of `cur` in `chart`, trying left, straight, right, back relative
    /// to `heading` (the left-hand rule of §3.2.3's Spiral), with the heading that reaches it.
    #[inline]
    fn free_neighbour(&self, cur: u32, heading: u8, chart: u32) -> Option<(u32, u8)> {
        let t = &self.texels[cur as usize];
        let (x, y) = (i32::from(t.x), i32::from(t.y));
        TURNS.iter().find_map(|&turn| {
            let dir = (heading + turn) % 4;
            let (dx, dy) = HEADING_OFFSETS[dir as usize];
            let nb = self.cells.get(x + dx, y + dy)?;
            (self.texels[nb as usize].chart == chart && !self.visited[nb as usize])
                .then_some((nb, dir))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::traverse::tests::{all_traversals_valid, atlas, cells, texel};
    use crate::traverse::traverse;
    use cssm_formats::Traversal;

    #[test]
    fn spiral_rectangle_is_outside_in() {
        let texels = atlas(&["0000", "0000", "0000"]);
        let order = traverse(&texels, 4, Traversal::Spiral);
        let expected = [
            (0, 0),
            (1, 0),
            (2, 0),
            (3, 0),
            (3, 1),
            (3, 2),
            (2, 2),
            (1, 2),
            (0, 2),
            (0, 1),
            (1, 1),
            (2, 1),
        ];
        assert_eq!(cells(&texels, &order), expected);
    }

    #[test]
    fn spiral_l_shape_follows_the_border() {
        let texels = atlas(&["00", "00", "00000", "00000"]);
        let order = traverse(&texels, 8, Traversal::Spiral);
        let expected = [
            (0, 0),
            (1, 0),
            (1, 1),
            (1, 2),
            (2, 2),
            (3, 2),
            (4, 2),
            (4, 3),
            (3, 3),
            (2, 3),
            (1, 3),
            (0, 3),
            (0, 2),
            (0, 1),
        ];
        assert_eq!(cells(&texels, &order), expected);
        all_traversals_valid(&texels, 8);
    }

    #[test]
    fn spiral_steps_back_from_dead_ends() {
        // A comb: the teeth are dead ends; stepped-back cells are not emitted again.
        let texels = atlas(&["00000", "0.0.0"]);
        let order = traverse(&texels, 5, Traversal::Spiral);
        let expected = [
            (0, 0),
            (1, 0),
            (2, 0),
            (3, 0),
            (4, 0),
            (4, 1),
            (2, 1),
            (0, 1),
        ];
        assert_eq!(cells(&texels, &order), expected);
    }

    #[test]
    fn coordinates_beyond_the_resolution_and_sparse_lookup() {
        let texels = atlas(&["0000", "0000", "0000"]);
        // Resolution smaller than the coordinates: the grid grows.
        assert_eq!(
            traverse(&texels, 1, Traversal::Spiral),
            traverse(&texels, 4, Traversal::Spiral)
        );
        // Dense and sparse lookups agree.
        let dense = CellIndex::new(&texels, 4, usize::MAX);
        assert!(matches!(dense, CellIndex::Dense { .. }));
        // At least four cells per texel stay dense whatever the limit.
        assert!(matches!(
            CellIndex::new(&texels, 4, 0),
            CellIndex::Dense { .. }
        ));
        let sparse = CellIndex::new(&texels, 1000, 0);
        assert!(matches!(sparse, CellIndex::Sparse(_)));
        for y in -1..5 {
            for x in -1..6 {
                assert_eq!(dense.get(x, y), sparse.get(x, y), "({x}, {y})");
            }
        }
        // Far-out coordinates use the sparse lookup and still work.
        let far: Vec<Texel> = texels
            .iter()
            .map(|t| texel(t.x + 60000, t.y + 60000, t.chart, t.position))
            .collect();
        assert_eq!(
            cells(&far, &traverse(&far, 1024, Traversal::Spiral))
                .iter()
                .map(|&(x, y)| (x - 60000, y - 60000))
                .collect::<Vec<_>>(),
            cells(&texels, &traverse(&texels, 4, Traversal::Spiral))
        );
    }
}
