//! The data of `cssm compare`: every method on every scene, with its error against the path
//! tracer in the full image and in the indirect light alone, the reference's own noise taken
//! out ([`super::error::without_noise`]), its GPU time per pass and its GPU memory; and the
//! files made of it that are not the page ([`csv`], [`json`], [`markdown`]; the page is
//! [`super::compare_html`]).

use std::fmt::Write as _;

use serde::Serialize;

use super::error::{self, Figures};
use super::error_write::SceneReference;

/// Everything `cssm compare` measured.
#[derive(Clone, Debug, Serialize)]
pub struct CompareReport {
    /// The command line that made it.
    pub command: String,
    /// The checkout's commit.
    pub commit: String,
    /// CPU, cores, memory.
    pub machine: String,
    /// The GPU adapter the GPU methods ran on; `None` when none did.
    pub device: Option<String>,
    /// What every image was rendered with.
    pub settings: CompareSettings,
    /// Scene by scene.
    pub scenes: Vec<SceneComparison>,
    /// Wall-clock seconds of the whole run.
    pub seconds: f64,
}

/// What every image was rendered with.
#[derive(Clone, Debug, Serialize)]
pub struct CompareSettings {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Paths per pixel of the reference.
    pub samples: u32,
    /// Indirect bounces of the reference and of every method with a `bounces` option.
    pub bounces: u32,
    /// Frames each GPU method rendered, the camera at rest, before its image was read.
    pub frames: u32,
    /// Exposure of the tone-mapped images, in stops.
    pub exposure_stops: f32,
    /// Shadow-map resolution.
    pub shadow_resolution: u32,
    /// Atlas resolution of the `.cssm` baked for the methods that need one.
    pub atlas: u32,
    /// Cube-map face resolution of that bake.
    pub cube: u32,
}

/// A pair of things, one of the full image and one of its indirect light.
#[derive(Clone, Debug, Serialize)]
pub struct Components<T> {
    /// Of the full image (direct and indirect light).
    pub full: T,
    /// Of the indirect light alone.
    pub indirect: T,
}

/// One scene: its reference and every method.
#[derive(Clone, Debug, Serialize)]
pub struct SceneComparison {
    /// `Scene::name`.
    pub name: String,
    /// The reference of each component.
    pub reference: Components<ReferenceEntry>,
    /// Every method, in the order given.
    pub methods: Vec<MethodComparison>,
}

/// The reference of one component of one scene.
#[derive(Clone, Debug, Serialize)]
pub struct ReferenceEntry {
    /// Its noise floor: its own relative RMSE against the converged image.
    pub noise_floor: Option<f64>,
    /// Its noise in mean FLIP.
    pub flip_floor: Option<f32>,
    /// Its noise in the bias.
    pub bias_noise: Option<f64>,
    /// Seconds its path tracing took (when it was path traced in this run or cached from one).
    pub seconds: f64,
    /// Whether it came from the cache.
    pub cached: bool,
    /// Its tone-mapped image, relative to the report's directory.
    pub image: String,
}

impl ReferenceEntry {
    /// The entry of `reference`, whose image is `image`.
    pub fn new(reference: &SceneReference, image: String) -> Self {
        Self {
            noise_floor: reference.noise_floor,
            flip_floor: reference.flip_floor,
            bias_noise: reference.bias_noise,
            seconds: reference.seconds,
            cached: reference.cached,
            image,
        }
    }
}

/// One method on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct MethodComparison {
    /// The spec as given (`lightcuts:bounces=2`).
    pub spec: String,
    /// The method's name in the table.
    pub method: String,
    /// Whether it runs on the GPU.
    pub on_gpu: bool,
    /// Why it has no figures (a failed bake, a device limit), or `None`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// What it measured, or `None` when it failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub measured: Option<MethodMeasured>,
}

/// One pass's GPU milliseconds in a warm frame of a method (one after its image, a light set again so that every pass runs).
#[derive(Clone, Debug, Serialize)]
pub struct PassTime {
    /// The pass's name (`gbuffer`, `rsm gather`, ...).
    pub name: String,
    /// Whether it runs before the first frame and again only when a light or an object moves
    /// (shadow maps, radiosity over the atlas), rather than every frame.
    pub prepare: bool,
    /// GPU milliseconds, by timestamp queries.
    pub ms: f64,
}

/// What one method measured on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct MethodMeasured {
    /// Its figures against the reference of each component.
    pub figures: Components<ComponentFigures>,
    /// GPU milliseconds of the passes every frame runs (of the full image's render).
    pub gpu_frame_ms: Option<f64>,
    /// GPU milliseconds of the passes before the first frame (shadow maps, radiosity).
    pub gpu_prepare_ms: Option<f64>,
    /// Every pass of that frame.
    pub passes: Vec<PassTime>,
    /// Bytes of GPU memory its renderer held (buffers and textures, the G-buffer and the
    /// scene's own included), as wgpu's allocator counts them.
    pub memory_bytes: Option<u64>,
    /// Wall-clock seconds of its render of the full image (set-up, frames, read-back).
    pub seconds: f64,
    /// Its tone-mapped images and its indirect light's FLIP error map, relative to the
    /// report's directory.
    pub images: MethodImages,
}

/// A method's images, relative to the report's directory.
#[derive(Clone, Debug, Serialize)]
pub struct MethodImages {
    /// The full image.
    pub full: String,
    /// The indirect light alone.
    pub indirect: String,
    /// The FLIP error map of the indirect light against the reference's.
    pub indirect_error: String,
}

/// A method's figures against one component's reference, with the reference's noise beside
/// them.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ComponentFigures {
    /// Relative RMSE against the reference as measured.
    pub relative_rmse: Option<f64>,
    /// Relative RMSE against the converged image: the reference's noise taken out
    /// ([`error::without_noise`]).
    pub relative_rmse_without_noise: Option<f64>,
    /// The share of the measured squared error that is the reference's noise
    /// ([`error::noise_share`]).
    pub noise_share: Option<f64>,
    /// Mean bias.
    pub bias: Option<f64>,
    /// The reference's own noise in the bias, one standard deviation.
    pub bias_noise: Option<f64>,
    /// Light where the ground truth is dark.
    pub leak: Option<f64>,
    /// Mean FLIP of the tone-mapped images.
    pub mean_flip: f32,
    /// The reference's own noise in mean FLIP.
    pub flip_floor: Option<f32>,
}

impl ComponentFigures {
    /// `figures` against a reference of noise `reference`.
    pub fn new(figures: &Figures, reference: &ReferenceEntry) -> Self {
        Self {
            relative_rmse: figures.relative_rmse,
            relative_rmse_without_noise: error::without_noise(
                figures.relative_rmse,
                reference.noise_floor,
            ),
            noise_share: error::noise_share(figures.relative_rmse, reference.noise_floor),
            bias: figures.bias,
            bias_noise: reference.bias_noise,
            leak: figures.leak.leak,
            mean_flip: figures.mean_flip,
            flip_floor: reference.flip_floor,
        }
    }
}

/// A number with `digits` decimals, or "–".
pub fn fixed(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |v| format!("{v:.digits$}"))
}

/// Mebibytes with one decimal, or "–".
pub fn mebibytes(bytes: Option<u64>) -> String {
    bytes.map_or("–".into(), |b| {
        format!("{:.1}", b as f64 / (1024.0 * 1024.0))
    })
}

/// `0.25 (0.30, 31% noise)`: the relative RMSE without the reference's noise, then as measured
/// and the noise's share of it.
pub fn rmse_cell(f: &ComponentFigures) -> String {
    match (f.relative_rmse_without_noise, f.relative_rmse) {
        (Some(clean), Some(raw)) => format!(
            "{clean:.3} ({raw:.3}, {:.0}% noise)",
            100.0 * f.noise_share.unwrap_or(0.0)
        ),
        (None, raw) => fixed(raw, 3),
        (Some(clean), None) => format!("{clean:.3}"),
    }
}

/// `-0.120 ± 0.0004`: the bias and the reference's noise in it (one more digit: at a thousand
/// paths per pixel it is small).
pub fn bias_cell(f: &ComponentFigures) -> String {
    match (f.bias, f.bias_noise) {
        (Some(b), Some(n)) => format!("{b:+.3} ± {n:.4}"),
        (b, _) => b.map_or("–".into(), |b| format!("{b:+.3}")),
    }
}

/// `0.081 (floor 0.012)`: mean FLIP and the reference's noise in it.
pub fn flip_cell(f: &ComponentFigures) -> String {
    match f.flip_floor {
        Some(floor) => format!("{:.3} (floor {floor:.3})", f.mean_flip),
        None => format!("{:.3}", f.mean_flip),
    }
}

fn md_cell(text: &str) -> String {
    text.replace('|', "\\|").replace('\n', " ")
}

/// The methods of a scene that measured, by their indirect light's relative RMSE without noise
/// (smallest first), then those that failed.
pub fn ranked(scene: &SceneComparison) -> Vec<&MethodComparison> {
    let mut methods: Vec<&MethodComparison> = scene.methods.iter().collect();
    let key = |m: &MethodComparison| {
        m.measured
            .as_ref()
            .and_then(|m| m.figures.indirect.relative_rmse_without_noise)
            .unwrap_or(f64::INFINITY)
    };
    methods.sort_by(|a, b| key(a).total_cmp(&key(b)));
    methods
}

/// What the figures mean, as one paragraph of Markdown (also on the page).
pub const DEFINITIONS: &str = "Every figure is over every pixel, against the reference path \
    tracer's image (the mean of two independent halves of its paths), of the full image and of \
    the indirect light alone. *Relative RMSE*: `sqrt(sum |m - r|^2 / sum |r|^2)` over rgb; the \
    reference's own noise adds its square to the square of a method's error on average, so the \
    first figure is the error against the converged image, `sqrt(max(0, e^2 - f^2))` for the \
    measured `e` and the reference's noise floor `f` (estimated from its two halves), and the \
    brackets give the measured `e` and the share `f^2 / e^2` of it that is the reference's \
    noise. *Bias*: `sum lum(m) / sum lum(r) - 1`, ± one standard deviation of the reference's \
    own total. *FLIP*: mean FLIP (Andersson et al. 2020) of the tone-mapped images; its floor is \
    the FLIP of the reference against its first half, which differs from it as much as the \
    reference differs from the converged image. *GPU ms*: the passes every frame runs, by \
    timestamp queries in a frame after the image's, its pipelines warm (*prepare*: those before the first frame and after a light moves: \
    shadow maps, radiosity over the atlas); only a real GPU's milliseconds say anything about \
    speed (lavapipe is a CPU emulation). *Memory*: the GPU buffers and textures the method's \
    renderer holds (G-buffer and the scene's own included), as wgpu's allocator counts them.";

/// `compare.md`: per scene a table of every method, best first.
pub fn markdown(r: &CompareReport) -> String {
    let mut s = String::new();
    s += "# Every method against the path tracer\n\n";
    let _ = writeln!(s, "`{}`\n", r.command);
    let _ = writeln!(
        s,
        "Commit {}; {}; GPU methods on {}. {}. Took {:.0} s.\n",
        r.commit,
        r.machine,
        r.device.as_deref().unwrap_or("no GPU (none ran)"),
        settings_line(&r.settings),
        r.seconds
    );
    s += DEFINITIONS;
    s += "\n";
    for scene in &r.scenes {
        let _ = writeln!(s, "\n## {}\n", md_cell(&scene.name));
        let floor = |e: &ReferenceEntry| {
            format!(
                "noise floor {}, FLIP floor {}",
                fixed(e.noise_floor, 3),
                fixed(e.flip_floor.map(f64::from), 3)
            )
        };
        let _ = writeln!(
            s,
            "Reference: indirect {}; full {}.\n",
            floor(&scene.reference.indirect),
            floor(&scene.reference.full)
        );
        s += "| method | indirect: relative RMSE | FLIP | bias | full: relative RMSE | FLIP | GPU ms (frame) | prepare | memory MiB |\n";
        s += "| --- | --- | --- | --- | --- | --- | ---: | ---: | ---: |\n";
        for m in ranked(scene) {
            let spec = md_cell(&m.spec);
            match (&m.measured, &m.error) {
                (Some(x), _) => {
                    let (i, f) = (&x.figures.indirect, &x.figures.full);
                    let _ = writeln!(
                        s,
                        "| {spec} | {} | {} | {} | {} | {} | {} | {} | {} |",
                        rmse_cell(i),
                        flip_cell(i),
                        bias_cell(i),
                        rmse_cell(f),
                        flip_cell(f),
                        fixed(x.gpu_frame_ms, 2),
                        fixed(x.gpu_prepare_ms, 2),
                        mebibytes(x.memory_bytes)
                    );
                }
                (None, error) => {
                    let _ = writeln!(
                        s,
                        "| {spec} | failed: {} | | | | | | | |",
                        md_cell(error.as_deref().unwrap_or("no figures"))
                    );
                }
            }
        }
    }
    s
}

/// The settings as one line.
pub fn settings_line(s: &CompareSettings) -> String {
    format!(
        "{}x{}, reference {} paths per pixel, {} bounce(s), {} frame(s) per GPU method, exposure \
         {:+} stops, shadow maps {}, .cssm baked at atlas {}, cube {} where a method needs one",
        s.width,
        s.height,
        s.samples,
        s.bounces,
        s.frames,
        s.exposure_stops,
        s.shadow_resolution,
        s.atlas,
        s.cube
    )
}

fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map_or(String::new(), |v| v.to_string())
}

/// `compare.csv`: per scene and component a line for the reference's noise (method
/// `reference-noise-floor`) and one per method; empty fields where a figure does not apply.
pub fn csv(r: &CompareReport) -> String {
    let mut s = String::from(
        "scene,method,component,relative_rmse,relative_rmse_without_noise,noise_share,bias,\
         bias_noise,leak,mean_flip,flip_floor,gpu_frame_ms,gpu_prepare_ms,memory_bytes,seconds,\
         device,error\n",
    );
    let device = csv_field(r.device.as_deref().unwrap_or(""));
    for scene in &r.scenes {
        let name = csv_field(&scene.name);
        for (component, reference) in [
            ("full", &scene.reference.full),
            ("indirect", &scene.reference.indirect),
        ] {
            let _ = writeln!(
                s,
                "{name},reference-noise-floor,{component},{},,,,{},,,{},,,,{:.3},cpu,",
                opt(reference.noise_floor),
                opt(reference.bias_noise),
                opt(reference.flip_floor),
                reference.seconds
            );
            for m in &scene.methods {
                let spec = csv_field(&m.spec);
                match &m.measured {
                    Some(x) => {
                        let f = if component == "full" {
                            &x.figures.full
                        } else {
                            &x.figures.indirect
                        };
                        let _ = writeln!(
                            s,
                            "{name},{spec},{component},{},{},{},{},{},{},{},{},{},{},{},{:.3},{},",
                            opt(f.relative_rmse),
                            opt(f.relative_rmse_without_noise),
                            opt(f.noise_share),
                            opt(f.bias),
                            opt(f.bias_noise),
                            opt(f.leak),
                            f.mean_flip,
                            opt(f.flip_floor),
                            opt(x.gpu_frame_ms),
                            opt(x.gpu_prepare_ms),
                            opt(x.memory_bytes),
                            x.seconds,
                            if m.on_gpu { device.as_str() } else { "cpu" }
                        );
                    }
                    None => {
                        let _ = writeln!(
                            s,
                            "{name},{spec},{component},,,,,,,,,,,,,,{}",
                            csv_field(m.error.as_deref().unwrap_or("no figures"))
                        );
                    }
                }
            }
        }
    }
    s
}

/// `compare.json`: the whole report.
///
/// # Errors
/// Never in practice (every field serialises); the serialiser's message otherwise.
pub fn json(r: &CompareReport) -> Result<String, String> {
    serde_json::to_string_pretty(r)
        .map(|text| text + "\n")
        .map_err(|e| e.to_string())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::report::error::Leak;

    fn figures(rmse: f64, flip: f32) -> Figures {
        Figures {
            relative_rmse: Some(rmse),
            bias: Some(-0.1),
            leak: Leak {
                leak: Some(0.05),
                mask_pixels: 10,
            },
            mean_flip: flip,
        }
    }

    fn reference(image: &str) -> ReferenceEntry {
        ReferenceEntry {
            noise_floor: Some(0.3),
            flip_floor: Some(0.02),
            bias_noise: Some(0.01),
            seconds: 2.0,
            cached: false,
            image: image.into(),
        }
    }

    fn method(spec: &str, rmse: f64, ms: f64) -> MethodComparison {
        let r = reference("r.png");
        MethodComparison {
            spec: spec.into(),
            method: spec.split(':').next().unwrap().into(),
            on_gpu: true,
            error: None,
            measured: Some(MethodMeasured {
                figures: Components {
                    full: ComponentFigures::new(&figures(rmse / 2.0, 0.05), &r),
                    indirect: ComponentFigures::new(&figures(rmse, 0.1), &r),
                },
                gpu_frame_ms: Some(ms),
                gpu_prepare_ms: Some(0.5),
                passes: vec![
                    PassTime {
                        name: "gbuffer".into(),
                        prepare: false,
                        ms: ms / 2.0,
                    },
                    PassTime {
                        name: "shadow map".into(),
                        prepare: true,
                        ms: 0.5,
                    },
                ],
                memory_bytes: Some(3 * 1024 * 1024),
                seconds: 0.25,
                images: MethodImages {
                    full: format!("images/box/{spec}-full.png"),
                    indirect: format!("images/box/{spec}-indirect.png"),
                    indirect_error: format!("images/box/{spec}-indirect-error.png"),
                },
            }),
        }
    }

    /// A report of one scene with three methods, one failed; also the page's test data.
    pub(crate) fn report() -> CompareReport {
        CompareReport {
            command: "cssm compare".into(),
            commit: "abc".into(),
            machine: "a CPU".into(),
            device: Some("llvmpipe (Vulkan)".into()),
            settings: CompareSettings {
                width: 16,
                height: 12,
                samples: 64,
                bounces: 1,
                frames: 1,
                exposure_stops: 0.0,
                shadow_resolution: 512,
                atlas: 32,
                cube: 8,
            },
            scenes: vec![SceneComparison {
                name: "box <1>".into(),
                reference: Components {
                    full: reference("images/box/reference-full.png"),
                    indirect: reference("images/box/reference-indirect.png"),
                },
                methods: vec![
                    method("rsm", 0.5, 2.0),
                    method("lightcuts:bounces=1,jitter=true", 0.4, 8.0),
                    MethodComparison {
                        spec: "hrc".into(),
                        method: "hrc".into(),
                        on_gpu: true,
                        error: Some("the atlas does not fit".into()),
                        measured: None,
                    },
                ],
            }],
            seconds: 3.0,
        }
    }

    #[test]
    fn the_reference_noise_comes_out() {
        let r = report();
        let f = &r.scenes[0].methods[0].measured.as_ref().unwrap().figures;
        // 0.5 measured against a floor of 0.3: 0.4 from the converged image, 36% noise.
        assert!((f.indirect.relative_rmse_without_noise.unwrap() - 0.4).abs() < 1e-12);
        assert!((f.indirect.noise_share.unwrap() - 0.36).abs() < 1e-12);
        assert_eq!(rmse_cell(&f.indirect), "0.400 (0.500, 36% noise)");
        assert_eq!(bias_cell(&f.indirect), "-0.100 ± 0.0100");
        assert_eq!(flip_cell(&f.indirect), "0.100 (floor 0.020)");
        // Below the floor: no error of its own to see.
        assert_eq!(f.full.relative_rmse_without_noise, Some(0.0));
    }

    #[test]
    fn markdown_ranks_and_csv_has_a_line_per_component() {
        let r = report();
        let md = markdown(&r);
        let lightcuts = md.find("| lightcuts:bounces=1,jitter=true |").expect(&md);
        let rsm = md.find("| rsm |").expect(&md);
        let hrc = md
            .find("| hrc | failed: the atlas does not fit")
            .expect(&md);
        assert!(
            lightcuts < rsm && rsm < hrc,
            "best first, failed last: {md}"
        );
        assert!(md.contains("| 8.00 | 0.50 | 3.0 |"), "{md}");
        let csv = csv(&r);
        let lines: Vec<&str> = csv.lines().collect();
        // Header, then per component the noise floor and three methods.
        assert_eq!(lines.len(), 1 + 2 * 4, "{csv}");
        let columns = lines[0].split(',').count();
        assert!(lines[2].starts_with("box <1>,rsm,full,0.25,"), "{csv}");
        assert!(
            lines[7].starts_with("box <1>,\"lightcuts:bounces=1,jitter=true\",indirect,0.4,"),
            "{csv}"
        );
        assert!(lines[8].ends_with(",the atlas does not fit"), "{csv}");
        for line in &lines[1..] {
            // Quoted commas aside, every line has the header's columns.
            let unquoted = line.replace("\"lightcuts:bounces=1,jitter=true\"", "x");
            let unquoted = unquoted.replace("\"llvmpipe (Vulkan)\"", "x");
            assert_eq!(unquoted.split(',').count(), columns, "{line}");
        }
        let json: serde_json::Value = serde_json::from_str(&json(&r).unwrap()).unwrap();
        let methods = &json["scenes"][0]["methods"];
        assert_eq!(methods[1]["measured"]["passes"][1]["prepare"], true);
        assert_eq!(methods[2]["error"], "the atlas does not fit");
        assert!(methods[2].get("measured").is_none());
    }
}
