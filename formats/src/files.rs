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
    bytes
        .try_reserve_exact(size as usize)
        .map_err(|_| too_large(size))?;
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(bytes.len() as u64));
    }
    Ok(bytes)
}
