//! The files of `cssm report error` beside the images: `error.md` (the table and what it
//! measured), `error.csv` (one line per figure row), the reference's sidecar
//! (`SCENE-reference.json`, what `--reference-cache` compares), the variants' file names and
//! the side-by-side strip. The figures themselves are [`super::error`].

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::error::Figures;

/// One variant on one scene.
#[derive(Clone, Debug)]
pub struct ErrorRow {
    /// `Scene::name`.
    pub scene: String,
    /// The method spec (`lightcuts:bounces=2`).
    pub spec: String,
    /// Its figures, or why it has none.
    pub outcome: Result<Measured, String>,
}

/// What a variant's render measured.
#[derive(Clone, Copy, Debug)]
pub struct Measured {
    /// Its error against the reference.
    pub figures: Figures,
    /// GPU milliseconds of its frame: the passes every frame runs (G-buffer, direct light, the
    /// method's frame passes, compose, tone mapping), by timestamp queries in a frame after the
    /// image's; `None` on the CPU or without timestamp queries.
    pub gpu_ms: Option<f64>,
    /// GPU milliseconds of the passes that run before the first frame and after a light moves
    /// (shadow maps, radiosity over the atlas).
    pub gpu_prepare_ms: Option<f64>,
    /// Wall-clock seconds of its render (renderer set-up, frames and read-back; not the bake).
    pub seconds: f64,
    /// Whether it ran on the GPU ([`ErrorReport::device`]) rather than the CPU.
    pub on_gpu: bool,
}

/// The reference of one scene.
#[derive(Clone, Debug)]
pub struct SceneReference {
    /// `Scene::name`.
    pub scene: String,
    /// Its noise floor ([`super::error::noise_floor`]).
    pub noise_floor: Option<f64>,
    /// Its noise in mean FLIP ([`super::error::ReferenceNoise::flip`]).
    pub flip_floor: Option<f32>,
    /// Its noise in the bias ([`super::error::ReferenceNoise::bias`]).
    pub bias_noise: Option<f64>,
    /// Seconds it took to path trace (when it was not cached).
    pub seconds: f64,
    /// Whether it came from `--reference-cache`.
    pub cached: bool,
}

/// Everything `error.md` and `error.csv` say.
#[derive(Clone, Debug)]
pub struct ErrorReport {
    /// The command line that made it.
    pub command: String,
    /// The checkout's commit.
    pub commit: String,
    /// CPU, cores, memory.
    pub machine: String,
    /// The GPU adapter the GPU methods ran on; `None` when none did.
    pub device: Option<String>,
    /// Size, samples, bounces, component, exposure, shadow maps, bake, as one line.
    pub settings: String,
    /// One per scene, in order.
    pub references: Vec<SceneReference>,
    /// Scene by scene, variant by variant.
    pub rows: Vec<ErrorRow>,
    /// Wall-clock seconds of the whole run.
    pub seconds: f64,
}

/// The name a variant's files take: the spec with `:`, `=` and `,` replaced by `-`; a spec that
/// would take a name of the report's own files (`reference`, `strip`) gets `-method` after it.
///
/// ```
/// use cssm_lab::report::error_write::file_stem;
/// assert_eq!(file_stem("lightcuts:bounces=2,jitter=true"), "lightcuts-bounces-2-jitter-true");
/// assert_eq!(file_stem("reference"), "reference-method");
/// ```
pub fn file_stem(spec: &str) -> String {
    let stem: String = spec
        .chars()
        .map(|c| match c {
            ':' | '=' | ',' => '-',
            '/' | '\\' | ' ' => '_',
            c => c,
        })
        .collect();
    // Control characters and leading dots as for any file name.
    let stem = cssm_formats::files::safe_file_stem(&stem);
    if stem == "reference" || stem == "strip" {
        format!("{stem}-method")
    } else {
        stem
    }
}

/// Gap between the images of the strip, in pixels (mid grey).
pub const STRIP_GAP: u32 = 2;

/// The RGBA8 images (each `width` x `height`) side by side, left to right, [`STRIP_GAP`] grey
/// pixels apart; returns the strip's width and its pixels.
///
/// # Panics
/// When an image is not `width * height * 4` bytes.
pub fn strip(width: u32, height: u32, images: &[&[u8]]) -> (u32, Vec<u8>) {
    let n = images.len() as u32;
    let total = if n == 0 {
        0
    } else {
        n * width + (n - 1) * STRIP_GAP
    };
    let mut out = vec![128u8; (total * height * 4) as usize];
    for p in out.chunks_exact_mut(4) {
        p[3] = 255;
    }
    for (i, image) in images.iter().enumerate() {
        assert_eq!(image.len(), (width * height * 4) as usize, "image {i}");
        let x0 = i as u32 * (width + STRIP_GAP);
        for y in 0..height {
            let src = (y * width * 4) as usize;
            let dst = ((y * total + x0) * 4) as usize;
            out[dst..dst + (width * 4) as usize]
                .copy_from_slice(&image[src..src + (width * 4) as usize]);
        }
    }
    (total, out)
}

/// What the reference was rendered from, stored beside its EXR: `--reference-cache` reuses
/// the EXR only when these are all the same.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceSettings {
    /// Version of cssm that path traced it.
    pub cssm_version: String,
    /// The path tracer's light model (`cssm_runtime::reference::LIGHT_MODEL`): a sidecar
    /// from before emitters were area lights has none, and its reference is rendered anew.
    pub light_model: u32,
    /// `Scene::name`.
    pub scene: String,
    /// `Scene::content_hash` in hex: every file of the scene.
    pub content_hash: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Paths per pixel in all.
    pub samples: u32,
    /// Indirect bounces.
    pub bounces: u32,
    /// `direct`, `indirect` or `full`.
    pub component: String,
    /// Seeds of the two halves.
    pub seeds: [u64; 2],
    /// Paths per pixel of each half.
    pub halves: [u32; 2],
}

/// `SCENE-reference.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceSidecar {
    /// What it was rendered from.
    pub settings: ReferenceSettings,
    /// Its noise floor.
    pub noise_floor: Option<f64>,
    /// Its noise in mean FLIP (absent in sidecars of cssm before `cssm compare`).
    #[serde(default)]
    pub flip_floor: Option<f32>,
    /// Its noise in the bias (absent in sidecars of cssm before `cssm compare`).
    #[serde(default)]
    pub bias_noise: Option<f64>,
    /// Seconds the path tracing took.
    pub seconds: f64,
}

fn figure(v: Option<f64>) -> String {
    v.map_or("–".into(), |v| format!("{v:.4}"))
}

fn signed(v: Option<f64>) -> String {
    v.map_or("–".into(), |v| format!("{v:+.4}"))
}

fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}

/// The Markdown table: per scene the reference's noise floor, then one line per variant.
pub fn table(r: &ErrorReport) -> String {
    let mut s = String::new();
    s += "| scene | method | relative RMSE | bias | leak | mask pixels | mean FLIP | GPU ms (frame) | time |\n";
    s += "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    for reference in &r.references {
        let time = if reference.cached {
            "cached".to_string()
        } else {
            format!("{:.1} s", reference.seconds)
        };
        let _ = writeln!(
            s,
            "| {} | *reference noise floor* | {} | – | – | – | – | – | {time} |",
            cell(&reference.scene),
            figure(reference.noise_floor)
        );
        for row in r.rows.iter().filter(|row| row.scene == reference.scene) {
            let (scene, spec) = (cell(&row.scene), cell(&row.spec));
            match &row.outcome {
                Ok(m) => {
                    let f = &m.figures;
                    let _ = writeln!(
                        s,
                        "| {scene} | {spec} | {} | {} | {} | {} | {:.4} | {} | {:.1} s |",
                        figure(f.relative_rmse),
                        signed(f.bias),
                        figure(f.leak.leak),
                        f.leak.mask_pixels,
                        f.mean_flip,
                        m.gpu_ms.map_or("–".into(), |ms| format!("{ms:.2}")),
                        m.seconds
                    );
                }
                Err(e) => {
                    let _ = writeln!(
                        s,
                        "| {scene} | {spec} | failed: {} | | | | | | |",
                        cell(&e.replace('\n', " "))
                    );
                }
            }
        }
    }
    s
}

/// `error.md`: what was measured and how, then [`table`].
pub fn markdown(r: &ErrorReport) -> String {
    let mut s = String::new();
    s += "# Error against the reference path tracer\n\n";
    let _ = writeln!(s, "`{}`", r.command);
    let _ = writeln!(
        s,
        "\nCommit {}; {}; GPU methods on {}. {}. Took {:.1} s.\n",
        r.commit,
        r.machine,
        r.device.as_deref().unwrap_or("no GPU (none ran)"),
        r.settings,
        r.seconds
    );
    s += "Every figure is over every pixel, against the reference path tracer's image (the mean \
          of two independent halves of its paths). *Relative RMSE*: `sqrt(sum |m - r|^2 / sum \
          |r|^2)` over rgb. *Bias*: `sum lum(m) / sum lum(r) - 1` (Rec. 709 luminance). *Leak*: \
          over the mask of pixels whose reference luminance is below half the median of the \
          nonzero ones (*mask pixels*), `sum max(0, lum(m) - lum(r)) / sum lum(r)`: light where \
          the ground truth is dark. *Mean FLIP*: of the tone-mapped 8-bit images. The *noise \
          floor* is the reference's own relative RMSE against the converged image, estimated \
          from its two halves: a method equal to the converged image would measure about this, \
          `--method reference` with as many paths about 1.4 times it; the leak has a floor of \
          its own in noise (the `reference` row shows it). *GPU ms*: the passes every frame \
          runs, by timestamp queries in a frame after the image's (warm), without those that run \
          before the first frame and when a light moves (shadow maps, radiosity: \
          `gpu_prepare_ms` in the CSV), on the device named above (on lavapipe, a CPU \
          emulation, these times say nothing about a GPU). *Time*: wall clock of the render \
          (the reference: its path tracing).\n\n";
    s += &table(r);
    s
}

fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

fn opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| format!("{v}"))
}

/// `error.csv`: a line per scene for the noise floor (method `reference-noise-floor`) and per
/// variant; empty fields where a figure does not apply.
pub fn csv(r: &ErrorReport) -> String {
    let mut s = String::from(
        "scene,method,relative_rmse,bias,leak,leak_mask_pixels,mean_flip,gpu_ms,gpu_prepare_ms,seconds,device,error\n",
    );
    let device = csv_field(r.device.as_deref().unwrap_or(""));
    for reference in &r.references {
        let _ = writeln!(
            s,
            "{},reference-noise-floor,{},,,,,,,{},cpu,",
            csv_field(&reference.scene),
            opt(reference.noise_floor),
            if reference.cached {
                String::new()
            } else {
                format!("{:.3}", reference.seconds)
            }
        );
        for row in r.rows.iter().filter(|row| row.scene == reference.scene) {
            let (scene, spec) = (csv_field(&row.scene), csv_field(&row.spec));
            match &row.outcome {
                Ok(m) => {
                    let f = &m.figures;
                    let _ = writeln!(
                        s,
                        "{scene},{spec},{},{},{},{},{},{},{},{:.3},{},",
                        opt(f.relative_rmse),
                        opt(f.bias),
                        opt(f.leak.leak),
                        f.leak.mask_pixels,
                        f.mean_flip,
                        opt(m.gpu_ms),
                        opt(m.gpu_prepare_ms),
                        m.seconds,
                        if m.on_gpu { device.as_str() } else { "cpu" }
                    );
                }
                Err(e) => {
                    let _ = writeln!(s, "{scene},{spec},,,,,,,,,,{}", csv_field(e));
                }
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::error::{Figures, Leak};

    fn report() -> ErrorReport {
        let figures = Figures {
            relative_rmse: Some(0.25),
            bias: Some(-0.1),
            leak: Leak {
                leak: Some(0.5),
                mask_pixels: 12,
            },
            mean_flip: 0.125,
        };
        ErrorReport {
            command: "cssm report error".into(),
            commit: "abc".into(),
            machine: "a CPU".into(),
            device: Some("llvmpipe (Vulkan)".into()),
            settings: "16x12".into(),
            references: vec![SceneReference {
                scene: "box".into(),
                noise_floor: Some(0.05),
                flip_floor: Some(0.01),
                bias_noise: Some(0.002),
                seconds: 1.0,
                cached: false,
            }],
            rows: vec![
                ErrorRow {
                    scene: "box".into(),
                    spec: "lightcuts:bounces=2,jitter=true".into(),
                    outcome: Ok(Measured {
                        figures,
                        gpu_ms: Some(1.5),
                        gpu_prepare_ms: Some(3.0),
                        seconds: 0.5,
                        on_gpu: true,
                    }),
                },
                ErrorRow {
                    scene: "box".into(),
                    spec: "hrc".into(),
                    outcome: Err("the atlas does not fit".into()),
                },
            ],
            seconds: 3.0,
        }
    }

    #[test]
    fn table_and_csv_have_a_line_per_row() {
        let r = report();
        let md = markdown(&r);
        assert!(
            md.contains("| box | *reference noise floor* | 0.0500 |"),
            "{md}"
        );
        assert!(
            md.contains(
                "| box | lightcuts:bounces=2,jitter=true | 0.2500 | -0.1000 | 0.5000 | 12 | 0.1250 | 1.50 | 0.5 s |"
            ),
            "{md}"
        );
        assert!(md.contains("failed: the atlas does not fit"), "{md}");
        let csv = csv(&r);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 4, "{csv}");
        assert!(
            lines[2].starts_with(
                "box,\"lightcuts:bounces=2,jitter=true\",0.25,-0.1,0.5,12,0.125,1.5,3,"
            ),
            "{csv}"
        );
        assert!(lines[3].ends_with(",the atlas does not fit"), "{csv}");
    }

    #[test]
    fn strip_puts_images_side_by_side() {
        let a = vec![10u8; 2 * 2 * 4];
        let b = vec![200u8; 2 * 2 * 4];
        let (w, s) = strip(2, 2, &[&a, &b]);
        assert_eq!(w, 2 + STRIP_GAP + 2);
        assert_eq!(s.len(), (w * 2 * 4) as usize);
        let px = |x: u32, y: u32| s[((y * w + x) * 4) as usize];
        assert_eq!(px(1, 1), 10);
        assert_eq!(px(2, 0), 128);
        assert_eq!(px(w - 1, 1), 200);
    }

    #[test]
    fn file_stems() {
        assert_eq!(file_stem("rsm:visibility=none"), "rsm-visibility-none");
        assert_eq!(file_stem("direct"), "direct");
        assert_eq!(file_stem("strip"), "strip-method");
    }
}
