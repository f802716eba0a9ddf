//! The seam every global-illumination method plugs into: the [`GiMethod`] trait, the typed
//! options a method declares ([`OptionSpec`]), and [`METHODS`], the one table that `cssm render
//! --method`, its `--help`, the tests, and later the viewer and the comparison page are built
//! from.
//!
//! # Adding a method
//! 1. A folder `runtime/src/<name>/` with `mod.rs` (the user docs: what it computes, the paper
//!    and section, its options with defaults, when it fails), one file per pass with its WGSL
//!    beside it, and `cpu.rs`, the CPU reference of the same computation.
//! 2. In `mod.rs`, a type implementing [`GiMethod`] and a `pub const METHOD: MethodEntry` naming
//!    it, its options, whether it needs a `.cssm`, the tolerances of the tests every method gets
//!    ([`Checks`]) and the settings it is timed at ([`Timing`]); and `pub const SHADERS:
//!    ShaderSet`, its WGSL: each pass file declares its module (`pub const SHADER: Shader =
//!    shader!("label", "<name>/pass.wgsl")`) and `SHADERS` lists them with the folder's
//!    libraries ([`crate::shaders`] collects them; its test fails on a WGSL file no folder
//!    lists).
//! 3. One line in the table in `runtime/src/lib.rs` (`method_table!`), which declares the
//!    folder's module and lists its entries in [`METHODS`].
//!
//! The shared passes (shadow maps, G-buffer, direct light, compose, tone mapping) and the shared
//! resources ([`FrameContext`]) come from the renderer; a method records only its own passes and
//! hands back its indirect light.
//!
//! ```
//! use cssm_runtime::method::{self, OptionValue, OptionValues};
//! let lightcuts = method::find("lightcuts")?;
//! assert!(lightcuts.needs_cssm);
//! let mut options = OptionValues::default();
//! options.set("bounces", OptionValue::Count(2));
//! let resolved = lightcuts.resolve(&options)?;
//! assert_eq!(resolved.count("bounces"), 2);
//! assert_eq!(resolved.number("threshold"), cssm_runtime::radiosity::DEFAULT_THRESHOLD);
//! # Ok::<(), cssm_runtime::RuntimeError>(())
//! ```

use std::{collections::BTreeMap, fmt};

use cssm_formats::{CssmFile, Scene};

use crate::{
    RuntimeError,
    common::camera::View,
    frame::{FrameContext, FrameEncoder, PassInfo, Slot},
};

/// A global-illumination method on the GPU, built once by the renderer and driven by it.
///
/// The renderer calls [`GiMethod::prepare`] before the first frame and again whenever a light
/// or an object moves (the view-independent work: radiosity over the atlas, say), then
/// [`GiMethod::encode`] every frame, and [`GiMethod::resize`] when the image size changes.
pub trait GiMethod {
    /// Records the view-independent passes. The default records nothing.
    fn prepare(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        let _ = (ctx, frame);
    }

    /// Records this frame's passes. `frame.index` counts the frames since the camera, a light
    /// or an object last moved (progressive accumulation restarts at 0).
    fn encode(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder);

    /// The indirect radiance towards the eye per pixel, one `vec4f` per pixel in row-major order
    /// (rgb; w is the method's own), or `None` for a method without indirect light.
    fn indirect(&self) -> Option<&wgpu::Buffer>;

    /// Rebuilds what depends on the image size; `ctx` already holds the new G-buffer.
    ///
    /// # Errors
    /// When the new size exceeds a device limit.
    fn resize(&mut self, ctx: &FrameContext) -> Result<(), RuntimeError>;

    /// How many bounces the last [`GiMethod::prepare`] ran, read back (waits for the GPU), for
    /// a method whose bounces stop once converged ([`crate::common::converge`]); `None` (the
    /// default) for the others.
    fn convergence(
        &self,
        ctx: &FrameContext,
    ) -> Option<Result<crate::common::converge::Convergence, RuntimeError>> {
        let _ = ctx;
        None
    }
}

/// What a method's constructor gets.
pub struct MethodSetup<'a> {
    /// The shared GPU resources.
    pub ctx: &'a FrameContext,
    /// The scene as loaded.
    pub scene: &'a Scene,
    /// The scene's `.cssm`, present whenever the entry says it needs one.
    pub cssm: Option<&'a CssmFile>,
    /// The method's options, checked against its [`MethodEntry::options`].
    pub options: &'a Resolved,
}

impl MethodSetup<'_> {
    /// The `.cssm` file.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] when none was given.
    pub fn cssm_file(&self) -> Result<&CssmFile, RuntimeError> {
        self.cssm.ok_or_else(|| {
            RuntimeError::Unsupported("this method needs the scene's .cssm file".into())
        })
    }
}

/// What a CPU method (the reference path tracer) gets.
pub struct CpuSetup<'a> {
    /// The scene as loaded.
    pub scene: &'a Scene,
    /// The camera and image size.
    pub view: &'a View,
    /// Which light paths the image holds.
    pub component: crate::common::compose::Component,
    /// The method's options, checked against its [`MethodEntry::options`].
    pub options: &'a Resolved,
    /// Called with (pixels done, pixels in all) as the work proceeds.
    pub progress: &'a (dyn Fn(u64, u64) + Sync),
    /// Called once when the method's bounces ran until converged, with how many it kept.
    pub on_bounces: &'a dyn Fn(crate::common::converge::Convergence),
}

/// How a method runs.
#[derive(Clone, Copy)]
pub enum Backend {
    /// On the GPU, inside the [`crate::Renderer`].
    Gpu(fn(&MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError>),
    /// On the CPU: linear radiance per pixel, row-major (the ground truth).
    Cpu(fn(&CpuSetup) -> Result<Vec<[f32; 4]>, RuntimeError>),
}

/// One row of [`METHODS`].
#[derive(Clone, Copy)]
pub struct MethodEntry {
    /// Name on the command line (`--method NAME`).
    pub name: &'static str,
    /// One line on what it computes, with the paper's section.
    pub summary: &'static str,
    /// Whether it needs the scene's `.cssm` file.
    pub needs_cssm: bool,
    /// Its options, with defaults and ranges.
    pub options: &'static [OptionSpec],
    /// The passes it records (GPU methods), prepare passes first, each with what it reads and
    /// writes; [`crate::frame::check_schedule`] holds them to the frame.
    pub passes: &'static [PassInfo],
    /// How it runs.
    pub backend: Backend,
    /// What the tests every method gets from this table hold it to.
    pub checks: Checks,
    /// The settings its timing benchmark runs it at (`benches/method_time.rs`, which
    /// `reports/runtime.sh` runs for every method that has rows).
    pub timing: Timing,
}

/// A method's timing benchmark: the settings its paper reports frame times at, each row timed
/// in one run beside the methods it is compared with (`benches/method_time.rs`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// What the rows are, citing the paper's table or figure; for a method without rows, why
    /// not and where it is timed instead.
    pub about: &'static str,
    /// Methods timed first in the same run, light still, at their defaults: each row's frame
    /// time is given as a ratio to theirs.
    pub compare_with: &'static [&'static str],
    /// The rows, in order.
    pub rows: &'static [TimingRow],
}

/// One row of a [`Timing`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimingRow {
    /// What the row is (the paper's setting it reproduces).
    pub label: &'static str,
    /// Its options as `OPTION=VALUE,OPTION=VALUE` (the syntax of `--method NAME:...`); the
    /// others take their defaults. Empty for the defaults.
    pub options: &'static str,
    /// Whether the light moves every frame, so that the prepare passes run every frame too.
    pub moving_light: bool,
}

impl Timing {
    /// A method that needs the scene's `.cssm`: timed on each baked scene by `cssm render
    /// --timings` (`reports/runtime.sh`'s gi step), not by the method benchmark, which bakes
    /// nothing.
    pub const PER_BAKE: Timing = Timing {
        about: "timed per baked scene by `cssm render --timings` (reports/runtime.sh's gi step)",
        compare_with: &[],
        rows: &[],
    };

    /// A method at its defaults, the light still and then moving every frame, beside `direct`:
    /// what a method gets unless it names its paper's settings.
    pub const DEFAULT: Timing = Timing {
        about: "the method's defaults",
        compare_with: &["direct"],
        rows: &[
            TimingRow {
                label: "defaults",
                options: "",
                moving_light: false,
            },
            TimingRow {
                label: "defaults",
                options: "",
                moving_light: true,
            },
        ],
    };
}

/// The tolerances a method declares for the tests every method gets from [`METHODS`]
/// (`tests/gpu/methods.rs`), each measured and set with a margin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Checks {
    /// The analytic energy check: in a closed sphere of one albedo lit by one spot light, the
    /// indirect irradiance is the same everywhere (every form factor is `dA / A`), so every
    /// pixel's indirect radiance is `rho / pi * Phi / A * (rho + ... + rho^B)` for `B`
    /// bounces.
    pub energy: Energy,
    /// Largest mean FLIP error (0 to 1) of its image of the Cornell box against its golden
    /// image (`tests/golden/`).
    pub golden_flip: f32,
    /// The energy check in the same sphere lit by its own emission instead (no light; every
    /// triangle emits `Le` inwards, its front; `tests/gpu/emissive.rs`): the `k`-th bounce's
    /// irradiance is `pi Le rho^(k-1)` everywhere, so every pixel's indirect radiance is
    /// `Le (rho + ... + rho^B)`. [`Energy::NoIndirect`] for a method whose indirect light does
    /// not carry the light of emitters (`vct` and `rsm` take theirs from the lights' RSM).
    pub emissive: Energy,
}

impl Checks {
    /// What a method is held to unless it says otherwise (`checks: Checks { golden_flip: 0.01,
    /// ..Checks::DEFAULT }`): the CSSM methods' tolerances, so a new kind of check has a value
    /// for every method without editing each.
    pub const DEFAULT: Checks = Checks {
        energy: Energy::Within(0.04),
        golden_flip: 0.005,
        emissive: Energy::Within(0.04),
    };
}

impl Default for Checks {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// What the energy check in the closed sphere holds a method to ([`Checks::energy`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Energy {
    /// The largest relative error of the image's mean indirect radiance the method meets.
    Within(f32),
    /// A method without indirect light: its indirect image must be black.
    NoIndirect,
    /// A screen-space method gathers only from the pixels it sees, and the sphere's camera
    /// looks away from the wall its light falls on: it must never exceed the closed form
    /// (energy lost, never made). Its energy is checked against the sum over the screen
    /// instead (`tests/gpu/ssil.rs`).
    OnScreenOnly,
}

impl fmt::Debug for MethodEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name)
    }
}

impl fmt::Display for MethodEntry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name)
    }
}

impl PartialEq for MethodEntry {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

impl MethodEntry {
    /// Checks `values` against [`Self::options`]: every name known, every value of the right
    /// kind and in range; missing options take their defaults.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] naming the option and its range.
    pub fn resolve(&self, values: &OptionValues) -> Result<Resolved, RuntimeError> {
        let mut resolved = BTreeMap::new();
        for (name, &value) in &values.0 {
            let spec = self.option(name).ok_or_else(|| {
                RuntimeError::Unsupported(format!(
                    "method '{}' has no option '{name}' (its options: {})",
                    self.name,
                    self.option_names()
                ))
            })?;
            spec.check(value)
                .map_err(|e| RuntimeError::Unsupported(format!("{e} (method {})", self.name)))?;
            resolved.insert(spec.name, value);
        }
        for spec in self.options {
            resolved.entry(spec.name).or_insert(spec.kind.default());
        }
        Ok(Resolved {
            method: self.name,
            values: resolved,
        })
    }

    /// The values of `text`, `OPTION=VALUE,OPTION=VALUE` (what follows `NAME:` in `--method
    /// NAME:...`; empty for none: an empty part between commas is an error), parsed by each
    /// option's kind but not range-checked ([`Self::resolve`] checks).
    ///
    /// # Errors
    /// A message naming the part that is not `OPTION=VALUE`, an option the method lacks (with
    /// the ones it has), one given twice, or a value of the wrong kind.
    pub fn parse_options(&self, text: &str) -> Result<OptionValues, String> {
        let mut values = OptionValues::default();
        if text.trim().is_empty() {
            return Ok(values);
        }
        for part in text.split(',') {
            let (key, value) = part
                .split_once('=')
                .ok_or_else(|| format!("'{}' is not OPTION=VALUE", part.trim()))?;
            let (key, value) = (key.trim(), value.trim());
            let spec = self.option(key).ok_or_else(|| {
                format!(
                    "method {} has no option '{key}' (its options: {})",
                    self.name,
                    self.option_names()
                )
            })?;
            if values.get(spec.name).is_some() {
                return Err(format!("option '{key}' is given twice"));
            }
            values.set(spec.name, spec.parse(value)?);
        }
        Ok(values)
    }

    /// Its options' names for a message, or "none".
    fn option_names(&self) -> String {
        if self.options.is_empty() {
            return "none".into();
        }
        let names: Vec<&str> = self.options.iter().map(|o| o.name).collect();
        names.join(", ")
    }

    /// The option called `name`.
    pub fn option(&self, name: &str) -> Option<&'static OptionSpec> {
        self.options.iter().find(|o| o.name == name)
    }

    /// Whether one of its passes reads `slot` (the renderer makes the shared resources its
    /// passes read: the reflective shadow map only for a method that reads [`Slot::Rsm`]).
    pub fn reads(&self, slot: Slot) -> bool {
        self.passes.iter().any(|p| p.reads.contains(&slot))
    }

    /// Whether it runs on the GPU, inside the renderer.
    pub fn on_gpu(&self) -> bool {
        matches!(self.backend, Backend::Gpu(_))
    }
}

/// The table of methods, declared with their folders in `runtime/src/lib.rs`.
pub use crate::METHODS;

/// The method called `name`.
///
/// # Errors
/// [`RuntimeError::Unsupported`] listing the methods there are.
pub fn find(name: &str) -> Result<&'static MethodEntry, RuntimeError> {
    METHODS.iter().find(|m| m.name == name).ok_or_else(|| {
        let names: Vec<&str> = METHODS.iter().map(|m| m.name).collect();
        RuntimeError::Unsupported(format!(
            "unknown method '{name}' (available: {})",
            names.join(", ")
        ))
    })
}

/// The method table as text: a line per method, then each option with its default and range
/// (what `cssm render --help` prints).
pub fn describe_methods() -> String {
    let width = METHODS.iter().map(|m| m.name.len()).max().unwrap_or(0);
    let mut out = String::new();
    for m in METHODS {
        let cssm = if m.needs_cssm { " [needs .cssm]" } else { "" };
        out += &format!("  {:<width$}  {}{cssm}\n", m.name, m.summary);
        for o in m.options {
            out += &format!("  {:<width$}    {}: {} ({})\n", "", o.name, o.help, o.kind);
        }
    }
    out
}

/// One option of a method.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OptionSpec {
    /// Its name (`bounces`); the command line's flag is `--NAME` or `--set NAME=VALUE`.
    pub name: &'static str,
    /// One line on what it does.
    pub help: &'static str,
    /// Its kind, default and range.
    pub kind: OptionKind,
}

/// The kind, default and range of an option.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OptionKind {
    /// A whole number in `min..=max`.
    Count {
        /// Default.
        default: u32,
        /// Smallest accepted.
        min: u32,
        /// Largest accepted.
        max: u32,
    },
    /// A finite number at least `min`.
    Number {
        /// Default.
        default: f32,
        /// Smallest accepted.
        min: f32,
    },
    /// On or off.
    Switch {
        /// Default.
        default: bool,
    },
    /// One of a few named variants.
    Choice {
        /// Default, one of `choices`.
        default: &'static str,
        /// The names accepted.
        choices: &'static [&'static str],
    },
}

impl OptionKind {
    /// The default value.
    pub fn default(self) -> OptionValue {
        match self {
            OptionKind::Count { default, .. } => OptionValue::Count(default),
            OptionKind::Number { default, .. } => OptionValue::Number(default),
            OptionKind::Switch { default } => OptionValue::Switch(default),
            OptionKind::Choice { default, .. } => OptionValue::Choice(default),
        }
    }
}

impl fmt::Display for OptionKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            OptionKind::Count { default, min, max } => {
                write!(f, "default {default}, {min} to {max}")
            }
            OptionKind::Number { default, min } => write!(f, "default {default}, at least {min}"),
            OptionKind::Switch { default } => write!(f, "default {default}"),
            OptionKind::Choice { default, choices } => {
                write!(f, "default {default}, one of {}", choices.join(", "))
            }
        }
    }
}

impl OptionSpec {
    /// Checks `value` against the kind and range (the one place each range is checked).
    ///
    /// # Errors
    /// A message naming the option, the value and what it must be.
    pub fn check(&self, value: OptionValue) -> Result<(), String> {
        let name = self.name;
        match (self.kind, value) {
            (OptionKind::Count { min, max, .. }, OptionValue::Count(v)) => {
                if (min..=max).contains(&v) {
                    Ok(())
                } else {
                    Err(format!("{name} {v} is out of range {min}..={max}"))
                }
            }
            (OptionKind::Number { min, .. }, OptionValue::Number(v)) => {
                if v.is_finite() && v >= min {
                    Ok(())
                } else {
                    Err(format!("{name} {v} must be a number >= {min}"))
                }
            }
            (OptionKind::Switch { .. }, OptionValue::Switch(_)) => Ok(()),
            (OptionKind::Choice { choices, .. }, OptionValue::Choice(v)) => {
                if choices.contains(&v) {
                    Ok(())
                } else {
                    Err(format!("{name} {v} is not one of {}", choices.join(", ")))
                }
            }
            (kind, value) => Err(format!(
                "{name} takes {}, not {value}",
                match kind {
                    OptionKind::Count { .. } => "a whole number".to_string(),
                    OptionKind::Number { .. } => "a number".to_string(),
                    OptionKind::Switch { .. } => "true or false".to_string(),
                    OptionKind::Choice { choices, .. } => format!("one of {}", choices.join(", ")),
                }
            )),
        }
    }

    /// Parses `text` as a value of this option's kind (`--set NAME=VALUE`); the range is
    /// checked by [`OptionSpec::check`].
    ///
    /// # Errors
    /// A message naming the option and what it takes.
    pub fn parse(&self, text: &str) -> Result<OptionValue, String> {
        let name = self.name;
        let text = text.trim();
        match self.kind {
            OptionKind::Count { .. } => text
                .parse()
                .map(OptionValue::Count)
                .map_err(|_| format!("{name} takes a whole number, not '{text}'")),
            OptionKind::Number { .. } => text
                .parse()
                .map(OptionValue::Number)
                .map_err(|_| format!("{name} {text} must be a number")),
            OptionKind::Switch { .. } => match text {
                "true" | "on" | "yes" | "1" => Ok(OptionValue::Switch(true)),
                "false" | "off" | "no" | "0" => Ok(OptionValue::Switch(false)),
                _ => Err(format!("{name} takes true or false, not '{text}'")),
            },
            OptionKind::Choice { choices, .. } => choices
                .iter()
                .find(|&&c| c == text)
                .map(|&c| OptionValue::Choice(c))
                .ok_or_else(|| format!("{name} takes one of {}, not '{text}'", choices.join(", "))),
        }
    }
}

/// A value of an option.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OptionValue {
    /// A whole number.
    Count(u32),
    /// A number.
    Number(f32),
    /// On or off.
    Switch(bool),
    /// One of the names of an [`OptionKind::Choice`].
    Choice(&'static str),
}

impl fmt::Display for OptionValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OptionValue::Count(v) => write!(f, "{v}"),
            OptionValue::Number(v) => write!(f, "{v}"),
            OptionValue::Switch(v) => write!(f, "{v}"),
            OptionValue::Choice(v) => f.write_str(v),
        }
    }
}

/// Option values by name, as a user gave them (unchecked; [`MethodEntry::resolve`] checks).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OptionValues(BTreeMap<String, OptionValue>);

impl OptionValues {
    /// Sets `name` to `value`.
    pub fn set(&mut self, name: &str, value: OptionValue) -> &mut Self {
        self.0.insert(name.to_string(), value);
        self
    }

    /// The value set for `name`, if any.
    pub fn get(&self, name: &str) -> Option<OptionValue> {
        self.0.get(name).copied()
    }
}

/// A method's options after [`MethodEntry::resolve`]: every option present, in range.
#[derive(Clone, Debug, PartialEq)]
pub struct Resolved {
    method: &'static str,
    values: BTreeMap<&'static str, OptionValue>,
}

impl Resolved {
    fn value(&self, name: &str) -> OptionValue {
        // A method asks only for options it declares; the table's tests build every method.
        *self.values.get(name).unwrap_or_else(|| {
            panic!(
                "method {} asked for an option it does not declare: {name}",
                self.method
            )
        })
    }

    /// The whole-number option `name`.
    ///
    /// # Panics
    /// When the method does not declare `name` as a count (a bug in the method).
    pub fn count(&self, name: &str) -> u32 {
        match self.value(name) {
            OptionValue::Count(v) => v,
            other => panic!("option {name} of {} is {other:?}, not a count", self.method),
        }
    }

    /// The number option `name`.
    ///
    /// # Panics
    /// When the method does not declare `name` as a number (a bug in the method).
    pub fn number(&self, name: &str) -> f32 {
        match self.value(name) {
            OptionValue::Number(v) => v,
            other => panic!(
                "option {name} of {} is {other:?}, not a number",
                self.method
            ),
        }
    }

    /// The switch `name`.
    ///
    /// # Panics
    /// When the method does not declare `name` as a switch (a bug in the method).
    pub fn switch(&self, name: &str) -> bool {
        match self.value(name) {
            OptionValue::Switch(v) => v,
            other => panic!(
                "option {name} of {} is {other:?}, not a switch",
                self.method
            ),
        }
    }

    /// The choice `name`: one of its declared names.
    ///
    /// # Panics
    /// When the method does not declare `name` as a choice (a bug in the method).
    pub fn choice(&self, name: &str) -> &'static str {
        match self.value(name) {
            OptionValue::Choice(v) => v,
            other => panic!(
                "option {name} of {} is {other:?}, not a choice",
                self.method
            ),
        }
    }

    /// Every option and its value, in name order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, OptionValue)> + '_ {
        self.values.iter().map(|(&k, &v)| (k, v))
    }
}

/// Most indirect bounces a method accepts.
pub const MAX_BOUNCES: u32 = 8;

/// `bounces`: indirect bounces (the hierarchical-radiosity methods and the path tracer); 0,
/// the default, until converged ([`crate::common::converge`]).
pub const BOUNCES: OptionSpec = OptionSpec {
    name: "bounces",
    help: "indirect bounces; 0 (the default): until a bounce adds at most 1% of the light, \
           at most 8",
    kind: OptionKind::Count {
        default: 0,
        min: 0,
        max: MAX_BOUNCES,
    },
};

/// `threshold`: the oracle threshold of the hierarchical traversal (§4.3).
pub const THRESHOLD: OptionSpec = OptionSpec {
    name: "threshold",
    help: "oracle threshold (§4.3): refine while a sender's tone-mapped bound is above it; \
           smaller is slower and closer",
    kind: OptionKind::Number {
        default: crate::radiosity::DEFAULT_THRESHOLD,
        min: 0.0,
    },
};

/// `links`: how the radiosity's bounces find their light once a light has been solved for
/// (`radiosity/links.rs`).
pub const LINKS: OptionSpec = OptionSpec {
    name: "links",
    help: "cached: from the second light on, every radiosity bounce multiplies the cuts and \
           visibilities stored (once) for the first; walk: every bounce walks the hierarchy \
           and queries the CSSM",
    kind: OptionKind::Choice {
        default: "cached",
        choices: &["cached", "walk"],
    },
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_found() {
        for (i, m) in METHODS.iter().enumerate() {
            assert!(METHODS[..i].iter().all(|o| o.name != m.name), "{}", m.name);
            assert_eq!(find(m.name).unwrap().name, m.name);
            for (j, o) in m.options.iter().enumerate() {
                assert!(
                    m.options[..j].iter().all(|p| p.name != o.name),
                    "{}",
                    o.name
                );
                assert!(o.check(o.kind.default()).is_ok(), "{}: default", o.name);
            }
        }
        let err = find("radiosity").unwrap_err().to_string();
        assert!(
            err.contains("unknown method") && err.contains("lightcuts"),
            "{err}"
        );
    }

    #[test]
    fn every_timing_row_is_a_valid_setting_beside_known_methods() {
        for m in METHODS {
            for row in m.timing.rows {
                let values = m
                    .parse_options(row.options)
                    .unwrap_or_else(|e| panic!("{} timing row '{}': {e}", m.name, row.label));
                m.resolve(&values)
                    .unwrap_or_else(|e| panic!("{} timing row '{}': {e}", m.name, row.label));
            }
            assert!(
                !m.timing.rows.is_empty() || !m.timing.about.is_empty(),
                "{}: a method without timing rows says where it is timed",
                m.name
            );
            for other in m.timing.compare_with {
                let other = find(other).unwrap();
                assert!(other.on_gpu() && !other.needs_cssm, "{}: {other}", m.name);
            }
        }
    }

    #[test]
    fn option_text_parses_by_kind_and_names_what_is_wrong() {
        let rsm = find("rsm").unwrap();
        let values = rsm.parse_options("visibility=none, paths=4").unwrap();
        assert_eq!(values.get("visibility"), Some(OptionValue::Choice("none")));
        assert_eq!(values.get("paths"), Some(OptionValue::Count(4)));
        assert_eq!(rsm.parse_options("").unwrap(), OptionValues::default());
        for (text, says) in [
            ("paths", "is not OPTION=VALUE"),
            ("bounce=2", "has no option 'bounce'"),
            ("paths=2,paths=3", "given twice"),
            ("paths=many", "whole number"),
            ("paths=2,", "'' is not OPTION=VALUE"),
        ] {
            let err = rsm.parse_options(text).unwrap_err();
            assert!(err.contains(says), "{text}: {err}");
        }
    }

    #[test]
    fn options_are_checked_once_with_their_ranges() {
        let lightcuts = find("lightcuts").unwrap();
        let mut values = OptionValues::default();
        values.set("bounces", OptionValue::Count(9));
        let err = lightcuts.resolve(&values).unwrap_err().to_string();
        assert!(err.contains("out of range 0..=8"), "{err}");
        values.set("bounces", OptionValue::Count(3));
        values.set("threshold", OptionValue::Number(-1.0));
        let err = lightcuts.resolve(&values).unwrap_err().to_string();
        assert!(err.contains("must be a number"), "{err}");
        values.set("threshold", OptionValue::Number(f32::NAN));
        assert!(lightcuts.resolve(&values).is_err());
        values.set("threshold", OptionValue::Number(0.5));
        let resolved = lightcuts.resolve(&values).unwrap();
        assert_eq!(resolved.count("bounces"), 3);
        assert_eq!(resolved.number("threshold"), 0.5);
        let mut unknown = OptionValues::default();
        unknown.set("samples", OptionValue::Count(4));
        let err = find("direct").unwrap().resolve(&unknown).unwrap_err();
        assert!(err.to_string().contains("no option 'samples'"), "{err}");
        let mut wrong = OptionValues::default();
        wrong.set("bounces", OptionValue::Number(2.0));
        assert!(lightcuts.resolve(&wrong).is_err());
    }

    #[test]
    fn options_parse_from_text() {
        let spec = BOUNCES;
        assert_eq!(spec.parse("3"), Ok(OptionValue::Count(3)));
        assert!(spec.parse("three").is_err());
        assert_eq!(THRESHOLD.parse("0.1"), Ok(OptionValue::Number(0.1)));
        let jitter = crate::lightcuts::METHOD.option("jitter").unwrap();
        assert_eq!(jitter.parse("on"), Ok(OptionValue::Switch(true)));
        assert!(jitter.parse("maybe").is_err());
    }

    #[test]
    fn help_lists_every_method_and_option() {
        let help = describe_methods();
        for m in METHODS {
            assert!(help.contains(m.name) && help.contains(m.summary), "{help}");
            for o in m.options {
                assert!(help.contains(o.help), "{help}");
            }
        }
    }
}
