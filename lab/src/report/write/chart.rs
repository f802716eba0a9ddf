//! `compression.svg`: ratio against atlas resolution, Table 2's traversals and Table 3's scenes
//! beside the paper's figures (plotters' SVG backend: no fonts or system libraries needed).

use plotters::prelude::*;

use super::rows;
use crate::report::{BEST, PAPER, PaperFigures, Report, Row, SceneId, TableId, paper};
use cssm_formats::Traversal;

fn colour(t: Traversal) -> RGBColor {
    match t {
        Traversal::Greedy => RGBColor(0x1f, 0x77, 0xb4),
        Traversal::Zigzag => RGBColor(0xff, 0x7f, 0x0e),
        Traversal::Spiral => RGBColor(0x2c, 0xa0, 0x2c),
        Traversal::Hilbert => RGBColor(0xd6, 0x27, 0x28),
        Traversal::Piloted => RGBColor(0x94, 0x67, 0xbd),
    }
}

/// The chart: ratio against atlas resolution (log2 axis), one line per traversal (Table 2, solid:
/// measured, dashed: the paper), and Table 3's scenes (paper method and best options).
pub fn svg(r: &Report) -> Result<String, String> {
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (1100, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (left, right) = root.split_horizontally(550);
        let t2: Vec<&Row> = rows(r, TableId::Table2).collect();
        let mut lines: Vec<Line> = Vec::new();
        for t in Traversal::ALL {
            let ours: Vec<(f64, f64)> = t2
                .iter()
                .filter(|row| row.plan.variant.traversal == t)
                .filter_map(|row| {
                    row.outcome
                        .as_ref()
                        .ok()
                        .map(|m| (row.plan.atlas as f64, m.ratio()))
                })
                .collect();
            let paper: Vec<(f64, f64)> = paper::TABLE2
                .iter()
                .filter(|p| p.1 == t)
                .map(|p| (p.0 as f64, p.2))
                .collect();
            let same_cube = t2.iter().all(|row| row.plan.cube == paper::TABLE2_CUBE);
            if !ours.is_empty() {
                lines.push((format!("{t} (ours)"), colour(t), false, ours));
                if !paper.is_empty() && same_cube {
                    lines.push((format!("{t} (paper's Table 2)"), colour(t), true, paper));
                }
            }
        }
        let cube2 = t2.first().map_or(32, |row| row.plan.cube);
        panel(
            &left,
            &format!("Table 2: Cornell box, cube 6x{cube2}x{cube2}"),
            &lines,
        )?;

        let mut lines3 = Vec::new();
        let palette = [
            RGBColor(0x2c, 0xa0, 0x2c),
            RGBColor(0x94, 0x67, 0xbd),
            RGBColor(0x8c, 0x56, 0x4b),
            RGBColor(0xd6, 0x27, 0x28),
        ];
        for (scene, c) in SceneId::ALL.into_iter().zip(palette) {
            for v in [PAPER, BEST] {
                let pts: Vec<(f64, f64)> = rows(r, TableId::Table3)
                    .filter(|row| row.plan.scene == scene && row.plan.variant == v)
                    .filter_map(|row| {
                        row.outcome
                            .as_ref()
                            .ok()
                            .map(|m| (row.plan.atlas as f64, m.ratio()))
                    })
                    .collect();
                if !pts.is_empty() {
                    // The paper's method in a lighter shade of the scene's colour.
                    let light = |x: u8| x + ((255 - x) as f32 * 0.5) as u8;
                    let rgb = if v == PAPER {
                        RGBColor(light(c.0), light(c.1), light(c.2))
                    } else {
                        c
                    };
                    let what = if v == PAPER { "paper's method" } else { v.name };
                    lines3.push((format!("{}, {what} (ours)", scene.name()), rgb, false, pts));
                }
            }
            if rows(r, TableId::Table3).any(|row| {
                row.plan.scene == scene
                    && row.outcome.is_ok()
                    && matches!(row.plan.paper, PaperFigures::Table3(_))
            }) {
                let paper: Vec<(f64, f64)> = scene
                    .paper_rows()
                    .iter()
                    .map(|p| (p.atlas as f64, p.ratio))
                    .collect();
                lines3.push((
                    format!("{} (paper's Table 3)", scene.name()),
                    c,
                    true,
                    paper,
                ));
            }
        }
        let title3 = match rows(r, TableId::Table3).next().map(|row| row.plan.cube) {
            Some(c) if rows(r, TableId::Table3).all(|row| row.plan.cube == c) => {
                format!("Table 3: cube 6x{c}x{c}")
            }
            _ => "Table 3: cube 6x64x64 (church 512: 6x32x32)".to_string(),
        };
        panel(&right, &title3, &lines3)?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(out)
}

/// A line of a panel: legend name, colour, dashed (the paper's figures), points (atlas, ratio).
type Line = (String, RGBColor, bool, Vec<(f64, f64)>);

/// One panel: atlas resolution on a log2 axis (labelled 32, 64, ...), ratio axis, lines with a
/// legend.
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    lines: &[Line],
) -> Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let xs = lines.iter().flat_map(|l| l.3.iter().map(|p| p.0.log2()));
    let (x0, x1) = xs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
        (a.min(x), b.max(x))
    });
    let (x0, x1) = if x0.is_finite() {
        (x0, x1.max(x0 + 1.0))
    } else {
        (5.0, 7.0)
    };
    let y1 = lines
        .iter()
        .flat_map(|l| l.3.iter().map(|p| p.1))
        .fold(1.0f64, f64::max)
        * 1.1;
    let mut chart = ChartBuilder::on(area)
        .caption(
            if lines.is_empty() {
                format!("{title}: no rows")
            } else {
                title.to_string()
            },
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0 - 0.25..x1 + 0.25, 0.0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("atlas resolution (texels per side, log scale)")
        .y_desc("ratio (uncompressed / GPU-resident)")
        .x_labels(((x1 - x0) as usize + 1) * 2 + 1)
        .x_label_formatter(&|x| {
            // Label only the powers of two.
            if (x - x.round()).abs() < 1e-6 {
                format!("{}", 2f64.powf(x.round()))
            } else {
                String::new()
            }
        })
        .light_line_style(WHITE)
        .draw()
        .map_err(err)?;
    for (name, c, dashed, pts) in lines {
        let c = *c;
        let pts: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (x.log2(), y)).collect();
        if *dashed {
            chart
                .draw_series(DashedLineSeries::new(
                    pts.iter().copied(),
                    6,
                    4,
                    c.stroke_width(2),
                ))
                .map_err(err)?
                .label(name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 8, y)], c.stroke_width(2))
                });
        } else {
            chart
                .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))
                .map_err(err)?
                .label(name.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2))
                });
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                .map_err(err)?;
        }
    }
    if lines.is_empty() {
        return Ok(());
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    Ok(())
}
