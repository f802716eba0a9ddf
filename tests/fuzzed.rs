//! Replays what the fuzzers found (`tests/fuzzed/<target>/`, see its README) through the bodies
//! of the fuzz targets (`fuzz/src/lib.rs`, included here as it is), together with the seeds
//! that need no bake (the built-in scenes' files, hand-written inputs, a tiny hand-made CSSM):
//! none may panic or allocate more than libFuzzer's memory limit at once ([`MAX_ALLOCATION`]),
//! and the seeds named `ok-...` must be accepted. One test per target; a failure names every
//! input that failed and why.
//!
//! An input that aborts the process (a stack overflow, an allocation failure) takes the test
//! binary down before it can say which; `CSSM_FUZZED_TRACE=1` prints each input's name first.

#[path = "../fuzz/src/lib.rs"]
mod bodies;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The largest single allocation an input may ask for: the limit of the fuzz runs
/// (`-rss_limit_mb=2048`, which libFuzzer also applies to every `malloc`). Without the
/// sanitizer a huge zeroed allocation that is never touched costs no memory, so the fuzzer's
/// out-of-memory findings would replay clean here; [`Largest`] sees them.
const MAX_ALLOCATION: usize = 2048 << 20;

/// The system allocator, noting the largest allocation of each thread since [`take_largest`].
struct Largest;

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

fn note_size(size: usize) {
    // `try_with`: no panic in the allocator while the thread is being torn down.
    let _ = LARGEST.try_with(|l| l.set(l.get().max(size)));
}

/// The largest allocation this thread made since the last call.
fn take_largest() -> usize {
    LARGEST.with(|l| l.replace(0))
}

// SAFETY: every call is passed on to `System` unchanged; noting a size touches only a
// thread-local `Cell` (const-initialised, no destructor), which allocates nothing.
unsafe impl GlobalAlloc for Largest {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note_size(layout.size());
        // SAFETY: the caller's guarantees, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note_size(layout.size());
        // SAFETY: the caller's guarantees, passed on.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note_size(new_size);
        // SAFETY: the caller's guarantees, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's guarantees, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Largest = Largest;

/// Replays every input of `target`; panics listing those that failed.
fn replay(target: &str) {
    let _finish = Finish;
    let body = bodies::body(target).expect("a fuzz target");
    let mut inputs: Vec<(String, Vec<u8>, bool)> = fuzzed_files(target)
        .into_iter()
        .map(|(name, bytes)| (name, bytes, false))
        .collect();
    assert!(
        inputs.iter().all(|(name, ..)| !name.ends_with(".cssm")),
        "*.cssm is gitignored: name the files of tests/fuzzed/{target}/ without that extension"
    );
    for (name, bytes) in bodies::seeds(target) {
        let must_accept = name.starts_with("ok-");
        inputs.push((
            format!("seed `{name}` of fuzz/src/lib.rs"),
            bytes,
            must_accept,
        ));
    }
    assert!(!inputs.is_empty(), "nothing to replay for {target}");
    record_panic_locations();
    let trace = std::env::var_os("CSSM_FUZZED_TRACE").is_some();
    let mut failures = Vec::new();
    for (name, data, must_accept) in &inputs {
        if trace {
            // Straight to the stream, past the test harness's capture: an abort loses that.
            let _ = writeln!(std::io::stderr(), "{target}: {name}");
        }
        take_largest();
        PANIC_AT.with(|p| p.take());
        let outcome = std::panic::catch_unwind(|| body(data));
        let largest = take_largest();
        if largest > MAX_ALLOCATION {
            failures.push(format!(
                "{name}: allocated {largest} bytes at once, more than the fuzzer's limit of \
                 {MAX_ALLOCATION}"
            ));
        }
        match outcome {
            Ok(Ok(())) => {}
            Ok(Err(e)) if *must_accept => failures.push(format!("{name}: refused: {e}")),
            Ok(Err(_)) => {}
            Err(panic) => {
                let message = panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "(no message)".into());
                let at = PANIC_AT.with(|p| p.take()).unwrap_or_default();
                failures.push(format!("{name}: panicked at {at}: {message}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of the {} inputs of the fuzz target {target} failed (replay one with `cargo +nightly \
         fuzz run {target} FILE` from the repository root, see tests/fuzzed/README.md):\n  {}",
        failures.len(),
        inputs.len(),
        failures.join("\n  ")
    );
}

thread_local! {
    /// Where the last panic of this thread happened (`file:line:column`).
    static PANIC_AT: std::cell::RefCell<Option<String>> = const { std::cell::RefCell::new(None) };
}

/// Installs (once) a panic hook that notes where each panic happened before the previous hook
/// reports it, so that a failure names the line as well as the message.
fn record_panic_locations() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let at = info.location().map(|l| l.to_string());
            let _ = PANIC_AT.try_with(|p| p.replace(at));
            previous(info);
        }));
    });
}

/// The files of `tests/fuzzed/<target>/`, by name, with their bytes.
fn fuzzed_files(target: &str) -> Vec<(String, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzzed")
        .join(target);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new(); // No finding kept for this target.
    };
    let mut files: Vec<(String, Vec<u8>)> = entries
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.is_file())
        .filter(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        })
        .map(|p| {
            let name = format!(
                "tests/fuzzed/{target}/{}",
                p.file_name().expect("a file name").to_string_lossy()
            );
            let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
            (name, bytes)
        })
        .collect();
    files.sort();
    files
}

/// Counts the finished tests; the last one removes the bodies' scratch directory (a run of some
/// of them leaves it to the next process, which removes it).
struct Finish;

impl Drop for Finish {
    fn drop(&mut self) {
        static FINISHED: AtomicUsize = AtomicUsize::new(0);
        if FINISHED.fetch_add(1, Ordering::SeqCst) + 1 == bodies::TARGETS.len() {
            bodies::remove_scratch();
        }
    }
}

#[test]
fn cssm_header() {
    replay("cssm_header");
}

#[test]
fn cssm_file() {
    replay("cssm_file");
}

#[test]
fn cssm_payload() {
    replay("cssm_payload");
}

#[test]
fn scene_toml() {
    replay("scene_toml");
}

#[test]
fn obj_mtl() {
    replay("obj_mtl");
}

#[test]
fn gltf() {
    replay("gltf");
}

/// Every folder of `tests/fuzzed/` is a target's (a misspelt one would never be replayed).
#[test]
fn fuzzed_folders_are_targets() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzzed");
    for entry in std::fs::read_dir(&dir).expect("tests/fuzzed/") {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            let name = path.file_name().expect("a name").to_string_lossy();
            assert!(
                bodies::body(&name).is_some(),
                "tests/fuzzed/{name}/ is no fuzz target's folder (targets: {})",
                bodies::TARGETS.join(", ")
            );
        }
    }
}
