//! Runs inputs through a target's body without the fuzzer (no sanitizer, any toolchain) and
//! prints what the library said:
//!
//! ```text
//! cargo run --manifest-path fuzz/Cargo.toml --example replay -- TARGET FILE...
//! ```

fn main() {
    let mut args = std::env::args().skip(1);
    let target = args.next().unwrap_or_default();
    let Some(body) = cssm_fuzz::body(&target) else {
        eprintln!(
            "usage: replay TARGET FILE...; TARGET is one of {}",
            cssm_fuzz::TARGETS.join(", ")
        );
        std::process::exit(2);
    };
    for path in args {
        let data = std::fs::read(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        match body(&data) {
            Ok(()) => println!("{path}: accepted"),
            Err(e) => println!("{path}: refused: {e}"),
        }
    }
    cssm_fuzz::remove_scratch();
}
