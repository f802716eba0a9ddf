//! What a glTF file is checked for before the `gltf` crate's parser and readers see it (they
//! index, unwrap and slice what the file claims) and before any file it names is read: the GLB
//! header, the URIs (inside the glTF's directory), every accessor's index, type, stride and
//! range (issue 53).

use std::path::{Path, PathBuf};

use super::gltf_error;
use crate::scene::SceneError;

/// A binary glTF's 12-byte header (magic, version, total length) checked before the crate
/// parses it: the crate subtracts the header's size from the declared length unchecked (an
/// overflow on a declared length below 12, found by fuzzing).
pub(super) fn check_glb_header(bytes: &[u8]) -> Result<(), String> {
    if !bytes.starts_with(b"glTF") {
        return Ok(());
    }
    let Some(length) = bytes.get(8..12) else {
        return Err(format!(
            "the binary glTF (GLB) header is cut short: {} bytes, a header needs 12",
            bytes.len()
        ));
    };
    let length = u32::from_le_bytes(length.try_into().expect("four bytes")) as usize;
    if length < 12 || length > bytes.len() {
        return Err(format!(
            "the binary glTF (GLB) header declares {length} bytes, but the file holds {} \
             (at least the 12 of the header)",
            bytes.len()
        ));
    }
    Ok(())
}

/// The file a URI (not a `data:` one) of the glTF file in `dir` names: relative to `dir`,
/// percent-decoded. Unless `outside` allows it, only a file in `dir` or below: an absolute path,
/// a `..` that leads out of `dir` or a link that points out of it is refused, before anything
/// is read (issue 53: a scene file must not make the tool read files elsewhere).
pub(super) fn uri_file(dir: &Path, uri: &str, outside: bool) -> Result<PathBuf, String> {
    let shown = uri
        .chars()
        .take(120)
        .collect::<String>()
        .escape_debug()
        .to_string();
    let decoded = urlencoding::decode(uri)
        .map_err(|_| format!("the URI \"{shown}\" is not UTF-8 once percent-decoded"))?;
    if decoded.contains('\0') {
        return Err(format!("the URI \"{shown}\" holds a NUL character"));
    }
    // A scheme other than data: (file:, http:) is not a relative reference (RFC 3986, §4.2).
    if let Some((scheme, _)) = decoded.split_once(':')
        && scheme.len() > 1
        && scheme
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
    {
        return Err(format!(
            "the URI \"{shown}\" has the scheme {scheme}:; a glTF file's buffers and images are \
             data: URIs or paths relative to the file"
        ));
    }
    let relative = Path::new(&*decoded);
    let file = dir.join(relative);
    if outside {
        return Ok(file);
    }
    let out = || {
        format!(
            "the URI \"{shown}\" names a file outside the glTF file's directory {}; \
             pass --allow-outside-files if you trust the scene",
            dir.display()
        )
    };
    // Lexically first (a file that does not exist yet still may not be named), then by the
    // file system (a link inside pointing out).
    let mut depth = 0usize;
    for component in relative.components() {
        match component {
            std::path::Component::Normal(_) => depth += 1,
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => depth = depth.checked_sub(1).ok_or_else(out)?,
            std::path::Component::RootDir | std::path::Component::Prefix(_) => return Err(out()),
        }
    }
    if let (Ok(real), Ok(real_dir)) = (std::fs::canonicalize(&file), std::fs::canonicalize(dir))
        && !real.starts_with(&real_dir)
    {
        return Err(out());
    }
    Ok(file)
}

/// The loaded buffers of a glTF file.
pub(super) struct Buffers {
    /// Each buffer's bytes, in the file's order.
    pub(super) data: Vec<Vec<u8>>,
}

impl Buffers {
    /// The bytes of `view`, checked against its buffer.
    pub(super) fn view<'a>(&'a self, view: &gltf::buffer::View) -> Option<&'a [u8]> {
        let buffer = self.data.get(view.buffer().index())?;
        let end = view.offset().checked_add(view.length())?;
        buffer.get(view.offset()..end)
    }
}

/// Every accessor a primitive names (its attributes and indices) exists.
pub(super) fn check_attribute_accessors(root: &gltf::json::Root) -> Result<(), String> {
    let accessors = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some(missing) = primitive
                .attributes
                .values()
                .chain(&primitive.indices)
                .find(|a| a.value() >= accessors)
            {
                return Err(format!(
                    "mesh {m} primitive {p} names accessor {}; the file has {accessors}",
                    missing.value()
                ));
            }
        }
    }
    Ok(())
}

/// What a primitive reads an accessor as. The gltf crate's readers assume the types glTF 2.0
/// allows for it (§3.7.2.1) and panic on any other, so each is checked first.
#[derive(Clone, Copy)]
pub(super) enum Role {
    Positions,
    Indices,
    TexCoords,
}

impl Role {
    fn name(self) -> &'static str {
        match self {
            Role::Positions => "POSITION",
            Role::Indices => "indices",
            Role::TexCoords => "TEXCOORD",
        }
    }

    /// Whether glTF allows `accessor` in this role, and what it allows if not.
    fn check(self, accessor: &gltf::Accessor) -> Result<(), &'static str> {
        use gltf::accessor::{DataType as T, Dimensions as D};
        let ok = match self {
            Role::Positions => accessor.dimensions() == D::Vec3 && accessor.data_type() == T::F32,
            Role::Indices => {
                accessor.dimensions() == D::Scalar
                    && matches!(accessor.data_type(), T::U8 | T::U16 | T::U32)
            }
            Role::TexCoords => {
                accessor.dimensions() == D::Vec2
                    && matches!(accessor.data_type(), T::F32 | T::U8 | T::U16)
            }
        };
        ok.then_some(()).ok_or(match self {
            Role::Positions => "VEC3 of FLOAT",
            Role::Indices => "SCALAR of UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
            Role::TexCoords => "VEC2 of FLOAT, UNSIGNED_BYTE or UNSIGNED_SHORT",
        })
    }
}

/// Checks that `accessor` has a type glTF allows in its `role`, that it reads only bytes its
/// buffer view holds, with a stride no shorter than an element (and that a sparse accessor's
/// count is no larger than the file's data), so that no reader panics, walks past a buffer or
/// allocates by a count the file merely claims.
pub(super) fn check_accessor(
    path: &Path,
    buffers: &Buffers,
    (accessor, role): (&gltf::Accessor, Role),
    total_bytes: usize,
) -> Result<(), SceneError> {
    let bad = |what: String| {
        gltf_error(
            path,
            format!("accessor {} ({}): {what}", accessor.index(), role.name()),
        )
    };
    role.check(accessor)
        .map_err(|allowed| bad(format!("glTF allows only {allowed} here")))?;
    let (count, size) = (accessor.count(), accessor.size());
    let claimed = count.checked_mul(size).filter(|&b| b <= total_bytes);
    if claimed.is_none() {
        return Err(bad(format!(
            "{count} elements of {size} bytes, more than the file's {total_bytes} bytes of data"
        )));
    }
    if let Some(view) = accessor.view() {
        let bytes = buffers.view(&view).ok_or_else(|| {
            bad(format!(
                "buffer view {} reaches past the end of buffer {}",
                view.index(),
                view.buffer().index()
            ))
        })?;
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            return Err(bad(format!(
                "buffer view {} has a byteStride of {stride}, less than the {size} bytes of an \
                 element",
                view.index()
            )));
        }
        let end = (count > 0).then(|| {
            stride
                .checked_mul(count - 1)
                .and_then(|b| b.checked_add(size))
                .and_then(|b| b.checked_add(accessor.offset()))
        });
        match end {
            None => {}
            Some(Some(end)) if end <= bytes.len() => {}
            _ => {
                return Err(bad(format!(
                    "{count} elements at offset {} reach past the end of buffer view {} \
                     ({} bytes)",
                    accessor.offset(),
                    view.index(),
                    bytes.len()
                )));
            }
        }
    }
    if let Some(sparse) = accessor.sparse() {
        for (view, what, elem) in [
            (sparse.indices().view(), "indices", 4usize),
            (sparse.values().view(), "values", size),
        ] {
            let bytes = buffers.view(&view).ok_or_else(|| {
                bad(format!(
                    "the sparse {what}' buffer view reaches past its buffer"
                ))
            })?;
            if sparse.count().saturating_mul(elem) > bytes.len() {
                return Err(bad(format!(
                    "{} sparse {what} do not fit in their buffer view",
                    sparse.count()
                )));
            }
        }
    }
    Ok(())
}
