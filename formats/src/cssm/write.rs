//! Atomic writes: a temporary file in the destination's directory, fsynced, then renamed over
//! the destination.

use std::io::{Seek, Write};
use std::path::{Path, PathBuf};

use super::{CssmError, CssmFile, FileCoding, HEADER_LEN, encode_into, validate};

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
        let (out, head) = encode_into(file, coding, std::io::BufWriter::new(&mut *f))?;
        out.into_inner().map_err(|e| io(e.into_error()))?;
        f.seek(std::io::SeekFrom::Start(0)).map_err(io)?;
        f.write_all(&head).map_err(io)?;
        written = f.seek(std::io::SeekFrom::End(0)).map_err(io)?;
        Ok(())
    })?;
    Ok(written)
}

/// Writes `bytes` to `path` atomically: a temporary file `.NAME.tmp-PID` in the same directory,
/// fsynced, then renamed over `path`. On any error the temporary file is removed and `path` is
/// left untouched. Used for `.cssm` files and for the reports.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<(), CssmError> {
    write_atomic_by(path, &mut |f, tmp| {
        f.write_all(bytes).map_err(|error| CssmError::Io {
            path: tmp.to_path_buf(),
            error,
        })
    })
}

/// The temporary-file-and-rename frame of the atomic writes: `fill(file, temporary path)`
/// writes the contents.
fn write_atomic_by(
    path: &Path,
    fill: &mut dyn FnMut(&mut std::fs::File, &Path) -> Result<(), CssmError>,
) -> Result<(), CssmError> {
    let name = path.file_name().ok_or_else(|| CssmError::Io {
        path: path.to_path_buf(),
        error: std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file path"),
    })?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    let tmp = dir.join(tmp_name);

    let result = (|| -> Result<(), CssmError> {
        let io = |error| CssmError::Io {
            path: tmp.clone(),
            error,
        };
        let mut f = std::fs::File::create(&tmp).map_err(io)?;
        fill(&mut f, &tmp)?;
        f.sync_all().map_err(io)?;
        drop(f);
        std::fs::rename(&tmp, path).map_err(|error| CssmError::Io {
            path: path.to_path_buf(),
            error,
        })?;
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        // Name the destination too when the failure was on the temporary file.
        return Err(match e {
            CssmError::Io { path: p, error } if p == tmp => CssmError::Io {
                path: path.to_path_buf(),
                error: std::io::Error::new(
                    error.kind(),
                    format!("writing temporary file {}: {error}", p.display()),
                ),
            },
            other => other,
        });
    }
    // Best effort: persist the rename itself.
    #[cfg(unix)]
    if let Ok(d) = std::fs::File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}
