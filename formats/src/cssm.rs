//! The `.cssm` container: a versioned, checksummed, zstd-compressed file holding one baked
//! Coherent Surface Shadow Map (§3.2): the bake parameters, the atlas texel table, the
//! traversal sequence and the piecewise-constant run data laid out for random access.
//!
//! TODO(helper): encode/decode, atomic write, validation. See the module's tests.

use serde::{Deserialize, Serialize};

use crate::texel::{Texel, Traversal};

/// First eight bytes of every `.cssm` file.
pub const MAGIC: [u8; 8] = *b"CSSM\x00\r\n\x1a";
/// Version written by this build; files with a larger version are refused as "newer".
pub const FORMAT_VERSION: u32 = 1;
/// Number of consecutive depth maps per run-data segment: run starts are stored relative to
/// their segment in 16 bits, so a segment holds at most 2^16 maps.
pub const SEGMENT_MAPS: u32 = 1 << 16;

/// What the bake was asked to do.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BakeParams {
    /// Atlas width and height in texels (32..=1024).
    pub atlas_resolution: u32,
    /// Cube face width and height in pixels (8..=128); a map has `6 * N * N` pixels.
    pub cube_resolution: u32,
    /// Distance the cube-map centre is pushed off the surface along the normal, and near plane
    /// of the linear depth range (scene units), §3.2.1.
    pub near: f32,
    /// Far plane of the linear depth range: the scene diameter (scene units), §3.2.1.
    pub far: f32,
    /// Order of the depth-map sequence.
    pub traversal: Traversal,
}

/// Which scene the file was baked from, so that `check` and the runtime can find the geometry
/// and refuse a scene that has changed since.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneRef {
    /// Absolute path of the scene directory at bake time.
    pub dir: String,
    /// Scene name (from `scene.toml`, or the directory name).
    pub name: String,
    /// BLAKE3 hash over the scene's files (see `scene::Scene::content_hash`).
    pub content_hash: [u8; 32],
    /// Number of triangles of the loaded scene (a cheap second check).
    pub triangle_count: u32,
}

/// Piecewise-constant runs of every cube-map pixel along the depth-map sequence, laid out for
/// random access by (map index, pixel) (§3.1, §3.2).
///
/// The sequence of `map_count` maps is cut into segments of [`SEGMENT_MAPS`] maps. For segment
/// `s` and pixel `p` (`p = face * N * N + row * N + col`), the runs are
/// `runs[offsets[s * pixel_count + p] .. offsets[s * pixel_count + p + 1]]`, sorted by start;
/// the first one starts at 0. A run is one `u32`: `(start_within_segment << 16) | depth16`.
/// The depth of map `m` at pixel `p` is the value of the last run of segment `m / SEGMENT_MAPS`
/// whose start is `<= m % SEGMENT_MAPS`: a binary search over a handful of entries.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunData {
    /// Number of depth maps (= defined texels).
    pub map_count: u32,
    /// Pixels per cube map, `6 * N * N`.
    pub pixel_count: u32,
    /// `segment_count * pixel_count + 1` prefix offsets into `runs`.
    pub offsets: Vec<u32>,
    /// Packed runs, `(start_within_segment << 16) | depth16`.
    pub runs: Vec<u32>,
}

impl RunData {
    /// Number of segments of [`SEGMENT_MAPS`] maps.
    pub fn segment_count(&self) -> u32 {
        self.map_count.div_ceil(SEGMENT_MAPS)
    }

    /// Quantised depth of map `map` at pixel `pixel`. Both must be in range.
    #[inline]
    pub fn lookup(&self, map: u32, pixel: u32) -> u16 {
        let segment = map / SEGMENT_MAPS;
        let local = map % SEGMENT_MAPS;
        let slot = (segment * self.pixel_count + pixel) as usize;
        let (lo, hi) = (self.offsets[slot] as usize, self.offsets[slot + 1] as usize);
        let runs = &self.runs[lo..hi];
        // Last run whose start <= local: partition point of "start <= local".
        let idx = runs.partition_point(|&r| (r >> 16) <= local);
        (runs[idx.max(1) - 1] & 0xFFFF) as u16
    }

    /// Bytes the random-access run data occupies in GPU memory: offsets plus runs.
    pub fn gpu_bytes(&self) -> u64 {
        4 * (self.offsets.len() as u64 + self.runs.len() as u64)
    }

    /// Uncompressed size, the denominator of every ratio: 2 bytes per cube-map pixel (paper,
    /// Tables 2 and 3).
    pub fn uncompressed_bytes(&self) -> u64 {
        2 * self.map_count as u64 * self.pixel_count as u64
    }
}

/// A whole baked CSSM.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CssmFile {
    /// Bake parameters.
    pub params: BakeParams,
    /// The scene it was baked from.
    pub scene: SceneRef,
    /// Defined atlas texels, in atlas row-major order (y, then x).
    pub texels: Vec<Texel>,
    /// Atlas coordinates (in texels, `0..atlas_resolution`) of the three corners of every scene
    /// triangle, in the scene's triangle order; lets any surface point find its texel.
    pub triangle_uvs: Vec<[[f32; 2]; 3]>,
    /// `sequence[k]` is the texel index of the `k`-th depth map.
    pub sequence: Vec<u32>,
    /// The compressed depth maps.
    pub runs: RunData,
}
