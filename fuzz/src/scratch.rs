//! The built-in scenes, loaded from scratch copies of their files; the scratch directories of
//! the targets; the panics the library catches, let through to it; notes printed once.

use super::*;

/// The files of the built-in Cornell box (`scenes/cornell-box/`), `scene.toml` first.
pub const CORNELL_BOX: [(&str, &[u8]); 3] = [
    (
        "scene.toml",
        include_bytes!("../../scenes/cornell-box/scene.toml"),
    ),
    (
        "cornell-box.obj",
        include_bytes!("../../scenes/cornell-box/cornell-box.obj"),
    ),
    (
        "cornell-box.mtl",
        include_bytes!("../../scenes/cornell-box/cornell-box.mtl"),
    ),
];

/// The files of the built-in glossy Cornell box (`scenes/cornell-glossy/`), `scene.toml` first.
pub const CORNELL_GLOSSY: [(&str, &[u8]); 3] = [
    (
        "scene.toml",
        include_bytes!("../../scenes/cornell-glossy/scene.toml"),
    ),
    (
        "cornell-glossy.obj",
        include_bytes!("../../scenes/cornell-glossy/cornell-glossy.obj"),
    ),
    (
        "cornell-glossy.mtl",
        include_bytes!("../../scenes/cornell-glossy/cornell-glossy.mtl"),
    ),
];

/// The meshes of the built-in scenes, without their `scene.toml`s.
pub(crate) const MESHES: [(&str, &[u8]); 4] = [
    CORNELL_BOX[1],
    CORNELL_BOX[2],
    CORNELL_GLOSSY[1],
    CORNELL_GLOSSY[2],
];

/// The built-in Cornell box, loaded once per process (from a scratch copy of its files).
pub fn cornell_box() -> &'static Scene {
    static DIR: ScratchDir = ScratchDir::new("cornell-box", &CORNELL_BOX);
    static SCENE: OnceLock<Scene> = OnceLock::new();
    SCENE.get_or_init(|| {
        let dir = DIR.lock();
        Scene::load(dir.path()).expect("the built-in Cornell box loads")
    })
}

// ---------------------------------------------------------------------------------------------
// Scratch directories

/// This process's scratch directory: `cssm-fuzz-<pid>` in `/dev/shm` where it can be made
/// there, else in [`std::env::temp_dir`]. Made empty on first use; the directories of processes
/// that have gone (where `/proc` says so) are removed then. [`remove_scratch`] removes it.
pub(crate) fn scratch_root() -> &'static Path {
    static ROOT: OnceLock<PathBuf> = OnceLock::new();
    ROOT.get_or_init(|| {
        let name = format!("cssm-fuzz-{}", std::process::id());
        let mut bases = vec![std::env::temp_dir()];
        if Path::new("/dev/shm").is_dir() {
            bases.insert(0, PathBuf::from("/dev/shm"));
        }
        for base in bases {
            let root = base.join(&name);
            let _ = std::fs::remove_dir_all(&root); // a former process of the same PID
            if std::fs::create_dir_all(&root).is_ok() {
                remove_stale(&base);
                return root;
            }
        }
        panic!("cannot make a scratch directory {name} in /dev/shm or the temp directory");
    })
}

/// Removes the `cssm-fuzz-<pid>` directories of `base` whose process has gone.
pub(crate) fn remove_stale(base: &Path) {
    if !Path::new("/proc/self").exists() {
        return; // No procfs: no way to tell.
    }
    let Ok(entries) = std::fs::read_dir(base) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(|n| n.strip_prefix("cssm-fuzz-")) else {
            continue;
        };
        if pid.parse::<u32>().is_ok() && !Path::new("/proc").join(pid).exists() {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Removes this process's scratch directory (the fuzz targets never do; the next process
/// removes it when this one has gone).
pub fn remove_scratch() {
    let _ = std::fs::remove_dir_all(scratch_root());
}

/// A scratch directory of one target, made on first use with `files` in it, and locked while a
/// body uses it (the tests replay the targets on several threads).
pub(crate) struct ScratchDir {
    name: &'static str,
    files: &'static [(&'static str, &'static [u8])],
    path: Mutex<Option<PathBuf>>,
}

/// A [`ScratchDir`] in use.
pub(crate) struct Held<'a>(MutexGuard<'a, Option<PathBuf>>);

impl Held<'_> {
    pub(crate) fn path(&self) -> &Path {
        self.0.as_deref().expect("made on lock")
    }
}

impl ScratchDir {
    pub(crate) const fn new(
        name: &'static str,
        files: &'static [(&'static str, &'static [u8])],
    ) -> Self {
        ScratchDir {
            name,
            files,
            path: Mutex::new(None),
        }
    }

    pub(crate) fn lock(&self) -> Held<'_> {
        // A panic while it was held (a finding, in a test) leaves the directory usable.
        let mut guard = self.path.lock().unwrap_or_else(PoisonError::into_inner);
        let path = guard.get_or_insert_with(|| scratch_root().join(self.name));
        if !path.is_dir() {
            std::fs::create_dir_all(&*path).expect("make a scratch directory");
            for (name, bytes) in self.files {
                std::fs::write(path.join(name), bytes).expect("write a scratch file");
            }
        }
        Held(guard)
    }
}

// ---------------------------------------------------------------------------------------------
// Panics that the library catches, and notes

/// The OBJ loader runs tobj under `catch_unwind` ("tobj has a few panicking paths on malformed
/// input: turn a panic into a parse error"), but libFuzzer's panic hook aborts on any panic,
/// caught or not. This hook lets a panic *inside tobj* unwind to that `catch_unwind` (noting
/// where it happened, once); every other panic goes to the previous hook (libFuzzer's abort,
/// or the test harness's). A tobj panic that nothing catches still ends in libFuzzer's own
/// `catch_unwind` around the target, which aborts.
pub(crate) fn tolerate_caught_tobj_panics() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| match info.location() {
            Some(at) if at.file().contains("tobj-") => {
                let message = info
                    .payload()
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| info.payload().downcast_ref::<String>().cloned())
                    .unwrap_or_default();
                let at = format!("{}:{}", at.file(), at.line());
                note(
                    &at,
                    &format!("tobj panicked at {at} (caught by Scene::load): {message}"),
                );
            }
            _ => previous(info),
        }));
    });
}

/// Prints `message` to stderr the first time this process notes `key`.
pub fn note(key: &str, message: &str) {
    static SEEN: Mutex<Option<HashSet<String>>> = Mutex::new(None);
    let mut seen = SEEN.lock().unwrap_or_else(PoisonError::into_inner);
    if seen
        .get_or_insert_with(HashSet::new)
        .insert(key.to_string())
    {
        eprintln!("cssm-fuzz note: {message}");
    }
}
