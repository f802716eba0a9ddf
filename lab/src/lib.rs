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
//! - [`measure`]: the engine of `cssm report error` and `cssm compare` that renders what those
//!   reports measure: the reference path tracer's image in two halves and its cache
//!   ([`measure::reference`]), each method variant's image with its GPU times and memory
//!   ([`measure::render`]), and each command's run ([`measure::error_run`],
//!   [`measure::compare_run`]); the command passes in its scene loading and bake
//!   ([`measure::Host`]).
//! - [`diagnose`]: the research diagnostics of `cssm diagnose` behind the query's and the
//!   radiosity's defaults, each on a `.cssm` file: which end of a pair to trust
//!   ([`diagnose::ends`]), what the sender filters cost ([`diagnose::filters`]), where the
//!   radiosity's indirect light loses against the path tracer's ([`diagnose::radiosity_bias`]).
//!
//! `reports/README.md` indexes what each report answers and the command that regenerates it.

pub mod diagnose;
pub mod measure;
pub mod report;

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    /// The repository's root.
    fn root() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
    }

    /// Every file under `dir` (build outputs and version control left out), as paths from the
    /// root with `/` between components.
    fn files(dir: &Path, from_root: &str, out: &mut Vec<String>) {
        for entry in std::fs::read_dir(dir).expect("a readable folder") {
            let entry = entry.expect("an entry");
            let name = entry.file_name().to_string_lossy().into_owned();
            if matches!(name.as_str(), "target" | ".git" | ".carry") {
                continue;
            }
            let path = format!("{from_root}{name}");
            if entry.file_type().expect("a file type").is_dir() {
                files(&entry.path(), &format!("{path}/"), out);
            } else {
                out.push(path);
            }
        }
    }

    /// The paths of Rust, WGSL and shell files that `text` names in backticks (`a/b.rs`, also
    /// inside `a/b.rs::Item`).
    fn named_sources(text: &str) -> Vec<&str> {
        let mut named = Vec::new();
        for quoted in text.split('`').skip(1).step_by(2) {
            let is_path_char = |c: char| c.is_ascii_alphanumeric() || "_./-".contains(c);
            for word in quoted.split(|c: char| !is_path_char(c)) {
                let word = word.trim_start_matches("./");
                if [".rs", ".wgsl", ".sh"].iter().any(|e| word.ends_with(e)) {
                    named.push(word);
                }
            }
        }
        named
    }

    /// docs/architecture.md is the map of the code: every source file it names exists (by its
    /// path from the root, or from a folder the text is in, such as `runtime/src/`), and every
    /// WGSL module of the runtime is on it by its path in `runtime/src/`. A file moved or split
    /// without the map following fails here.
    #[test]
    fn the_architecture_map_names_files_that_exist_and_every_shader() {
        let map = std::fs::read_to_string(root().join("docs/architecture.md")).expect("the map");
        let mut all = Vec::new();
        files(&root(), "", &mut all);
        let mut wrong: Vec<String> = named_sources(&map)
            .into_iter()
            .filter(|named| {
                !all.iter()
                    .any(|f| f == named || f.ends_with(&format!("/{named}")))
            })
            .map(|named| format!("names {named}, which is no file"))
            .collect();
        for wgsl in all.iter().filter(|f| f.ends_with(".wgsl")) {
            if let Some(in_runtime) = wgsl.strip_prefix("runtime/src/")
                && !map.contains(in_runtime)
            {
                wrong.push(format!("does not name {in_runtime}"));
            }
        }
        wrong.sort();
        wrong.dedup();
        assert!(
            wrong.is_empty(),
            "docs/architecture.md {}",
            wrong.join("\n")
        );
    }

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
