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
//! - [`diagnose`]: the research diagnostics of `cssm diagnose` behind the query's and the
//!   radiosity's defaults, each on a `.cssm` file: which end of a pair to trust
//!   ([`diagnose::ends`]), what the sender filters cost ([`diagnose::filters`]), where the
//!   radiosity's indirect light loses against the path tracer's ([`diagnose::radiosity_bias`]).
//!
//! `reports/README.md` indexes what each report answers and the command that regenerates it.

pub mod diagnose;
pub mod report;

#[cfg(test)]
mod tests {
    /// `reports/README.md` indexes every report: a file or folder added to `reports/` without a
    /// line there fails here.
    #[test]
    fn the_reports_index_names_every_report() {
        let reports = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../reports");
        let index = std::fs::read_to_string(reports.join("README.md")).expect("reports/README.md");
        let mut missing = Vec::new();
        for entry in std::fs::read_dir(&reports).expect("reports/") {
            let name = entry.expect("an entry").file_name();
            let name = name.to_string_lossy();
            if name != "README.md" && !index.contains(name.as_ref()) {
                missing.push(name.into_owned());
            }
        }
        missing.sort();
        assert!(
            missing.is_empty(),
            "reports/README.md does not name {missing:?}"
        );
    }
}
