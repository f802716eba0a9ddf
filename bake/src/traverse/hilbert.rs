//! Hilbert order inside one chart (beyond the paper), along the generalised Hilbert curve
//! ("gilbert") over the chart's bounding rectangle.

use cssm_formats::Texel;

/// Hilbert order inside one chart (beyond §3.2.3, which keeps the CSM's Hilbert pattern for
/// square depth-map grids only): the chart's texels sorted by their position along the
/// generalised Hilbert curve over the chart's bounding rectangle ([`gilbert_ranks`]). The curve
/// visits one half or quadrant of the rectangle before the next, so consecutive texels stay
/// close in both atlas directions, which shortens the depth drift inside a run compared with
/// long Zig-Zag rows; unlike a power-of-two Hilbert curve over the bounding square it fits long
/// thin charts without wandering outside them.
pub(super) fn hilbert_chart(texels: &[Texel], rows: &[u32], out: &mut Vec<u32>) {
    let Some(&first) = rows.first() else {
        return;
    };
    let t0 = &texels[first as usize];
    let (mut x0, mut y0, mut x1, mut y1) = (t0.x, t0.y, t0.x, t0.y);
    for &i in rows {
        let t = &texels[i as usize];
        (x0, y0, x1, y1) = (x0.min(t.x), y0.min(t.y), x1.max(t.x), y1.max(t.y));
    }
    let (width, height) = (u32::from(x1 - x0) + 1, u32::from(y1 - y0) + 1);
    if u64::from(width) * u64::from(height) > MAX_CURVE_CELLS {
        // Only hand-made texels spread this far (an atlas is at most 1024 x 1024): keep memory
        // bounded and take them row by row.
        out.extend_from_slice(rows);
        return;
    }
    let rank = gilbert_ranks(width, height);
    let mut keyed: Vec<(u32, u32)> = rows
        .iter()
        .map(|&i| {
            let t = &texels[i as usize];
            let cell = u32::from(t.y - y0) * width + u32::from(t.x - x0);
            (rank[cell as usize], i)
        })
        .collect();
    keyed.sort_unstable();
    out.extend(keyed.iter().map(|&(_, i)| i));
}

/// Largest bounding rectangle, in cells, that [`hilbert_chart`] lays a curve over (64 MiB of
/// ranks; sixteen times the largest atlas).
const MAX_CURVE_CELLS: u64 = 1 << 24;

/// Position of every cell of a `width x height` grid (row-major) along the generalised Hilbert
/// curve over it ("gilbert", J. Červený): the Hilbert curve's recursive quadrant split, adapted to
/// any rectangle, every step to a 4-neighbour (one diagonal step at most, when a side is odd);
/// on a long strip it degenerates into a serpentine across the short side.
pub fn gilbert_ranks(width: u32, height: u32) -> Vec<u32> {
    let mut ranks = vec![0; (width * height) as usize];
    let mut next = 0;
    let (w, h) = (width as i64, height as i64);
    let mut visit = |x: i64, y: i64| {
        ranks[(y * w + x) as usize] = next;
        next += 1;
    };
    if w >= h {
        gilbert(0, 0, w, 0, 0, h, &mut visit);
    } else {
        gilbert(0, 0, 0, h, w, 0, &mut visit);
    }
    ranks
}

/// One block of the generalised Hilbert curve: from `(x, y)`, major axis `(ax, ay)`, minor axis
/// `(bx, by)`.
fn gilbert(x: i64, y: i64, ax: i64, ay: i64, bx: i64, by: i64, visit: &mut impl FnMut(i64, i64)) {
    let (w, h) = ((ax + ay).abs(), (bx + by).abs());
    let (dax, day) = (ax.signum(), ay.signum());
    let (dbx, dby) = (bx.signum(), by.signum());
    if h == 1 || w == 1 {
        let (n, sx, sy) = if h == 1 { (w, dax, day) } else { (h, dbx, dby) };
        for i in 0..n {
            visit(x + i * sx, y + i * sy);
        }
        return;
    }
    let (mut ax2, mut ay2) = (ax.div_euclid(2), ay.div_euclid(2));
    let (mut bx2, mut by2) = (bx.div_euclid(2), by.div_euclid(2));
    let (w2, h2) = ((ax2 + ay2).abs(), (bx2 + by2).abs());
    if 2 * w > 3 * h {
        if w2 % 2 == 1 && w > 2 {
            (ax2, ay2) = (ax2 + dax, ay2 + day);
        }
        gilbert(x, y, ax2, ay2, bx, by, visit);
        gilbert(x + ax2, y + ay2, ax - ax2, ay - ay2, bx, by, visit);
    } else {
        if h2 % 2 == 1 && h > 2 {
            (bx2, by2) = (bx2 + dbx, by2 + dby);
        }
        gilbert(x, y, bx2, by2, ax2, ay2, visit);
        gilbert(x + bx2, y + by2, ax, ay, bx - bx2, by - by2, visit);
        gilbert(
            x + (ax - dax) + (bx2 - dbx),
            y + (ay - day) + (by2 - dby),
            -bx2,
            -by2,
            -(ax - ax2),
            -(ay - ay2),
            visit,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gilbert_visits_every_cell_once_in_neighbouring_steps() {
        let sizes = (1..=24).flat_map(|w| (1..=24).map(move |h| (w, h)));
        for (w, h) in sizes.chain([(12, 40), (33, 17), (64, 64), (100, 3)]) {
            let ranks = gilbert_ranks(w, h);
            let mut cells = vec![(0i64, 0i64); (w * h) as usize];
            let mut seen = vec![false; (w * h) as usize];
            for (cell, &r) in ranks.iter().enumerate() {
                assert!(!seen[r as usize], "{w}x{h}: rank {r} twice");
                seen[r as usize] = true;
                cells[r as usize] = ((cell as u32 % w) as i64, (cell as u32 / w) as i64);
            }
            // Steps to a 4-neighbour, with at most one diagonal step, only when a side is odd.
            let diagonal = cells
                .windows(2)
                .map(|p| {
                    let (dx, dy) = ((p[1].0 - p[0].0).abs(), (p[1].1 - p[0].1).abs());
                    assert!(dx <= 1 && dy <= 1 && dx + dy >= 1, "{w}x{h}: {:?}", p);
                    usize::from(dx + dy == 2)
                })
                .sum::<usize>();
            assert!(
                diagonal <= usize::from(w % 2 == 1 || h % 2 == 1),
                "{w}x{h}: {diagonal}"
            );
        }
    }
}
