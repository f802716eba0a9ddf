//! What the command-line test binaries share (each includes it as `mod common;`).
//!
//! Each binary uses some of these, so the others are dead code in it.
#![allow(dead_code)]

use std::{
    path::{Path, PathBuf},
    process::Output,
};

/// The built-in Cornell box's scene directory in this checkout.
pub fn cornell() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box")
}

/// A finished command's standard error, as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A clear refusal: exit status 2, `needle` in the message, no panic.
pub fn assert_refused(o: &Output, needle: &str) {
    assert_eq!(o.status.code(), Some(2), "stderr: {}", stderr(o));
    assert!(
        stderr(o).contains(needle),
        "expected '{needle}' in: {}",
        stderr(o)
    );
    assert!(!stderr(o).contains("panicked"), "{}", stderr(o));
}

/// `args` with `--method direct` added when they are a `cssm render` that names no method: the
/// default, lightmap, bakes and iterates its radiosity first (seconds a render on lavapipe), and
/// these tests are about something else. The default's own test is
/// `tests/gpu/emissive.rs::a_room_lit_by_emitters_renders_lit_and_converged_with_no_options`.
pub fn direct_unless_named<'a>(args: &[&'a str]) -> Vec<&'a str> {
    let mut args = args.to_vec();
    if args.first() == Some(&"render") && !args.iter().any(|a| a.starts_with("--method")) {
        args.extend(["--method", "direct"]);
    }
    args
}
