//! The `cssm` command line: a thin layer over the `cssm-formats`, `cssm-bake` and
//! `cssm-runtime` libraries. [`cli`] holds the clap definitions and turns each command's
//! arguments into a config of library types, checked by the libraries; `bake_cmd`,
//! `check_cmd`, `render` and `view` (`cssm view`, the window) run the commands; `inspect` and
//! the reports are here, `cssm report error` and `cssm compare` run by the lab's engine
//! ([`cssm::measure`]) with the command's scene loading and bake ([`CommandHost`]). What
//! `bake`, `inspect` and `check` print, text or `--json`, is [`cssm::summary`].
//!
//! Exit codes: 0 success, 1 a check ran and failed its threshold, 2 an error.

use std::{
    path::{Path, PathBuf},
    process::ExitCode,
};

mod animate;
mod bake_cmd;
mod check_cmd;
mod cli;
mod render;
mod view;

use clap::Parser;
use cli::{ChurchArgs, Command, HeadsArgs, InspectArgs, ReportCommand};
use cssm::{formats, summary::InspectSummary};
use formats::{CssmFile, Scene};

fn main() -> ExitCode {
    // A closed standard output (`cssm inspect f | head -1`) ends the process quietly, as it
    // does `cat`, instead of making `println!` panic; every file is written atomically, so
    // nothing is half-written by it.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to its default, before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = cli::Cli::parse();
    let _ = LOAD_OPTIONS.set(formats::LoadOptions {
        files_outside: cli.allow_outside_files,
    });
    let command = cli.command;
    // Before any thread exists (the set_var in it needs that): every command that may open the
    // GPU.
    // The private directory, if one was made, is removed when `main` returns.
    let _wsi_dir = matches!(
        command,
        Command::Render(_)
            | Command::View(_)
            | Command::Compare(_)
            | Command::Report(ReportCommand::Error(_))
    )
    .then(quiet_mesa_wsi)
    .flatten();
    let result = match command {
        Command::Bake(args) => args.config().and_then(bake_cmd::run_bake),
        Command::Merge(args) => bake_cmd::run_merge(args),
        Command::Inspect(args) => run_inspect(args),
        Command::Check(args) => check_cmd::run_check(args.config()),
        Command::Render(args) => args.config().and_then(render::run_render),
        Command::View(args) => args.config().and_then(view::run_view),
        Command::Report(ReportCommand::Compression(args)) => run_report(args),
        Command::Report(ReportCommand::Heads(args)) => run_heads(args),
        Command::Report(ReportCommand::Church(args)) => run_church(args),
        Command::Report(ReportCommand::Error(args)) => args
            .config()
            .and_then(|config| {
                cssm::measure::error_run::run(&config, &command_line(), &CommandHost)
            })
            .map(|()| ExitCode::SUCCESS),
        Command::Compare(args) => args
            .config()
            .and_then(|config| {
                cssm::measure::compare_run::run(&config, &command_line(), &CommandHost)
            })
            .map(|()| ExitCode::SUCCESS),
        Command::Diagnose(command) => {
            let scenes = LOAD_OPTIONS.get().copied().unwrap_or_default();
            cssm::diagnose::run(&command, scenes).map(|()| ExitCode::SUCCESS)
        }
    };
    match result {
        Ok(code) => code,
        Err(message) => {
            eprintln!("error: {}", printable(&message));
            ExitCode::from(2)
        }
    }
}

type CliResult = Result<ExitCode, String>;

/// The scene directory given, else the built-in Cornell box's.
fn scene_dir(scene: Option<PathBuf>) -> Result<PathBuf, String> {
    match scene {
        Some(dir) => Ok(dir),
        None => cssm::builtin::cornell_box()
            .map_err(|e| format!("cannot prepare the built-in Cornell box: {e}")),
    }
}

/// How scenes are loaded, from the global flags (`--allow-outside-files`); set once in `main`.
static LOAD_OPTIONS: std::sync::OnceLock<formats::LoadOptions> = std::sync::OnceLock::new();

/// Loads the scene at `dir` with a spinner on a terminal (parsing a large OBJ takes seconds)
/// and prints its warnings.
fn load_scene(dir: &Path) -> Result<Scene, String> {
    let spinner = indicatif::ProgressBar::new_spinner()
        .with_message(format!("loading {}", printable(&dir.display().to_string())));
    spinner.enable_steady_tick(std::time::Duration::from_millis(200));
    let options = LOAD_OPTIONS.get().copied().unwrap_or_default();
    let scene = Scene::load_with(dir, options).map_err(|e| e.to_string());
    spinner.finish_and_clear();
    let scene = scene?;
    for w in &scene.warnings {
        eprintln!("warning: {}", printable(w));
    }
    Ok(scene)
}

/// What the lab's runs of `cssm report error` and `cssm compare` take from the command: the
/// built-in scenes, and the command's scene loading and bake with their spinner and progress
/// bar.
struct CommandHost;

impl cssm::measure::Host for CommandHost {
    fn builtin_scenes(&self) -> std::io::Result<Vec<PathBuf>> {
        Ok(vec![
            cssm::builtin::cornell_box()?,
            cssm::builtin::cornell_glossy()?,
        ])
    }

    fn load_scene(&self, dir: &Path) -> Result<Scene, String> {
        load_scene(dir)
    }

    fn bake(
        &self,
        scene: &Scene,
        options: &cssm::bake::BakeOptions,
    ) -> Result<cssm::bake::Baked, cssm::bake::BakeError> {
        bake_cmd::bake_with_progress(scene, options)
    }
}

/// The command line as typed (`cssm` and its arguments), for a report to name.
fn command_line() -> String {
    std::iter::once("cssm".to_string())
        .chain(std::env::args().skip(1))
        .collect::<Vec<_>>()
        .join(" ")
}

fn read_file(path: &Path) -> Result<CssmFile, String> {
    formats::cssm::read(path).map_err(|e| e.to_string())
}

/// Mesa's Vulkan drivers print "error: XDG_RUNTIME_DIR is invalid or not set" on machines
/// without a desktop session although a headless render never needs it; point it at a private
/// directory of ours (mode 0700; the caller holds it until the command ends) so users are not
/// alarmed by an error that is not one.
fn quiet_mesa_wsi() -> Option<tempfile::TempDir> {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return None;
    }
    let dir = tempfile::Builder::new()
        .prefix("cssm-runtime-")
        .tempdir()
        .ok()?;
    // SAFETY: called by `main` before any other thread exists (no spinner, no rayon pool, no
    // GPU instance yet).
    unsafe { std::env::set_var("XDG_RUNTIME_DIR", dir.path()) };
    Some(dir)
}

/// Fails early, before any work, when `output` cannot or must not be written: what is there is
/// not a regular file (a device, a FIFO, a directory: [`formats::cssm::destination`]), it is one
/// of the command's own `inputs` (through any link), its name is too long, or its directory
/// does not exist or cannot be written.
/// `name` inside the `--out` directory `out`, never through a link planted there
/// ([`formats::files::output_in`]; with `directory`, [`formats::files::output_dir_in`]).
fn out_path(out: &Path, name: &str, directory: bool) -> Result<PathBuf, String> {
    let path = if directory {
        formats::files::output_dir_in(out, name)
    } else {
        formats::files::output_in(out, name)
    };
    path.map_err(|e| format!("--out: {e}"))
}

fn check_writable(output: &Path, inputs: &[PathBuf]) -> Result<(), String> {
    let target = formats::cssm::destination(output).map_err(|e| match e {
        formats::cssm::CssmError::Io { error, .. } => {
            format!("cannot write {}: {error}", output.display())
        }
        other => format!("cannot write {}: {other}", output.display()),
    })?;
    if let Some(input) = inputs.iter().find(|input| same_file(&target, input)) {
        return Err(format!(
            "cannot write {}: it is {}, which this command reads; write the output elsewhere",
            output.display(),
            input.display()
        ));
    }
    let parent = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !parent.is_dir() {
        return Err(format!(
            "cannot write {}: directory {} does not exist",
            output.display(),
            parent.display()
        ));
    }
    let probe = parent.join(format!(".cssm-write-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").map_err(|e| format!("cannot write {}: {e}", output.display()))?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Whether `a` and `b` are the same file (the same device and inode: through links, `..` and
/// hard links alike). A path that does not exist is no file.
fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        #[cfg(unix)]
        (Ok(ma), Ok(mb)) => {
            use std::os::unix::fs::MetadataExt;
            (ma.dev(), ma.ino()) == (mb.dev(), mb.ino())
        }
        #[cfg(not(unix))]
        (Ok(_), Ok(_)) => std::fs::canonicalize(a).ok() == std::fs::canonicalize(b).ok(),
        _ => false,
    }
}

/// `text` safe to print on a terminal: control characters (escape sequences among them, which
/// a crafted scene name or file name could carry) written as `\u{..}`; newlines and tabs kept.
fn printable(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_control() && c != '\n' && c != '\t' {
                c.escape_unicode().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

fn run_inspect(args: InspectArgs) -> CliResult {
    let file = match formats::cssm::read(&args.file) {
        Ok(file) => file,
        // A chunk of a chunked bake: which slice it holds (what a farm's operator asks).
        Err(e) if matches!(e.root(), formats::cssm::CssmError::IsChunk) => {
            return inspect_chunk(&args);
        }
        Err(e) => return Err(e.to_string()),
    };
    let file_bytes = std::fs::metadata(&args.file)
        .map_err(|e| format!("{}: {e}", args.file.display()))?
        .len();
    let summary = InspectSummary::new(&args.file, &file, file_bytes);
    if args.json {
        println!("{}", summary.to_json());
    } else {
        println!("{summary}");
    }
    Ok(ExitCode::SUCCESS)
}

fn inspect_chunk(args: &InspectArgs) -> CliResult {
    let chunk = formats::cssm::read_chunk(&args.file).map_err(|e| e.to_string())?;
    let file_bytes = std::fs::metadata(&args.file)
        .map_err(|e| format!("{}: {e}", args.file.display()))?
        .len();
    let summary = cssm::summary::ChunkSummary::new(&args.file, &chunk, None, file_bytes);
    if args.json {
        println!("{}", summary.to_json());
    } else {
        println!("{summary}");
    }
    Ok(ExitCode::SUCCESS)
}

fn run_report(args: cssm::report::CompressionArgs) -> CliResult {
    let exe = std::env::current_exe().map_err(|e| format!("cannot find the cssm binary: {e}"))?;
    let command = command_line();
    let cornell = cssm::builtin::cornell_box()
        .map_err(|e| format!("cannot prepare the built-in Cornell box: {e}"))?;
    let report = cssm::report::run(&args, &exe, &command, &cornell)?;
    let done = report.rows.iter().filter(|r| r.outcome.is_ok()).count();
    println!(
        "wrote {} ({done} of {} rows ran)",
        args.out.join("compression.md").display(),
        report.rows.len()
    );
    Ok(ExitCode::SUCCESS)
}

fn run_heads(args: HeadsArgs) -> CliResult {
    for part in ["teapot", "bunny"] {
        let dir = args.scenes.join(part);
        if !dir.is_dir() {
            return Err(format!(
                "{}: not a directory; the heads scene needs the teapot and the bunny (pass --scenes)",
                dir.display()
            ));
        }
    }
    let cornell = scene_dir(None)?;
    let heads = cssm::report::heads::build(&cornell, &args.scenes, &args.out)?;
    println!(
        "wrote {} ({} faces: Cornell box {}, teapot {}, bunny {})",
        heads.dir.display(),
        heads.faces.iter().sum::<usize>(),
        heads.faces[0],
        heads.faces[1],
        heads.faces[2]
    );
    Ok(ExitCode::SUCCESS)
}

fn run_church(args: ChurchArgs) -> CliResult {
    let sibenik = args.scenes.join("sibenik");
    if !sibenik.is_dir() {
        return Err(format!(
            "{}: not a directory; the church is built from the Sibenik cathedral (pass --scenes)",
            sibenik.display()
        ));
    }
    let church = cssm::report::church::build(&sibenik, &args.out)?;
    println!(
        "wrote {} ({} faces, simplified from {})",
        church.dir.display(),
        church.faces,
        church.faces_in
    );
    Ok(ExitCode::SUCCESS)
}
