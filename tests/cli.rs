//! End-to-end tests of the `cssm` command line: bake, inspect, check, the reports, `cssm
//! compare` and its page in a browser, and every class of bad input (clear message, exit
//! status 2, no file left behind).

use std::{
    path::{Path, PathBuf},
    process::{Command, Output},
};

#[path = "cli/bake.rs"]
mod bake;
mod common;

use common::{cornell, stderr};
#[path = "cli/compare.rs"]
mod compare;
#[path = "cli/render.rs"]
mod render;
#[path = "cli/report.rs"]
mod report;

/// Runs `cssm`; a `render` that names no method draws the direct light
/// ([`common::direct_unless_named`]).
fn cssm(args: &[&str]) -> Output {
    let args = common::direct_unless_named(args);
    Command::new(env!("CARGO_BIN_EXE_cssm"))
        .args(args)
        .output()
        .expect("run cssm")
}

fn bake_small(scene: &Path, out: &Path) -> Output {
    cssm(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--atlas",
        "32",
        "--cube",
        "8",
        "--json",
    ])
}

/// Asserts a failed run: a clear refusal ([`common::assert_refused`]) and no output file.
fn assert_fails(o: &Output, needle: &str, out: &Path) {
    common::assert_refused(o, needle);
    assert!(!out.exists(), "a failed bake left {}", out.display());
}

fn write(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(name), text).unwrap();
}

#[test]
fn help_explains_every_command() {
    // Every command is listed with a line that says what it does.
    let o = cssm(&["--help"]);
    let text = String::from_utf8_lossy(&o.stdout);
    for (command, about) in [
        ("compare", "Render every method side by side"),
        ("report", "Measure the toolchain against the paper"),
        (
            "diagnose",
            "Take a baked file's visibility or radiosity apart",
        ),
    ] {
        assert!(
            text.lines()
                .any(|l| l.trim_start().starts_with(command) && l.contains(about)),
            "{command}: {text}"
        );
    }
    for cmd in [
        vec!["--help"],
        vec!["bake", "--help"],
        vec!["inspect", "--help"],
        vec!["check", "--help"],
        vec!["render", "--help"],
        vec!["report", "compression", "--help"],
    ] {
        let o = cssm(&cmd);
        assert!(o.status.success());
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains("Usage"), "{text}");
    }
    for cmd in [
        vec!["--help"],
        vec!["bake", "--help"],
        vec!["inspect", "--help"],
        vec!["check", "--help"],
        vec!["render", "--help"],
        vec!["report", "--help"],
        vec!["report", "compression", "--help"],
        vec!["report", "heads", "--help"],
        vec!["report", "church", "--help"],
        vec!["report", "error", "--help"],
        vec!["compare", "--help"],
        vec!["diagnose", "--help"],
    ] {
        let o = cssm(&cmd);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains("Example"), "{cmd:?}: {text}");
    }
}
