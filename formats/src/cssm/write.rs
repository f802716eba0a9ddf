//! Atomic writes: a temporary file in the destination's directory, fsynced, then renamed over
//! the destination.

use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use super::{CssmError, CssmFile, FileCoding, HEADER_LEN, encode_into, validate};
use crate::files::kind_of;

/// Writes `file` to `path` atomically (see [`write_bytes_atomic`]) with the default
/// [`FileCoding`]. Returns the number of bytes written.
pub fn write_atomic(path: &Path, file: &CssmFile) -> Result<u64, CssmError> {
    write_atomic_with(path, file, FileCoding::default())
}

/// [`write_atomic`] with the run data coded as `coding` says.
///
/// The payload is streamed into the temporary file and the header written last, so the file's
/// bytes are never all in memory at once (the same bytes as [`encode_with`]).
///
/// [`encode_with`]: super::encode_with
pub fn write_atomic_with(
    path: &Path,
    file: &CssmFile,
    coding: FileCoding,
) -> Result<u64, CssmError> {
    // Check before creating anything, so an invalid file leaves nothing behind.
    validate(file)?;
    let mut written = 0;
    write_atomic_by(path, &mut |f, tmp| {
        let io = |error| CssmError::Io {
            path: tmp.to_path_buf(),
            error,
        };
        f.write_all(&[0u8; HEADER_LEN]).map_err(io)?;
        let (out, head) = match encode_reporting_io(file, coding, std::io::BufWriter::new(&mut *f))
        {
            Err(CssmError::Io { error, .. }) => return Err(io(error)),
            other => other?,
        };
        out.into_inner().map_err(|e| io(e.into_error()))?;
        f.seek(std::io::SeekFrom::Start(0)).map_err(io)?;
        f.write_all(&head).map_err(io)?;
        written = f.seek(std::io::SeekFrom::End(0)).map_err(io)?;
        Ok(())
    })?;
    Ok(written)
}

/// [`encode_into`] whose failures to write `out` are [`CssmError::Io`] (with an empty path
/// for the caller to fill): a full disk fails a write deep inside zstd's encoder, which
/// reports it as an encoding error of its own.
fn encode_reporting_io<W: Write>(
    file: &CssmFile,
    coding: FileCoding,
    out: W,
) -> Result<(W, Vec<u8>), CssmError> {
    let mut first_error = None;
    let keeping = ErrorKeepingWriter {
        inner: out,
        first_error: &mut first_error,
    };
    let encoded = encode_into(file, coding, keeping).map(|(out, head)| (out.inner, head));
    match (encoded, first_error) {
        (Ok(done), None) => Ok(done),
        (_, Some(error)) => Err(CssmError::Io {
            path: PathBuf::new(),
            error,
        }),
        (Err(e), None) => Err(e),
    }
}

/// A writer that keeps the first error its inner writer gave (and passes every error on).
struct ErrorKeepingWriter<'a, W> {
    inner: W,
    first_error: &'a mut Option<std::io::Error>,
}

impl<W: Write> ErrorKeepingWriter<'_, W> {
    fn keep<T>(&mut self, result: std::io::Result<T>) -> std::io::Result<T> {
        result.map_err(|e| {
            let copy = std::io::Error::new(e.kind(), e.to_string());
            self.first_error.get_or_insert(e);
            copy
        })
    }
}

impl<W: Write> Write for ErrorKeepingWriter<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let result = self.inner.write(buf);
        self.keep(result)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        let result = self.inner.flush();
        self.keep(result)
    }
}

/// Writes `bytes` to `path` atomically (see [`destination`] for what it may replace): an
/// unnamed temporary file in the same directory (`O_TMPFILE` on Linux, so a killed process
/// leaves nothing behind; elsewhere `.NAME.XXXXXX`), fsynced, then renamed over `path`. On any
/// error `path` is left untouched. Used for `.cssm` files, images and the reports.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<(), CssmError> {
    write_atomic_by(path, &mut |f, tmp| {
        f.write_all(bytes).map_err(|error| CssmError::Io {
            path: tmp.to_path_buf(),
            error,
        })
    })
}

/// The longest file name, in bytes, the atomic writes accept: the file system's 255 less the
/// `.` and `.XXXXXX` of the temporary name the rename starts from.
pub const MAX_NAME_BYTES: usize = 255 - 8;

/// What an atomic write of `path` may replace, and the path it writes: nothing (a new file), a
/// regular file, or through a symbolic link the regular file it points to (the link stays a
/// link). Refused, before anything is written: a directory, a FIFO, a device or a socket at
/// `path` (renaming over a character device would replace, say, `/dev/null` with a file), a
/// link to nothing or to anything but a regular file, and a file name longer than
/// [`MAX_NAME_BYTES`].
///
/// ```
/// # let dir = tempfile::tempdir().unwrap();
/// let fifo = dir.path().join("pipe");
/// # #[cfg(unix)] std::process::Command::new("mkfifo").arg(&fifo).status().unwrap();
/// # #[cfg(unix)]
/// assert!(cssm_formats::cssm::destination(&fifo).is_err());
/// let new = dir.path().join("new.cssm");
/// assert_eq!(cssm_formats::cssm::destination(&new).unwrap(), new);
/// ```
pub fn destination(path: &Path) -> Result<PathBuf, CssmError> {
    let refuse = |why: String| CssmError::Io {
        path: path.to_path_buf(),
        error: std::io::Error::new(std::io::ErrorKind::InvalidInput, why),
    };
    let name = path
        .file_name()
        .ok_or_else(|| refuse("not a file path".into()))?;
    if name.len() > MAX_NAME_BYTES {
        return Err(refuse(format!(
            "the file name is {} bytes long; at most {MAX_NAME_BYTES} can be written safely \
             (the file system allows 255, the temporary file's name needs the rest)",
            name.len()
        )));
    }
    let metadata = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(path.to_path_buf()),
        Err(error) => {
            return Err(CssmError::Io {
                path: path.to_path_buf(),
                error,
            });
        }
    };
    if metadata.file_type().is_symlink() {
        let target = std::fs::canonicalize(path).map_err(|e| {
            refuse(format!(
                "a symbolic link whose target cannot be written ({e}); remove the link or \
                 write elsewhere"
            ))
        })?;
        let kind = std::fs::metadata(&target).map(|m| kind_of(&m));
        return match kind {
            Ok(None) => Ok(target),
            Ok(Some(kind)) => Err(refuse(format!(
                "a symbolic link to {} ({kind}); cssm writes only regular files",
                target.display()
            ))),
            Err(error) => Err(CssmError::Io {
                path: target,
                error,
            }),
        };
    }
    match kind_of(&metadata) {
        None => Ok(path.to_path_buf()),
        Some(kind) => Err(refuse(format!(
            "it is {kind}; cssm writes only regular files and will not replace it"
        ))),
    }
}

/// The atomic write frame: `fill(file, destination)` writes the contents into the temporary
/// file, which then replaces [`destination`]`(path)`.
pub(super) fn write_atomic_by(
    path: &Path,
    fill: &mut dyn FnMut(&mut std::fs::File, &Path) -> Result<(), CssmError>,
) -> Result<(), CssmError> {
    let target = destination(path)?;
    // Errors name the path the user gave (and the link's target where that differs).
    let named = |error: std::io::Error| CssmError::Io {
        path: path.to_path_buf(),
        error: if target == path {
            error
        } else {
            std::io::Error::new(
                error.kind(),
                format!("writing {}: {error}", target.display()),
            )
        },
    };
    let mut file = atomic_write_file::AtomicWriteFile::options()
        .open(&target)
        .map_err(named)?;
    match fill(file.as_file_mut(), &target) {
        Ok(()) => {}
        Err(CssmError::Io { error, .. }) => return Err(named(error)),
        Err(other) => return Err(other),
    }
    file.commit().map_err(named)?;
    if let Some(dir) = target.parent() {
        remove_stale_temporaries(dir, target.file_name().unwrap_or_default());
    }
    Ok(())
}

/// Removes the temporary files earlier versions left when killed mid-write:
/// `.NAME.tmp-PID` beside `NAME`, where no process PID runs any more (Linux: `/proc/PID`).
fn remove_stale_temporaries(dir: &Path, name: &std::ffi::OsStr) {
    #[cfg(target_os = "linux")]
    {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        let mut prefix = std::ffi::OsString::from(".");
        prefix.push(name);
        prefix.push(".tmp-");
        let Some(prefix) = prefix.to_str() else {
            return;
        };
        // Without /proc no process looks alive: remove nothing.
        if !Path::new("/proc/self").exists() {
            return;
        }
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for entry in entries.flatten() {
            let file_name = entry.file_name();
            let Some(pid) = file_name.to_str().and_then(|n| n.strip_prefix(prefix)) else {
                continue;
            };
            let is_pid = !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit());
            let regular = entry.file_type().is_ok_and(|t| t.is_file());
            if is_pid && regular && !Path::new("/proc").join(pid).exists() {
                let _ = std::fs::remove_file(entry.path());
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (dir, name);
}

#[cfg(test)]
#[path = "../../tests/common/sample.rs"]
mod sample;

#[cfg(test)]
mod tests {
    use super::*;

    /// A disk that fills after `room` bytes.
    struct FullAfter {
        room: usize,
    }

    impl Write for FullAfter {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            if self.room == 0 {
                return Err(std::io::ErrorKind::StorageFull.into());
            }
            let n = buf.len().min(self.room);
            self.room -= n;
            Ok(n)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// A full disk is reported as the write's own error, not as an encoding failure, at any
    /// point of the stream (before, inside and after zstd's frames).
    #[test]
    fn a_full_disk_is_an_io_error_wherever_it_fills() {
        let file = super::sample::sample();
        let whole = crate::cssm::encode(&file).unwrap().len();
        for room in [0, 1, 100, whole / 2, whole - HEADER_LEN - 1] {
            let err = encode_reporting_io(&file, FileCoding::default(), FullAfter { room })
                .err()
                .unwrap_or_else(|| panic!("room {room}: encoded into a full disk"));
            match err {
                CssmError::Io { error, .. } => {
                    assert_eq!(error.kind(), std::io::ErrorKind::StorageFull, "room {room}")
                }
                other => panic!("room {room}: {other}"),
            }
        }
        let room = whole - HEADER_LEN;
        assert!(encode_reporting_io(&file, FileCoding::default(), FullAfter { room }).is_ok());
    }
}
