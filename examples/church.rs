//! Writes the compression report's 3,700-face church (the Sibenik cathedral simplified with
//! meshoptimizer, `cssm::report::church`) into a directory, so that `cssm bake` and
//! `cssm check` can measure it outside the report (`reports/visibility.sh`).
//!
//! Usage: `cargo run --release --example church -- SIBENIK_DIR OUT_DIR`

use std::path::Path;

fn main() -> std::process::ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [sibenik, out] = args.as_slice() else {
        eprintln!("usage: church SIBENIK_DIR OUT_DIR");
        return std::process::ExitCode::from(2);
    };
    match cssm::report::church::build(Path::new(sibenik), Path::new(out)) {
        Ok(c) => {
            println!(
                "{}: {} faces (from {})",
                c.dir.display(),
                c.faces,
                c.faces_in
            );
            std::process::ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
