//! Reading a glTF file: its document parsed (after the checks of `checks.rs`), the extensions
//! it requires or uses weighed against those the loader understands, and its buffers read from
//! the GLB's binary chunk, `data:` URIs or files next to it (bounded, hashed).

use std::path::Path;

use super::checks::{Buffers, check_attribute_accessors, check_glb_header, uri_file};
use super::gltf_error;
use crate::scene::{Builder, Hasher, MAX_FILE_BYTES, SceneError, read_bounded};

/// Extensions the loader understands; a file that requires any other is refused, as the glTF
/// specification asks (§3.12).
const SUPPORTED_EXTENSIONS: [&str; 2] = ["KHR_lights_punctual", "KHR_materials_emissive_strength"];

/// The bytes of a `data:` URI and its MIME type, if it declares one.
pub(super) type DataUri = (Vec<u8>, Option<String>);

/// The bytes of a `data:` URI (`data:[<mime>][;base64],<data>`) and its MIME type; `None` for
/// any other URI.
pub(super) fn data_uri(uri: &str) -> Option<Result<DataUri, String>> {
    let rest = uri.strip_prefix("data:")?;
    let Some((header, data)) = rest.split_once(',') else {
        return Some(Err("a data URI without a comma".into()));
    };
    let (mime, base64) = match header.strip_suffix(";base64") {
        Some(mime) => (mime, true),
        None => (header, false),
    };
    let mime = (!mime.is_empty()).then(|| mime.to_string());
    let bytes = if base64 {
        use base64::Engine;
        match base64::engine::general_purpose::STANDARD.decode(data) {
            Ok(b) => b,
            Err(e) => return Some(Err(format!("a data URI's base64 does not decode: {e}"))),
        }
    } else {
        urlencoding::decode_binary(data.as_bytes()).into_owned()
    };
    Some(Ok((bytes, mime)))
}

/// The document of the glTF file `path`, whose bytes are `bytes`, and its binary chunk (for a
/// GLB that has one).
pub(super) fn parse_document(
    path: &Path,
    bytes: &[u8],
) -> Result<(gltf::Document, Option<Vec<u8>>), SceneError> {
    check_glb_header(bytes).map_err(|e| gltf_error(path, e))?;
    // The crate's validation checks every index the JSON holds but one, which its own
    // check of POSITION's bounds indexes unchecked: that one first, then the crate's. A
    // panic on malformed input still becomes an error like any other.
    let parsed = std::panic::catch_unwind(|| {
        gltf::Gltf::from_slice_without_validation(bytes).map(|g| (g.document.into_json(), g.blob))
    })
    .map_err(|_| gltf_error(path, "the glTF parser failed on malformed input"))?;
    let (root, blob) = parsed.map_err(|e| gltf_error(path, e.to_string()))?;
    check_attribute_accessors(&root).map_err(|e| gltf_error(path, e))?;
    let document = std::panic::catch_unwind(|| gltf::Document::from_json(root))
        .map_err(|_| gltf_error(path, "the glTF parser failed on malformed input"))?
        .map_err(|e| gltf_error(path, e.to_string()))?;
    Ok((document, blob))
}

impl Builder {
    /// Refuses a file that requires an extension the loader lacks (glTF §3.12) and warns of
    /// the extensions it uses that are ignored.
    pub(super) fn check_gltf_extensions(
        &mut self,
        path: &Path,
        document: &gltf::Document,
    ) -> Result<(), SceneError> {
        if let Some(ext) = document
            .extensions_required()
            .find(|e| !SUPPORTED_EXTENSIONS.contains(e))
        {
            return Err(gltf_error(
                path,
                format!(
                    "the file requires the extension {ext}, which cssm does not support \
                     (supported: {})",
                    SUPPORTED_EXTENSIONS.join(", ")
                ),
            ));
        }
        let ignored: Vec<&str> = document
            .extensions_used()
            .filter(|e| !SUPPORTED_EXTENSIONS.contains(e))
            .collect();
        if !ignored.is_empty() {
            self.warnings.push(format!(
                "{}: glTF extensions ignored: {}",
                path.display(),
                ignored.join(", ")
            ));
        }
        Ok(())
    }
}

/// The buffers of `document`, in order: the binary chunk `blob`, data URIs, or files named
/// relative to `dir` (outside it only where `outside` allows), each file hashed; a buffer
/// shorter than the file says is an error.
pub(super) fn read_buffers(
    path: &Path,
    dir: &Path,
    outside: bool,
    document: &gltf::Document,
    blob: Option<Vec<u8>>,
    hasher: &mut Hasher,
) -> Result<Buffers, SceneError> {
    // Buffers: the GLB's binary chunk, data URIs, or files next to the glTF.
    let mut blob = blob;
    // The buffer files' sizes in all, before any is read: one file named by many buffers
    // is read once per buffer.
    let mut file_bytes = 0u64;
    for buffer in document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source()
            && !uri.starts_with("data:")
            && let Ok(file) = uri_file(dir, uri, outside)
            && let Ok(metadata) = std::fs::metadata(&file)
        {
            file_bytes = file_bytes.saturating_add(metadata.len());
            if file_bytes > MAX_FILE_BYTES {
                return Err(gltf_error(
                    path,
                    format!(
                        "buffer {}: the buffer files come to more than {MAX_FILE_BYTES} bytes \
                         in all, the most a glTF's buffers may hold",
                        buffer.index()
                    ),
                ));
            }
        }
    }
    let mut data = Vec::new();
    for buffer in document.buffers() {
        let bytes = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                gltf_error(
                    path,
                    format!(
                        "buffer {} is the binary chunk, which the file lacks",
                        buffer.index()
                    ),
                )
            })?,
            gltf::buffer::Source::Uri(uri) => match data_uri(uri) {
                Some(decoded) => {
                    decoded
                        .map_err(|e| gltf_error(path, format!("buffer {}: {e}", buffer.index())))?
                        .0
                }
                None => {
                    let file = uri_file(dir, uri, outside)
                        .map_err(|e| gltf_error(path, format!("buffer {}: {e}", buffer.index())))?;
                    let bytes = read_bounded(&file)?;
                    hasher.add(&file, &bytes);
                    bytes
                }
            },
        };
        if bytes.len() < buffer.length() {
            return Err(gltf_error(
                path,
                format!(
                    "buffer {} holds {} bytes, the file says {}",
                    buffer.index(),
                    bytes.len(),
                    buffer.length()
                ),
            ));
        }
        data.push(bytes);
    }
    Ok(Buffers { data })
}
