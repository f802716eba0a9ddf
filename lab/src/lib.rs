//! The lab of the CSSM toolchain: what measures the bake and the methods, apart from the
//! libraries a user embeds (`cssm-formats`, `cssm-bake`, `cssm-runtime`) and from the `cssm`
//! command, which calls it for `cssm report` and `cssm compare`.
//!
//! - [`report`]: the compression report against the paper's Tables 2 and 3 (`cssm report
//!   compression`, `benches/compression.rs`) with its scenes ([`report::heads`],
//!   [`report::church`]); every method's error against the reference path tracer
//!   ([`report::error`]: relative RMSE and FLIP, the one place the project computes them, shared
//!   with the golden-image tests; [`report::error_write`]: `cssm report error`'s files); and the
//!   comparison page of `cssm compare` ([`report::compare`], [`report::compare_html`]).
//!
//! `reports/README.md` indexes what each report answers and the command that regenerates it.

pub mod report;
