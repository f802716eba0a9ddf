//! Opening what the tool reads: every input is opened as a regular file whose size is known
//! before a byte is read. A FIFO would block the open (a hang), a device like `/dev/zero`
//! would never end (memory without bound), a directory is not a file: each is refused with a
//! message that says what the path is.

use std::{fs::File, io, path::Path};

/// What a path that is not a regular file is, in words (`"a FIFO (named pipe)"`); `None` for a
/// regular file.
pub fn kind_of(metadata: &std::fs::Metadata) -> Option<&'static str> {
    let t = metadata.file_type();
    if t.is_file() {
        return None;
    }
    if t.is_dir() {
        return Some("a directory");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return Some("a FIFO (named pipe)");
        }
        if t.is_char_device() {
            return Some("a character device");
        }
        if t.is_block_device() {
            return Some("a block device");
        }
        if t.is_socket() {
            return Some("a socket");
        }
    }
    Some("not a regular file")
}

/// Opens `path` (through links) for reading if it is a regular file, with its size. The type
/// is checked before the open (opening a FIFO blocks until a writer comes) and again on the
/// open file.
///
/// # Errors
/// The open's own error (not found, permission), or [`io::ErrorKind::InvalidInput`] saying what
/// the path is when it is not a regular file.
///
/// ```
/// # let dir = tempfile::tempdir().unwrap();
/// let e = cssm_formats::files::open_regular(dir.path()).unwrap_err();
/// assert_eq!(e.to_string(), "it is a directory, not a file");
/// ```
pub fn open_regular(path: &Path) -> io::Result<(File, u64)> {
    let not_a_file = |kind: &str| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("it is {kind}, not a file"),
        )
    };
    if let Some(kind) = kind_of(&std::fs::metadata(path)?) {
        return Err(not_a_file(kind));
    }
    let file = File::open(path)?;
    let metadata = file.metadata()?;
    if let Some(kind) = kind_of(&metadata) {
        return Err(not_a_file(kind));
    }
    Ok((file, metadata.len()))
}

/// Reads the whole of `path` if it is a regular file of at most `limit` bytes, reading at most
/// `limit + 1` bytes whatever the file claims (it may grow while being read).
///
/// # Errors
/// As [`open_regular`], and [`io::ErrorKind::FileTooLarge`] naming the size and the limit.
pub fn read_bounded(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    use io::Read;
    let (file, size) = open_regular(path)?;
    let too_large = |size: u64| {
        io::Error::new(
            io::ErrorKind::FileTooLarge,
            format!("the file is {size} bytes, more than the {limit} this reads"),
        )
    };
    if size > limit {
        return Err(too_large(size));
    }
    let mut bytes = Vec::new();
    // A failed reservation is the machine's memory, not the file's size against the limit.
    bytes.try_reserve_exact(size as usize).map_err(|_| {
        io::Error::new(
            io::ErrorKind::OutOfMemory,
            format!("cannot reserve {size} bytes of memory to read it"),
        )
    })?;
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}

/// The path of `name` inside the output directory `out`, ready to be written by a command that
/// writes fixed names there (`index.html`, `images/SCENE/x.png`): the directories on the way are
/// created, and neither they nor the file may be a symbolic link, the file only a regular file
/// or absent. A link planted in `out` under one of those names would otherwise have the command
/// write wherever it points. `out` itself is the user's choice and may be a link. `name` is
/// split at `/`; a component that is empty, `.` or `..` is refused.
///
/// # Errors
/// [`io::ErrorKind::InvalidInput`] naming the path and what it is; a directory's creation error.
///
/// ```
/// # let dir = tempfile::tempdir().unwrap();
/// # #[cfg(unix)] {
/// std::os::unix::fs::symlink("/elsewhere", dir.path().join("index.html")).unwrap();
/// let e = cssm_formats::files::output_in(dir.path(), "index.html").unwrap_err();
/// assert!(e.to_string().ends_with("index.html is a symbolic link: the tool writes its own \
///     files in an output directory only as new or regular files (remove it or choose another \
///     directory)"));
/// let png = cssm_formats::files::output_in(dir.path(), "images/a/b.png").unwrap();
/// assert!(dir.path().join("images/a").is_dir() && !png.exists());
/// # }
/// ```
pub fn output_in(out: &Path, name: &str) -> io::Result<std::path::PathBuf> {
    output_walk(out, name, false)
}

/// The directory `name` inside the output directory `out`, created if missing, checked as
/// [`output_in`] checks the way to a file.
///
/// # Errors
/// As [`output_in`].
pub fn output_dir_in(out: &Path, name: &str) -> io::Result<std::path::PathBuf> {
    output_walk(out, name, true)
}

fn output_walk(out: &Path, name: &str, directory: bool) -> io::Result<std::path::PathBuf> {
    let refuse = |path: &Path, what: &str| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "{} {what}: the tool writes its own files in an output directory only as new or \
                 regular files (remove it or choose another directory)",
                path.display()
            ),
        )
    };
    let named =
        |path: &Path, e: io::Error| io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    std::fs::create_dir_all(out).map_err(|e| named(out, e))?;
    let components: Vec<&str> = name.split('/').collect();
    if components
        .iter()
        .any(|c| c.is_empty() || *c == "." || *c == "..")
    {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{name:?} is not a plain relative name"),
        ));
    }
    let mut path = out.to_path_buf();
    for (i, component) in components.iter().enumerate() {
        path.push(component);
        let last = i + 1 == components.len();
        match std::fs::symlink_metadata(&path) {
            Ok(m) if m.file_type().is_symlink() => return Err(refuse(&path, "is a symbolic link")),
            Ok(m) if last && !directory => {
                if let Some(kind) = kind_of(&m) {
                    return Err(refuse(&path, &format!("is {kind}")));
                }
            }
            Ok(m) if !m.is_dir() => return Err(refuse(&path, "is not a directory")),
            Ok(_) => {}
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                if !last || directory {
                    std::fs::create_dir(&path).map_err(|e| named(&path, e))?;
                }
            }
            Err(e) => return Err(named(&path, e)),
        }
    }
    Ok(path)
}

/// `name` (a scene's or a method's) as one safe file-name component: path separators, `:` and
/// control characters become `_`, leading dots are dropped (no hidden file, no `..`), at most
/// 200 bytes are kept, and an empty result is `scene`. Default output names are built from
/// it, so a crafted scene name cannot write outside the directory it is meant for.
///
/// ```
/// assert_eq!(cssm_formats::files::safe_file_stem("Cornell box"), "Cornell box");
/// assert_eq!(cssm_formats::files::safe_file_stem("../../etc/passwd"), "_.._etc_passwd");
/// assert_eq!(cssm_formats::files::safe_file_stem("/abs\u{1b}[31m"), "_abs_[31m");
/// assert_eq!(cssm_formats::files::safe_file_stem(".."), "scene");
/// assert_eq!(cssm_formats::files::safe_file_stem(""), "scene");
/// ```
pub fn safe_file_stem(name: &str) -> String {
    let mapped: String = name
        .chars()
        .map(|c| match c {
            '/' | '\\' | ':' => '_',
            c if c.is_control() => '_',
            c => c,
        })
        .collect();
    let mut stem = mapped.trim_start_matches('.').to_string();
    if stem.len() > 200 {
        let mut end = 200;
        while !stem.is_char_boundary(end) {
            end -= 1;
        }
        stem.truncate(end);
    }
    if stem.trim().is_empty() {
        "scene".into()
    } else {
        stem
    }
}

/// `bytes` in binary units (B, KiB, MiB, GiB, TiB) with `decimals` digits after the point;
/// whole bytes below 1 KiB.
///
/// ```
/// assert_eq!(cssm_formats::files::human_bytes(512, 2), "512 B");
/// assert_eq!(cssm_formats::files::human_bytes(3 << 20, 1), "3.0 MiB");
/// ```
pub fn human_bytes(bytes: u64, decimals: usize) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{bytes} B")
    } else {
        format!("{v:.decimals$} {}", UNITS[u])
    }
}
