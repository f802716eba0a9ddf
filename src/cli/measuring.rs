//! `cssm report error` and `cssm compare`: the flags they share ([`MeasureFlags`]), each
//! `--method` spec parsed against the method table (into the lab's [`Variant`]), and their
//! configurations (the lab's [`ErrorConfig`] and [`CompareConfig`], which
//! [`cssm::measure`] runs).

use cssm::measure::{CompareConfig, ErrorConfig, Variant};

use super::*;

/// `cssm report error --help`'s text after the options: the method table, then examples.
pub(super) fn error_after_help() -> String {
    format!(
        "Methods and their options (--method NAME:OPTION=VALUE,OPTION=VALUE; --bounces and \
         --samples fill those options of every variant that has them and does not set them):\n{}\n\
         Every method marked [needs .cssm] gets one baked in memory per scene (--atlas, --cube).\n\n\
         Examples:\n  \
         cssm report error --method direct --method lightcuts --out /tmp/error\n  \
         cssm report error --method hrc --method lightmap --method lightcuts:jitter=true --samples 4096 --out /tmp/error\n  \
         cssm report error --scene reports/scenes/sibenik --method direct --size 320x240 --reference-cache --out /tmp/sibenik",
        runtime::method::describe_methods()
    )
}

#[derive(clap::Args)]
pub struct ErrorArgs {
    /// Scene directory or mesh file (.obj, .gltf, .glb); repeatable. Default: the built-in
    /// Cornell box and the Cornell box with a glossy floor (scenes/cornell-box,
    /// scenes/cornell-glossy).
    #[arg(long = "scene", value_name = "SCENE")]
    scenes: Vec<PathBuf>,
    /// A method variant to measure, NAME or NAME:OPTION=VALUE,OPTION=VALUE (for example
    /// `lightcuts:bounces=2,jitter=true`; the list below); repeatable, at least one.
    #[arg(long = "method", value_name = "SPEC", required = true)]
    methods: Vec<String>,
    /// Image size WIDTHxHEIGHT.
    #[arg(long, default_value = "160x120", value_parser = parse_size)]
    size: (u32, u32),
    #[command(flatten)]
    measure: MeasureFlags,
    /// Which light the images hold and the figures measure: direct, indirect or full.
    #[arg(long, default_value = "indirect")]
    component: Component,
    /// Directory of the report (created; only the report's own files in it are replaced, and
    /// never through a symbolic link: a link under one of their names is refused).
    #[arg(long)]
    out: PathBuf,
    /// Reuse OUT/SCENE-reference.exr when its sidecar SCENE-reference.json records the same
    /// scene files, size, samples, bounces and component, instead of path tracing again.
    #[arg(long)]
    reference_cache: bool,
}

impl ErrorArgs {
    /// Every spec parsed and resolved against the method table, the reference's options, the
    /// frame settings and the bake options checked; an error names the spec or the flag.
    pub fn config(self) -> Result<ErrorConfig, String> {
        let checked = self.measure.check(self.size)?;
        let m = &self.measure;
        Ok(ErrorConfig {
            scenes: self.scenes,
            variants: parse_variants(&self.methods, m.bounces, m.samples)?,
            frame: checked.frame,
            reference: checked.reference,
            component: self.component,
            bake: checked.bake,
            out: self.out,
            reference_cache: self.reference_cache,
            frames: m.frames,
        })
    }
}

/// The flags `cssm report error` and `cssm compare` share, spelled and checked once.
#[derive(clap::Args)]
pub struct MeasureFlags {
    /// Paths per pixel of the reference, in two independent halves whose difference measures
    /// its noise (and of a `reference` variant unless its spec sets `samples`).
    #[arg(long, default_value_t = 1024)]
    samples: u32,
    /// Indirect bounces of the reference and of every method with a `bounces` option that does
    /// not set it (the methods without one compute a single bounce).
    #[arg(long, default_value_t = 1)]
    bounces: u32,
    /// Frames each GPU method renders before its image is measured, the camera at rest (ssil's
    /// temporal filter converges over a few).
    #[arg(long, default_value_t = 1)]
    frames: u32,
    /// Exposure in stops of every tone-mapped image and of FLIP (radiance is scaled by 2^EV
    /// before tone mapping; also the oracle's tone mapping of hrc, lightmap, lightcuts).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = stops)]
    exposure: f32,
    /// Shadow-map resolution in texels per side.
    #[arg(long, default_value_t = runtime::common::shadow_map::DEFAULT_RESOLUTION)]
    shadow_resolution: u32,
    /// CSSM methods: ask only the receiver's cube maps for each sender, as the paper does,
    /// instead of both ends' answers combined (the default; see `cssm check --one-end`).
    #[arg(long)]
    one_end: bool,
    /// Atlas resolution of the .cssm baked in memory for the methods that need one (32 to 1024).
    #[arg(long, default_value_t = 64)]
    atlas: u32,
    /// Cube-map face resolution of that bake (8 to 128).
    #[arg(long, default_value_t = 32)]
    cube: u32,
}

/// [`MeasureFlags`], checked.
struct MeasureChecked {
    reference: Resolved,
    frame: runtime::frame::FrameSettings,
    bake: bake::BakeOptions,
}

impl MeasureFlags {
    /// The reference's options checked by its table entry, the frame settings by the runtime,
    /// the bake options by the bake library, the frame count against [`MAX_FRAMES`]; an error
    /// names the flag.
    fn check(&self, size: (u32, u32)) -> Result<MeasureChecked, String> {
        // Until converged, the reference and each method would stop where their own light
        // says: a comparison needs them to compute the same bounces.
        if self.bounces == 0 {
            return Err(
                "--bounces 0 (until converged) cannot be compared: the reference and \
                        the methods must compute the same bounces; give a count, 1 to 8"
                    .into(),
            );
        }
        let reference_entry = runtime::method::find("reference").map_err(|e| e.to_string())?;
        for (name, value) in [("samples", self.samples), ("bounces", self.bounces)] {
            if let Some(spec) = reference_entry.option(name) {
                spec.check(OptionValue::Count(value))
                    .map_err(|e| format!("--{e}"))?;
            }
        }
        let mut values = OptionValues::default();
        values.set("samples", OptionValue::Count(self.samples));
        values.set("bounces", OptionValue::Count(self.bounces));
        let reference = reference_entry
            .resolve(&values)
            .map_err(|e| e.to_string())?;
        let frame = runtime::frame::FrameSettings {
            width: size.0,
            height: size.1,
            exposure: self.exposure.exp2(),
            shadow_resolution: self.shadow_resolution,
            visibility: QueryOptions {
                both_ends: !self.one_end,
                ..QueryOptions::default()
            },
        };
        frame.check().map_err(|e| e.to_string())?;
        let bake = bake::BakeOptions {
            atlas_resolution: self.atlas,
            cube_resolution: self.cube,
            ..Default::default()
        };
        bake.check().map_err(|e| cssm::flag_error(&e))?;
        if !(1..=MAX_FRAMES).contains(&self.frames) {
            return Err(format!(
                "--frames {} is out of range 1..={MAX_FRAMES}",
                self.frames
            ));
        }
        Ok(MeasureChecked {
            reference,
            frame,
            bake,
        })
    }
}

/// Each spec parsed ([`parse_variant`]); a spec given twice is refused.
fn parse_variants(specs: &[String], bounces: u32, samples: u32) -> Result<Vec<Variant>, String> {
    let mut variants: Vec<Variant> = Vec::new();
    for text in specs {
        let variant = parse_variant(text, bounces, samples)?;
        if let Some(other) = variants.iter().find(|v| v.spec == variant.spec) {
            return Err(format!("--method {}: given twice", other.spec));
        }
        variants.push(variant);
    }
    Ok(variants)
}

/// `cssm compare --help`'s text after the options: the method table, then examples.
pub(super) fn compare_after_help() -> String {
    format!(
        "Methods and their options (--methods NAME:OPTION=VALUE,OPTION=VALUE,NAME,...; --bounces \
         and --samples fill those options of every method that has them and does not set them):\n{}\n\
         Every method marked [needs .cssm] gets one baked in memory per scene (--atlas, --cube).\n\n\
         Examples:\n  \
         cssm compare --out /tmp/compare                       # the built-in boxes, every method\n  \
         cssm compare scenes/cornell-box reports/scenes/sibenik --methods rsm,vct,vf --size 640x480\n  \
         cssm compare --methods lightcuts:bounces=2,jitter=true,ssil --bounces 2 --frames 16\n  \
         cssm compare ../shared/scenes/sibenik --atlas 256 --samples 4096 --out /tmp/sibenik",
        runtime::method::describe_methods()
    )
}

#[derive(clap::Args)]
pub struct CompareArgs {
    /// Scene directories or mesh files (.obj, .gltf, .glb). Default: the built-in Cornell box and
    /// the Cornell box with a glossy floor (scenes/cornell-box, scenes/cornell-glossy).
    #[arg(value_name = "SCENE")]
    scenes: Vec<PathBuf>,
    /// Methods to compare, comma-separated, each NAME or NAME:OPTION=VALUE,OPTION=VALUE (a part
    /// with `=` and no `:` is an option of the method before it: `lightcuts:bounces=2,jitter=true,rsm`
    /// is two methods); repeatable. Default: every method of the table but the path tracer.
    #[arg(long = "methods", value_name = "LIST")]
    methods: Vec<String>,
    /// Image size WIDTHxHEIGHT.
    #[arg(long, default_value = "320x240", value_parser = parse_size)]
    size: (u32, u32),
    #[command(flatten)]
    measure: MeasureFlags,
    /// Directory of the page (created; only the page's own files in it are replaced, and never
    /// through a symbolic link: a link under one of their names is refused): index.html,
    /// chart.svg, compare.csv, compare.json, compare.md, images/ and reference-cache/.
    #[arg(long, default_value = "compare")]
    out: PathBuf,
    /// Path trace the references again even where OUT/reference-cache/ holds one of the same
    /// scene files and settings.
    #[arg(long)]
    no_cache: bool,
}

impl CompareArgs {
    /// The methods split ([`split_methods`]), parsed and resolved against the method table, and
    /// the shared flags checked; an error names the method or the flag.
    pub fn config(self) -> Result<CompareConfig, String> {
        let checked = self.measure.check(self.size)?;
        let m = &self.measure;
        let specs: Vec<String> = if self.methods.is_empty() {
            runtime::METHODS
                .iter()
                .filter(|m| m.on_gpu())
                .map(|m| m.name.to_string())
                .collect()
        } else {
            self.methods.iter().flat_map(|l| split_methods(l)).collect()
        };
        if specs.is_empty() {
            return Err("--methods: no method given".into());
        }
        Ok(CompareConfig {
            scenes: self.scenes,
            variants: parse_variants(&specs, m.bounces, m.samples)?,
            frame: checked.frame,
            exposure_stops: m.exposure,
            reference: checked.reference,
            bake: checked.bake,
            out: self.out,
            reuse_references: !self.no_cache,
            frames: m.frames,
        })
    }
}

/// A `--methods` list split into method specs: at each comma, unless the part after it holds
/// `=` and no `:` (an option of the method before it). Empty parts are dropped.
pub(super) fn split_methods(list: &str) -> Vec<String> {
    let mut specs: Vec<String> = Vec::new();
    for part in list.split(',') {
        let part = part.trim();
        if part.is_empty() {
            continue;
        }
        match specs.last_mut() {
            Some(last) if part.contains('=') && !part.contains(':') && last.contains(':') => {
                last.push(',');
                last.push_str(part);
            }
            _ => specs.push(part.to_string()),
        }
    }
    specs
}

/// `NAME` or `NAME:OPTION=VALUE,OPTION=VALUE`, checked against the method table; `bounces` and
/// `samples` filled from the flags where the method has them and the spec does not set them.
/// Errors name the spec.
pub(super) fn parse_variant(text: &str, bounces: u32, samples: u32) -> Result<Variant, String> {
    let fail = |message: String| format!("--method {text}: {message}");
    let (name, options) = match text.split_once(':') {
        Some((name, options)) => (name.trim(), Some(options)),
        None => (text.trim(), None),
    };
    let method = runtime::method::find(name).map_err(|e| fail(e.to_string()))?;
    // `NAME:` with nothing after it is an empty part, refused as one.
    let options = options.map(|o| if o.trim().is_empty() { "," } else { o });
    let mut values = method
        .parse_options(options.unwrap_or_default())
        .map_err(fail)?;
    let given: Vec<String> = options
        .into_iter()
        .flat_map(|o| o.split(','))
        .filter_map(|part| part.split_once('='))
        .map(|(key, value)| format!("{}={}", key.trim(), value.trim()))
        .collect();
    for (option, value) in [("bounces", bounces), ("samples", samples)] {
        if method.option(option).is_some() && values.get(option).is_none() {
            values.set(option, OptionValue::Count(value));
        }
    }
    let resolved = method.resolve(&values).map_err(|e| fail(e.to_string()))?;
    let spec = if given.is_empty() {
        method.name.to_string()
    } else {
        format!("{}:{}", method.name, given.join(","))
    };
    Ok(Variant {
        spec,
        method,
        values,
        resolved,
    })
}
