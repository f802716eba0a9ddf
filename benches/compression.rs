//! The compression report as a benchmark harness: runs the same code as
//! `cssm report compression` (`cssm::report`), with the same flags after `--`.
//!
//! `cargo bench --bench compression -- --quick --out /tmp` (a smoke run: atlas 32 and 64, cube
//! 8); `cargo bench --bench compression -- --scene cornell` for the Cornell box's rows;
//! `reports/compression.sh` for the published report.

use clap::Parser;

#[derive(Parser)]
#[command(name = "compression")]
struct Args {
    #[command(flatten)]
    report: cssm::report::CompressionArgs,
    /// Passed by `cargo bench`; ignored.
    #[arg(long, hide = true)]
    bench: bool,
}

fn main() {
    let args = Args::parse();
    let exe = std::path::PathBuf::from(env!("CARGO_BIN_EXE_cssm"));
    let command = std::iter::once("cargo bench --bench compression --".to_string())
        .chain(std::env::args().skip(1).filter(|a| a != "--bench"))
        .collect::<Vec<_>>()
        .join(" ");
    let cornell = cssm::builtin::cornell_box().expect("built-in Cornell box");
    match cssm::report::run(&args.report, &exe, &command, &cornell) {
        Ok(report) => println!(
            "wrote {} ({} rows)",
            args.report.out.join("compression.md").display(),
            report.rows.len()
        ),
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(2);
        }
    }
}
