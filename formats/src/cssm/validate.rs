//! Semantic checks of a decoded (or about to be encoded) [`CssmFile`].

use super::{ATLAS_RESOLUTION_RANGE, CUBE_RESOLUTION_RANGE, CssmError, CssmFile, SEGMENT_MAPS};

macro_rules! invalid {
    ($($arg:tt)*) => {
        return Err(CssmError::Invalid(format!($($arg)*)))
    };
}

/// Semantic checks of a [`CssmFile`]: parameter ranges, table sizes, the sequence being a
/// permutation, texel coordinates in range and unique, finite geometry, the hierarchy
/// ([`Hierarchy::validate`]: a well-formed tree over the texels), and the run-data layout
/// (offsets, run starts) that [`RunData::lookup`] relies on. [`decode`] and [`encode`] call it;
/// the bake can call it on its own output.
///
/// [`Hierarchy::validate`]: crate::hierarchy::Hierarchy::validate
/// [`RunData::lookup`]: super::RunData::lookup
/// [`decode`]: super::decode
/// [`encode`]: super::encode
pub fn validate(file: &CssmFile) -> Result<(), CssmError> {
    let p = &file.params;
    validate_params(p)?;
    let maps = file.runs.map_count as usize;
    if maps == 0 {
        invalid!("no depth maps (map_count 0)");
    }
    if file.texels.len() != maps || file.sequence.len() != maps {
        invalid!(
            "map_count {maps}, {} texels and {} sequence entries must all be equal",
            file.texels.len(),
            file.sequence.len()
        );
    }
    validate_tables(file)?;
    validate_runs(&file.runs, p.cube_resolution)?;
    validate_csms(&file.csms)
}

/// The coherent shadow maps: each valid, one per object, in object order.
pub(super) fn validate_csms(csms: &[crate::csm::CsmData]) -> Result<(), CssmError> {
    for (i, c) in csms.iter().enumerate() {
        if let Err(e) = c.validate() {
            invalid!("coherent shadow map {i} (object {}): {e}", c.object);
        }
        if i > 0 && c.object <= csms[i - 1].object {
            invalid!("coherent shadow maps not in increasing object order at {i}");
        }
    }
    Ok(())
}

/// The parameters' ranges.
pub(super) fn validate_params(p: &super::BakeParams) -> Result<(), CssmError> {
    if !ATLAS_RESOLUTION_RANGE.contains(&p.atlas_resolution) {
        invalid!(
            "atlas_resolution {} outside {}..={}",
            p.atlas_resolution,
            ATLAS_RESOLUTION_RANGE.start(),
            ATLAS_RESOLUTION_RANGE.end()
        );
    }
    if !CUBE_RESOLUTION_RANGE.contains(&p.cube_resolution) {
        invalid!(
            "cube_resolution {} outside {}..={}",
            p.cube_resolution,
            CUBE_RESOLUTION_RANGE.start(),
            CUBE_RESOLUTION_RANGE.end()
        );
    }
    if !(p.near.is_finite() && p.near > 0.0) {
        invalid!("near {} must be finite and > 0", p.near);
    }
    if !(p.far.is_finite() && p.far > p.near) {
        invalid!("far {} must be finite and > near {}", p.far, p.near);
    }
    Ok(())
}

/// The checks of everything but the run data, for a file of `file.texels.len()` maps: the
/// tables (triangle_uvs, sequence, texels) and the hierarchy. A chunk of a chunked bake
/// ([`super::chunk`]) holds the whole tables and a slice of the runs.
pub(super) fn validate_tables(file: &CssmFile) -> Result<(), CssmError> {
    let p = &file.params;
    let maps = file.texels.len();
    if file.sequence.len() != maps {
        invalid!(
            "{maps} texels and {} sequence entries must be equal",
            file.sequence.len()
        );
    }
    if file.triangle_uvs.len() as u64 != file.scene.triangle_count as u64 {
        invalid!(
            "{} triangle_uvs for a scene of {} triangles",
            file.triangle_uvs.len(),
            file.scene.triangle_count
        );
    }
    if let Some(t) = file
        .triangle_uvs
        .iter()
        .position(|uv| uv.iter().flatten().any(|c| !c.is_finite()))
    {
        invalid!("triangle_uvs[{t}] is not finite");
    }
    // On the page, with a texel of margin for rounding (a bake's lie well inside); far-off
    // coordinates overflowed the query's cell arithmetic (found by fuzzing).
    let page = -1.0..=p.atlas_resolution as f32 + 1.0;
    if let Some(t) = file
        .triangle_uvs
        .iter()
        .position(|uv| uv.iter().flatten().any(|c| !page.contains(c)))
    {
        invalid!(
            "triangle_uvs[{t}] = {:?} lies off the {}x{} atlas",
            file.triangle_uvs[t],
            p.atlas_resolution,
            p.atlas_resolution
        );
    }
    let mut seen = vec![false; maps];
    for (k, &t) in file.sequence.iter().enumerate() {
        match seen.get_mut(t as usize) {
            None => invalid!("sequence[{k}] = {t} is not a texel index (< {maps})"),
            Some(s) if *s => invalid!("sequence[{k}] = {t} repeats a texel: not a permutation"),
            Some(s) => *s = true,
        }
    }
    let res = p.atlas_resolution as usize;
    let mut used = vec![false; res * res];
    for (i, t) in file.texels.iter().enumerate() {
        if t.x as usize >= res || t.y as usize >= res {
            invalid!(
                "texel {i} at ({}, {}) outside the {res}x{res} atlas",
                t.x,
                t.y
            );
        }
        let slot = &mut used[t.y as usize * res + t.x as usize];
        if *slot {
            invalid!("texel {i} at ({}, {}) duplicates another texel", t.x, t.y);
        }
        *slot = true;
        if !(t.position.iter().all(|c| c.is_finite()) && t.normal.iter().all(|c| c.is_finite())) {
            invalid!("texel {i} has a non-finite position or normal");
        }
        if !(t.area.is_finite() && t.area >= 0.0) {
            invalid!("texel {i} has invalid area {}", t.area);
        }
    }
    if let Err(e) = file.hierarchy.validate(maps) {
        invalid!("hierarchy: {e}");
    }
    Ok(())
}

/// The run-data layout that [`RunData::lookup`] relies on, for cube resolution `n`: offsets,
/// run starts, `6 n²` pixels. `runs.map_count` may be 0 (an empty chunk).
///
/// [`RunData::lookup`]: super::RunData::lookup
pub(super) fn validate_runs(r: &super::RunData, n: u32) -> Result<(), CssmError> {
    if r.pixel_count != 6 * n * n {
        invalid!(
            "pixel_count {} != 6 * {n} * {n} = {}",
            r.pixel_count,
            6 * n * n
        );
    }
    validate_run_layout(r, r.pixel_count)
}

/// The run-data layout of maps of `pixels` pixels each: offsets, run starts; what
/// [`super::RunData::lookup`] relies on (a cube map's `6 n²`, a CSM's `r²`).
pub fn validate_run_layout(r: &super::RunData, pixels: u32) -> Result<(), CssmError> {
    let maps = r.map_count as usize;
    if r.pixel_count != pixels {
        invalid!("pixel_count {} for maps of {pixels} pixels", r.pixel_count);
    }
    let segments = r.segment_count() as u64;
    let slots = segments * r.pixel_count as u64;
    if r.offsets.len() as u64 != slots + 1 {
        invalid!(
            "{} run offsets, expected segment_count * pixel_count + 1 = {}",
            r.offsets.len(),
            slots + 1
        );
    }
    if r.offsets[0] != 0 {
        invalid!("first run offset is {}, not 0", r.offsets[0]);
    }
    if *r.offsets.last().expect("non-empty") as usize != r.runs.len() {
        invalid!(
            "last run offset {} != number of runs {}",
            r.offsets.last().expect("non-empty"),
            r.runs.len()
        );
    }
    if let Some(i) = r.offsets.windows(2).position(|w| w[1] < w[0]) {
        invalid!(
            "run offsets decrease at segment {}, pixel {}",
            i / r.pixel_count as usize,
            i % r.pixel_count as usize
        );
    }
    for slot in 0..slots as usize {
        let (lo, hi) = (r.offsets[slot] as usize, r.offsets[slot + 1] as usize);
        let (segment, pixel) = (slot / r.pixel_count as usize, slot % r.pixel_count as usize);
        let in_segment = (maps - segment * SEGMENT_MAPS as usize).min(SEGMENT_MAPS as usize);
        let runs = &r.runs[lo..hi];
        let Some(first) = runs.first() else {
            invalid!("segment {segment}, pixel {pixel} has no runs");
        };
        if first >> 16 != 0 {
            invalid!(
                "segment {segment}, pixel {pixel}: first run starts at {}, not 0",
                first >> 16
            );
        }
        for w in runs.windows(2) {
            if w[1] >> 16 <= w[0] >> 16 {
                invalid!("segment {segment}, pixel {pixel}: run starts not strictly increasing");
            }
        }
        let last = (runs[runs.len() - 1] >> 16) as usize;
        if last >= in_segment {
            invalid!(
                "segment {segment}, pixel {pixel}: run starts at map {last}, segment has {in_segment}"
            );
        }
    }
    Ok(())
}

/// The checks of `file` against the scene it is used with, for what [`validate`] cannot see
/// alone: every index into the scene in range (the texels' materials, the triangle count), so
/// that a file whose checksum holds but whose contents were crafted or come from another
/// scene is refused before any renderer indexes with them. The content hash, which says
/// whether the scene is the one baked, is the caller's to compare (`cssm_runtime::load`).
///
/// ```
/// # fn demo(file: &cssm_formats::CssmFile, scene: &cssm_formats::Scene) {
/// if let Err(e) = cssm_formats::cssm::validate_for_scene(file, scene) {
///     eprintln!("{e}");
/// }
/// # }
/// ```
pub fn validate_for_scene(file: &CssmFile, scene: &crate::Scene) -> Result<(), CssmError> {
    if file.triangle_uvs.len() != scene.triangles.len() {
        invalid!(
            "{} triangles in the file, {} in the scene '{}'",
            file.triangle_uvs.len(),
            scene.triangles.len(),
            scene.name
        );
    }
    let materials = scene.materials.len();
    if let Some((i, t)) = file
        .texels
        .iter()
        .enumerate()
        .find(|(_, t)| t.material as usize >= materials)
    {
        invalid!(
            "texel {i} has material {}, the scene '{}' has {materials}",
            t.material,
            scene.name
        );
    }
    let objects = scene.objects.len();
    if let Some((i, t)) = file
        .texels
        .iter()
        .enumerate()
        .find(|(_, t)| t.object as usize >= objects)
    {
        invalid!(
            "texel {i} lies on object {}, the scene '{}' has {objects}",
            t.object,
            scene.name
        );
    }
    for c in &file.csms {
        match scene.objects.get(c.object as usize) {
            Some(o) if o.kind == crate::ObjectKind::Rigid => {}
            Some(o) => invalid!(
                "a coherent shadow map for object {} ('{}'), which is not a rigid object",
                c.object,
                o.name
            ),
            None => invalid!(
                "a coherent shadow map for object {}, the scene has {}",
                c.object,
                scene.objects.len()
            ),
        }
    }
    Ok(())
}
