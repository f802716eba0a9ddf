//! What the command-line test binaries share (each includes it as `mod common;`).

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
