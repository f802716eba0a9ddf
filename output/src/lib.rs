//! What the `cssm` command prints: the summaries of `cssm bake`, `cssm inspect` and
//! `cssm check`, as text or as one line of JSON ([`summary`]), and a bake error spelled in the
//! command's flags ([`flag_error`]).
//!
//! These are the command's output, not the bake's: a program that embeds `cssm-bake` gets its
//! figures as [`cssm_bake::BakeStats`] and its errors as [`cssm_bake::BakeError`], and prints them
//! its own way. The command (`src/`, through `cssm::summary` and `cssm::flag_error`) and the
//! lab (`cssm-lab`, whose compression report runs `cssm bake` and `cssm check` as child
//! processes and reads their `--json` back into these types) share this crate, so the two spell
//! the same output alike.
#![warn(missing_docs)]

pub mod summary;

use cssm_bake::{BakeError, BakeParameter};

/// A bake error as the command line says it: a parameter by the flag that sets it (`cssm bake`
/// and `cssm report compression` spell them alike), any other error as the library does.
///
/// ```
/// use cssm_bake::BakeOptions;
///
/// let e = BakeOptions { atlas_resolution: 16, ..Default::default() }.check().unwrap_err();
/// assert_eq!(cssm_output::flag_error(&e), "--atlas 16 is out of range 32..=1024");
/// ```
pub fn flag_error(e: &BakeError) -> String {
    match e {
        BakeError::Parameter {
            parameter,
            value,
            problem,
        } => {
            let flag = match parameter {
                BakeParameter::AtlasResolution => "--atlas",
                BakeParameter::CubeResolution => "--cube",
                BakeParameter::Near => "--near",
            };
            format!("{flag} {value} {problem}")
        }
        other => other.to_string(),
    }
}
