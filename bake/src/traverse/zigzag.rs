//! Zig-Zag inside one chart (§3.2.3).

use cssm_formats::Texel;

/// Zig-Zag inside one chart (§3.2.3): "visit all texels inside the box in a zig-zag pattern from
/// top to bottom", skipping cells that are undefined or belong to another chart.
///
/// `rows` are the chart's texels in row-major order. Row `r` of the chart's bounding box (counted
/// from its top row, empty rows included) is visited left-to-right when `r` is even and
/// right-to-left when `r` is odd.
pub(super) fn zigzag_chart(texels: &[Texel], rows: &[u32], out: &mut Vec<u32>) {
    let Some(&first) = rows.first() else {
        return;
    };
    let top = texels[first as usize].y;
    let mut start = 0;
    while start < rows.len() {
        let y = texels[rows[start] as usize].y;
        let mut end = start + 1;
        while end < rows.len() && texels[rows[end] as usize].y == y {
            end += 1;
        }
        if (y - top) % 2 == 0 {
            out.extend_from_slice(&rows[start..end]);
        } else {
            out.extend(rows[start..end].iter().rev());
        }
        start = end;
    }
}

#[cfg(test)]
mod tests {
    use crate::traverse::tests::{atlas, cells};
    use crate::traverse::traverse;
    use cssm_formats::Traversal;

    #[test]
    fn zigzag_rectangle_is_serpentine() {
        let texels = atlas(&["", " 00000", " 00000", " 00000", " 00000"]);
        let order = traverse(&texels, 8, Traversal::Zigzag);
        let mut expected = Vec::new();
        for y in 1..5u16 {
            let xs: Vec<u16> = if y % 2 == 1 {
                (1..6).collect()
            } else {
                (1..6).rev().collect()
            };
            expected.extend(xs.into_iter().map(|x| (x, y)));
        }
        assert_eq!(cells(&texels, &order), expected);
    }

    #[test]
    fn zigzag_l_shape() {
        let texels = atlas(&["00", "00", "00000", "00000"]);
        let order = traverse(&texels, 8, Traversal::Zigzag);
        let expected = [
            (0, 0),
            (1, 0),
            (1, 1),
            (0, 1),
            (0, 2),
            (1, 2),
            (2, 2),
            (3, 2),
            (4, 2),
            (4, 3),
            (3, 3),
            (2, 3),
            (1, 3),
            (0, 3),
        ];
        assert_eq!(cells(&texels, &order), expected);
    }
}
