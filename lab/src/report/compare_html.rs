//! The page of `cssm compare`: `index.html` (one self-contained file beside its images: the
//! settings, the chart of error against time, a table of every figure sortable by any column,
//! and per scene a grid of the reference's and every method's full image, indirect light and
//! the indirect light's FLIP error map), and `chart.svg` (plotters).

use std::fmt::Write as _;

use plotters::prelude::*;

use super::compare::{
    self, CompareReport, ComponentFigures, DEFINITIONS, MethodComparison, SceneComparison,
    bias_cell, fixed, flip_cell, mebibytes, rmse_cell,
};

/// `text` with `& < > " '` escaped for HTML text and attribute values.
///
/// ```
/// use cssm_lab::report::compare_html::escape;
/// assert_eq!(escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
/// ```
pub fn escape(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => s += "&amp;",
            '<' => s += "&lt;",
            '>' => s += "&gt;",
            '"' => s += "&quot;",
            '\'' => s += "&#39;",
            c => s.push(c),
        }
    }
    s
}

/// Markdown's `code` and *emphasis* of [`DEFINITIONS`] as HTML.
fn definitions_html() -> String {
    let mut s = String::new();
    let (mut code, mut em) = (false, false);
    for c in escape(DEFINITIONS).chars() {
        match c {
            '`' => {
                s += if code { "</code>" } else { "<code>" };
                code = !code;
            }
            '*' if !code => {
                s += if em { "</em>" } else { "<em>" };
                em = !em;
            }
            c => s.push(c),
        }
    }
    s
}

const STYLE: &str = "
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; max-width: 1400px; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 2em; }
.meta, .note { color: #555; font-size: 0.9em; }
code { background: #f3f3f3; padding: 0 0.2em; }
table.figures { border-collapse: collapse; font-size: 0.85em; }
table.figures th, table.figures td { border-bottom: 1px solid #ddd; padding: 0.25em 0.6em; text-align: right; }
table.figures th { cursor: pointer; background: #f6f6f6; position: sticky; top: 0; }
table.figures th[aria-sort='ascending']::after { content: ' ▲'; }
table.figures th[aria-sort='descending']::after { content: ' ▼'; }
table.figures td.name { text-align: left; }
table.grid { border-collapse: collapse; }
table.grid td, table.grid th { padding: 0.3em; vertical-align: top; text-align: left; font-size: 0.85em; }
table.grid img { image-rendering: pixelated; display: block; }
.failed { color: #a00; }
details { font-size: 0.85em; }
";

/// Sorts a table of class `figures` by the clicked column: numbers by `data-value` (cells
/// without one, and the rows of failed methods, last), text otherwise; a second click reverses.
const SCRIPT: &str = "
document.querySelectorAll('table.figures').forEach(function (table) {
  var headers = table.querySelectorAll('th');
  headers.forEach(function (th, column) {
    th.addEventListener('click', function () {
      var ascending = th.getAttribute('aria-sort') !== 'ascending';
      headers.forEach(function (h) { h.removeAttribute('aria-sort'); });
      th.setAttribute('aria-sort', ascending ? 'ascending' : 'descending');
      var body = table.tBodies[0];
      var rows = Array.prototype.slice.call(body.rows);
      var key = function (row) {
        var cell = row.cells[column];
        if (!cell) { return null; } // a failed method's row: one cell past the names
        var v = cell.getAttribute('data-value');
        return v === null ? cell.textContent : (v === '' ? null : parseFloat(v));
      };
      rows.sort(function (a, b) {
        var x = key(a), y = key(b);
        if (x === null || y === null) { return (x === null) - (y === null); }
        var order = typeof x === 'number' ? x - y : String(x).localeCompare(String(y));
        return ascending ? order : -order;
      });
      rows.forEach(function (row) { body.appendChild(row); });
    });
  });
});
";

/// A number cell sortable by its value.
fn number_td(value: Option<f64>, text: String) -> String {
    format!(
        "<td data-value=\"{}\">{}</td>",
        value.map_or(String::new(), |v| format!("{v}")),
        escape(&text)
    )
}

/// The scale at which images of `width` pixels are shown: a whole number, at least 240 pixels
/// wide.
fn scale(width: u32) -> u32 {
    240u32.div_ceil(width.max(1)).max(1)
}

/// A relative path as a URL: every byte outside `A-Z a-z 0-9 - . _ ~ /` percent-encoded, so a
/// scene named `a#b` or `50%` still finds its images.
///
/// ```
/// use cssm_lab::report::compare_html::url_path;
/// assert_eq!(url_path("images/a#b/x y.png"), "images/a%23b/x%20y.png");
/// ```
pub fn url_path(path: &str) -> String {
    let mut s = String::with_capacity(path.len());
    for b in path.bytes() {
        match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'.' | b'_' | b'~' | b'/' => {
                s.push(b as char)
            }
            b => s += &format!("%{b:02X}"),
        }
    }
    s
}

fn img(src: &str, alt: &str, width: u32, height: u32) -> String {
    let k = scale(width);
    format!(
        "<img src=\"{}\" alt=\"{}\" width=\"{}\" height=\"{}\">",
        url_path(src),
        escape(alt),
        width * k,
        height * k
    )
}

fn figures_table(r: &CompareReport) -> String {
    let mut s = String::from(
        "<table class=\"figures\" id=\"figures\"><thead><tr>\
         <th>scene</th><th>method</th>\
         <th title=\"relative RMSE of the indirect light against the converged image\">indirect RMSE</th>\
         <th title=\"as measured against the reference\">measured</th>\
         <th title=\"share of the measured squared error that is the reference's noise\">noise</th>\
         <th>indirect FLIP</th><th>indirect bias</th>\
         <th title=\"light where the reference is dark, relative to the reference there\">indirect leak</th>\
         <th>full RMSE</th><th>full FLIP</th>\
         <th>GPU ms (frame)</th><th>GPU ms (prepare)</th><th>memory MiB</th><th>wall s</th>\
         </tr></thead><tbody>\n",
    );
    for scene in &r.scenes {
        for m in &scene.methods {
            let _ = write!(
                s,
                "<tr><td class=\"name\">{}</td><td class=\"name\">{}</td>",
                escape(&scene.name),
                escape(&m.spec)
            );
            match &m.measured {
                Some(x) => {
                    let (i, f) = (&x.figures.indirect, &x.figures.full);
                    s += &number_td(
                        i.relative_rmse_without_noise,
                        fixed(i.relative_rmse_without_noise, 3),
                    );
                    s += &number_td(i.relative_rmse, fixed(i.relative_rmse, 3));
                    s += &number_td(
                        i.noise_share,
                        i.noise_share
                            .map_or("–".into(), |n| format!("{:.0}%", 100.0 * n)),
                    );
                    s += &number_td(Some(i.mean_flip.into()), flip_cell(i));
                    s += &number_td(i.bias, bias_cell(i));
                    s += &number_td(i.leak, fixed(i.leak, 3));
                    s += &number_td(
                        f.relative_rmse_without_noise,
                        fixed(f.relative_rmse_without_noise, 3),
                    );
                    s += &number_td(Some(f.mean_flip.into()), format!("{:.3}", f.mean_flip));
                    s += &number_td(x.gpu_frame_ms, fixed(x.gpu_frame_ms, 2));
                    s += &number_td(x.gpu_prepare_ms, fixed(x.gpu_prepare_ms, 2));
                    s += &number_td(x.memory_bytes.map(|b| b as f64), mebibytes(x.memory_bytes));
                    s += &number_td(Some(x.seconds), format!("{:.2}", x.seconds));
                }
                None => {
                    let _ = write!(
                        s,
                        "<td class=\"name failed\" data-value=\"\" colspan=\"12\">failed: {}</td>",
                        escape(m.error.as_deref().unwrap_or("no figures"))
                    );
                }
            }
            s += "</tr>\n";
        }
    }
    s += "</tbody></table>\n";
    s
}

fn figures_caption(f: &ComponentFigures) -> String {
    format!(
        "RMSE {} · FLIP {} · bias {}",
        rmse_cell(f),
        flip_cell(f),
        bias_cell(f)
    )
}

fn method_row(r: &CompareReport, m: &MethodComparison) -> String {
    let (w, h) = (r.settings.width, r.settings.height);
    let mut s = format!("<tr><th>{}", escape(&m.spec));
    let Some(x) = &m.measured else {
        let _ = writeln!(
            s,
            "</th><td colspan=\"3\" class=\"failed\">failed: {}</td></tr>",
            escape(m.error.as_deref().unwrap_or("no figures"))
        );
        return s;
    };
    let _ = write!(
        s,
        "<br>{} ms frame, {} ms prepare, {} MiB<details><summary>GPU ms per pass</summary><table>",
        fixed(x.gpu_frame_ms, 2),
        fixed(x.gpu_prepare_ms, 2),
        mebibytes(x.memory_bytes)
    );
    for p in &x.passes {
        let _ = write!(
            s,
            "<tr><td>{}{}</td><td>{:.3}</td></tr>",
            escape(&p.name),
            if p.prepare { " (prepare)" } else { "" },
            p.ms
        );
    }
    if x.passes.is_empty() {
        s += "<tr><td>no timestamp queries</td></tr>";
    }
    s += "</table></details></th>";
    let cells = [
        (&x.images.full, "full", figures_caption(&x.figures.full)),
        (
            &x.images.indirect,
            "indirect",
            figures_caption(&x.figures.indirect),
        ),
        (
            &x.images.indirect_error,
            "indirect FLIP error",
            format!("mean {:.3}", x.figures.indirect.mean_flip),
        ),
    ];
    for (src, what, caption) in cells {
        let _ = write!(
            s,
            "<td>{}{}</td>",
            img(src, &format!("{} {what}", m.spec), w, h),
            escape(&caption)
        );
    }
    s += "</tr>\n";
    s
}

fn scene_grid(r: &CompareReport, scene: &SceneComparison) -> String {
    let (w, h) = (r.settings.width, r.settings.height);
    let mut s = format!(
        "<h2 id=\"scene-{0}\">{0}</h2>\n<table class=\"grid\"><thead><tr><th></th><th>full</th>\
         <th>indirect</th><th>indirect: FLIP error against the reference (black: none, yellow: \
         most)</th></tr></thead><tbody>\n",
        escape(&scene.name)
    );
    let reference = &scene.reference;
    let noise = |e: &compare::ReferenceEntry| {
        format!(
            "noise floor {} · FLIP floor {}{}",
            fixed(e.noise_floor, 3),
            fixed(e.flip_floor.map(f64::from), 3),
            if e.cached {
                " · cached".to_string()
            } else {
                format!(" · {:.1} s", e.seconds)
            }
        )
    };
    let _ = writeln!(
        s,
        "<tr><th>reference<br>{} paths per pixel</th><td>{}{}</td><td>{}{}</td><td></td></tr>",
        r.settings.samples,
        img(&reference.full.image, "reference full", w, h),
        escape(&noise(&reference.full)),
        img(&reference.indirect.image, "reference indirect", w, h),
        escape(&noise(&reference.indirect)),
    );
    for m in compare::ranked(scene) {
        s += &method_row(r, m);
    }
    s += "</tbody></table>\n";
    s
}

/// `index.html`: the page, its images and `chart.svg` referenced by relative paths.
pub fn html(r: &CompareReport) -> String {
    let mut s = String::from(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>cssm compare</title>\n<style>",
    );
    s += STYLE;
    s += "</style></head><body>\n<h1>Every method against the path tracer</h1>\n";
    let _ = writeln!(
        s,
        "<p class=\"meta\"><code>{}</code><br>Commit {}; {}; GPU methods on {}.<br>{}. Took {:.0} s.</p>",
        escape(&r.command),
        escape(&r.commit),
        escape(&r.machine),
        escape(r.device.as_deref().unwrap_or("no GPU (none ran)")),
        escape(&compare::settings_line(&r.settings)),
        r.seconds
    );
    let _ = writeln!(
        s,
        "<p>Scenes: {}.</p>",
        r.scenes
            .iter()
            .map(|sc| format!("<a href=\"#scene-{0}\">{0}</a>", escape(&sc.name)))
            .collect::<Vec<_>>()
            .join(", ")
    );
    s += "<h2>Error against time</h2>\n<p><img src=\"chart.svg\" alt=\"relative RMSE of the \
          indirect light against GPU milliseconds per frame\" width=\"900\" height=\"500\"></p>\n";
    s += "<h2>Every figure</h2>\n<p class=\"note\">Click a column to sort by it.</p>\n";
    s += &figures_table(r);
    let _ = writeln!(s, "<p class=\"note\">{}</p>", definitions_html());
    for scene in &r.scenes {
        s += &scene_grid(r, scene);
    }
    s += "<p class=\"note\">The same figures: <a href=\"compare.csv\">compare.csv</a>, \
          <a href=\"compare.json\">compare.json</a>, <a href=\"compare.md\">compare.md</a>.</p>\n";
    s += "<script>";
    s += SCRIPT;
    s += "</script>\n</body></html>\n";
    s
}

const PALETTE: [RGBColor; 10] = [
    RGBColor(0x1f, 0x77, 0xb4),
    RGBColor(0xff, 0x7f, 0x0e),
    RGBColor(0x2c, 0xa0, 0x2c),
    RGBColor(0xd6, 0x27, 0x28),
    RGBColor(0x94, 0x67, 0xbd),
    RGBColor(0x8c, 0x56, 0x4b),
    RGBColor(0xe3, 0x77, 0xc2),
    RGBColor(0x7f, 0x7f, 0x7f),
    RGBColor(0xbc, 0xbd, 0x22),
    RGBColor(0x17, 0xbe, 0xcf),
];

/// A point of the chart: method (colour), scene (marker), GPU ms, relative RMSE.
struct Point<'a> {
    spec: &'a str,
    scene: usize,
    ms: f64,
    rmse: f64,
}

/// `chart.svg`: per scene and method its indirect light's relative RMSE without the
/// reference's noise against its GPU milliseconds per frame (log scale); one colour per method,
/// one marker per scene.
///
/// # Errors
/// plotters' message when drawing fails.
pub fn chart_svg(r: &CompareReport) -> Result<String, String> {
    let mut specs: Vec<&str> = Vec::new();
    let mut points = Vec::new();
    for (i, scene) in r.scenes.iter().enumerate() {
        for m in &scene.methods {
            let Some(x) = &m.measured else { continue };
            if let (Some(ms), Some(rmse)) = (
                x.gpu_frame_ms,
                x.figures.indirect.relative_rmse_without_noise,
            ) && ms > 0.0
            {
                if !specs.contains(&m.spec.as_str()) {
                    specs.push(&m.spec);
                }
                points.push(Point {
                    spec: &m.spec,
                    scene: i,
                    ms,
                    rmse,
                });
            }
        }
    }
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, (900, 500)).into_drawing_area();
        let err = |e: DrawingAreaErrorKind<std::io::Error>| e.to_string();
        root.fill(&WHITE).map_err(err)?;
        let (lo, hi) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
            (a.min(p.ms), b.max(p.ms))
        });
        let (lo, hi) = if points.is_empty() {
            (0.1, 10.0)
        } else {
            (lo / 2.0, hi * 2.0)
        };
        let top = points.iter().map(|p| p.rmse).fold(0.5f64, f64::max) * 1.1;
        let caption = if points.is_empty() {
            "no GPU timings (no timestamp queries) or no figures".to_string()
        } else {
            format!(
                "indirect light: error against GPU time per frame ({})",
                r.device.as_deref().unwrap_or("no GPU")
            )
        };
        // The caption across the top, the legends in a column of their own on the right, so
        // that they never hide a point.
        let body = root.titled(&caption, ("sans-serif", 16)).map_err(err)?;
        let (plot, side) = body.split_horizontally(720);
        let mut chart = ChartBuilder::on(&plot)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(56)
            .build_cartesian_2d((lo..hi).log_scale(), 0.0..top)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("GPU milliseconds per frame (log scale)")
            .y_desc("relative RMSE without the reference's noise")
            .light_line_style(WHITE)
            .draw()
            .map_err(err)?;
        for (k, spec) in specs.iter().enumerate() {
            let c = PALETTE[k % PALETTE.len()];
            let at = |shape: usize| {
                points
                    .iter()
                    .filter(move |p| p.spec == *spec && p.scene % 4 == shape)
                    .map(|p| (p.ms, p.rmse))
            };
            chart
                .draw_series(at(0).map(|p| Circle::new(p, 5, c.filled())))
                .map_err(err)?;
            chart
                .draw_series(at(1).map(|p| TriangleMarker::new(p, 6, c.filled())))
                .map_err(err)?;
            chart
                .draw_series(at(2).map(|p| Cross::new(p, 5, c.stroke_width(2))))
                .map_err(err)?;
            chart
                .draw_series(
                    at(3).map(|p| {
                        EmptyElement::at(p) + Rectangle::new([(-4, -4), (4, 4)], c.filled())
                    }),
                )
                .map_err(err)?;
        }
        let font = ("sans-serif", 12);
        let mut y = 16;
        if !specs.is_empty() {
            side.draw(&Text::new("methods (colour)", (8, y), font))
                .map_err(err)?;
            for (k, spec) in specs.iter().enumerate() {
                y += 18;
                let c = PALETTE[k % PALETTE.len()];
                side.draw(&Circle::new((14, y + 6), 5, c.filled()))
                    .map_err(err)?;
                side.draw(&Text::new(spec.to_string(), (26, y), font))
                    .map_err(err)?;
            }
            y += 36;
        }
        side.draw(&Text::new("scenes (marker)", (8, y), font))
            .map_err(err)?;
        for (i, scene) in r.scenes.iter().enumerate() {
            y += 18;
            let at = (14, y + 6);
            match i % 4 {
                0 => side.draw(&Circle::new(at, 5, BLACK.filled())),
                1 => side.draw(&TriangleMarker::new(at, 6, BLACK.filled())),
                2 => side.draw(&Cross::new(at, 5, BLACK.stroke_width(2))),
                _ => side.draw(&Rectangle::new([(10, y + 2), (18, y + 10)], BLACK.filled())),
            }
            .map_err(err)?;
            side.draw(&Text::new(scene.name.clone(), (26, y), font))
                .map_err(err)?;
        }
        root.present().map_err(err)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::compare::tests::report;

    #[test]
    fn the_page_escapes_and_links_every_image() {
        let r = report();
        let page = html(&r);
        assert!(page.contains("box &lt;1&gt;"), "scene names are escaped");
        assert!(
            page.contains("src=\"images/box/lightcuts%3Abounces%3D1%2Cjitter%3Dtrue-full.png\""),
            "paths are URL-encoded"
        );
        assert!(!page.contains("box <1>"));
        for src in [
            "chart.svg",
            "images/box/reference-full.png",
            "images/box/reference-indirect.png",
            "images/box/rsm-full.png",
            "images/box/rsm-indirect-error.png",
        ] {
            assert!(page.contains(&format!("src=\"{src}\"")), "{src}");
        }
        // One row per method in the table, the failed one saying why; the definitions with
        // their code spans.
        assert_eq!(
            page.matches("<tr><td class=\"name\">box &lt;1&gt;</td>")
                .count(),
            3
        );
        assert!(page.contains("failed: the atlas does not fit"));
        assert!(page.contains("<code>sqrt(max(0, e^2 - f^2))</code>"));
        assert!(page.contains("data-value=\"0.4\""));
        // 16 pixels wide shown 15 times as large.
        assert!(page.contains("width=\"240\" height=\"180\""));
    }

    #[test]
    fn the_chart_has_a_point_per_timed_method() {
        let svg = chart_svg(&report()).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..80]);
        assert!(svg.contains("rsm") && svg.contains("lightcuts:bounces=1,jitter=true"));
        // The scene's marker is named, escaped as XML.
        assert!(svg.contains("box &lt;1&gt;"), "{svg}");
    }
}
