//! Texture atlas over the whole scene (§3.2.3): unwrap with xatlas into one square page of the
//! requested resolution, then rasterise every chart so that each covered texel records its
//! world position, normal, the world-space area it stands for, its material and its chart.
//!
//! A texel is *defined* when its centre lies inside a triangle of the atlas (first triangle in
//! scene order wins on shared edges). A triangle too small to cover any texel centre hands its
//! area, and if that texel is still free its centroid, to the texel under its centroid, so no
//! surface is lost and the texel areas add up to the scene's surface area.

use cssm_formats::{Scene, Texel};
use glam::{Vec2, Vec3};

use crate::{BakeError, Progress, Stage};

use cssm_formats::cssm::ATLAS_RESOLUTION_RANGE;

/// Average number of faces per chart above which xatlas' charts are capped in area.
const FACES_PER_CHART: f64 = 200.0;

/// Most separate pieces of surface (sets of triangles joined by shared edges) the atlas stage
/// takes: xatlas makes a chart group of each, at a cost in memory and time that grows with their
/// number (20,000 loose quads held 2.3 GB after 3 s and were still packing after a minute;
/// reports/reliability.md). The Sibenik cathedral has 260.
pub const MAX_ATLAS_PIECES: usize = 8192;

/// Factor by which the scale shrinks while the charts do not fit on one page.
const SHRINK: f32 = 0.92;

/// Atlas coordinates (texel units) of a triangle's three corners.
pub type TriangleUv = [[f32; 2]; 3];

/// A rasterised atlas.
#[derive(Clone, Debug)]
pub struct Atlas {
    /// Width and height in texels.
    pub resolution: u32,
    /// Defined texels in row-major order (y, then x).
    pub texels: Vec<Texel>,
    /// Atlas coordinates (texel units) of the corners of every scene triangle.
    pub triangle_uvs: Vec<[[f32; 2]; 3]>,
    /// Number of charts.
    pub chart_count: u32,
}

/// Unwraps `scene` into an atlas of `resolution` x `resolution` texels.
///
/// xatlas picks its scale from a texels-per-unit figure; we start from the scale that would fill
/// 75% of the page, shrink it until every chart fits on the single page, then bisect between
/// the last scale that did not fit and the first that did.
pub fn build(
    scene: &Scene,
    resolution: u32,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> Result<Atlas, BakeError> {
    crate::check_range(
        crate::BakeParameter::AtlasResolution,
        resolution,
        &ATLAS_RESOLUTION_RANGE,
    )?;
    let area: f64 = (0..scene.triangles.len())
        .map(|t| triangle_area(scene.triangle(t)) as f64)
        .sum();
    if area <= 0.0 || !area.is_finite() {
        return Err(BakeError::Scene("the scene has no surface area".into()));
    }
    let texels_per_unit = (resolution as f64 * (0.75 / area).sqrt()) as f32;
    let (uvs, charts) = unwrap(scene, area, resolution, texels_per_unit, progress)?;
    let texels = rasterise(scene, resolution, &uvs, &charts);
    let chart_count = texels.iter().map(|t| t.chart + 1).max().unwrap_or(0);
    Ok(Atlas {
        resolution,
        texels,
        triangle_uvs: uvs,
        chart_count,
    })
}

/// Charts the scene once with xatlas, then packs it at a shrinking scale until every chart
/// fits on one page. Returns per-triangle atlas coordinates and chart ids.
fn unwrap(
    scene: &Scene,
    area: f64,
    resolution: u32,
    mut texels_per_unit: f32,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> Result<(Vec<TriangleUv>, Vec<u32>), BakeError> {
    // xatlas charts connected triangles; vertices split in the OBJ (UV seams, smoothing groups,
    // separate objects) would cut the surface into many more, smaller charts, so vertices at
    // the same position are merged first. Triangles keep their order, so the per-triangle output
    // is unchanged in meaning.
    let (welded, remap) = weld(&scene.positions);
    let positions: Vec<f32> = welded.iter().flat_map(|p| p.to_array()).collect();
    let indices: Vec<u32> = scene
        .triangles
        .iter()
        .flatten()
        .map(|&i| remap[i as usize])
        .collect();
    check_pieces(&indices, resolution)?;
    // xatlas prints warnings (charts it could not parameterise well) on standard output, where
    // they would break `cssm bake --json`; the atlas is checked here instead.
    xatlas_rs::silence_messages();
    xatlas_rs::abort_on_failed_allocation();
    let mut atlas = xatlas_rs::Xatlas::new();
    atlas.add_mesh(&xatlas_rs::MeshDecl {
        vertex_count: welded.len() as u32,
        vertex_position_data: bytemuck::cast_slice(&positions),
        vertex_position_stride: 12,
        index_count: indices.len() as u32,
        index_data: bytemuck::cast_slice(&indices),
        index_format: xatlas_rs::IndexFormat::Uint32,
        ..Default::default()
    });
    // xatlas' parameterisation grows much faster than linearly with the faces of a chart (67 s
    // for the 69k-triangle bunny in 39 charts, 3 s in 364): cap the chart area so that a chart
    // holds about `FACES_PER_CHART` faces of average size. Scenes of big flat faces (the
    // Cornell box) are not capped and keep one chart per wall.
    let triangles = scene.triangles.len() as f64;
    let max_chart_area = if triangles > FACES_PER_CHART {
        (area * FACES_PER_CHART / triangles) as f32
    } else {
        0.0
    };
    // xatlas' steps report a percentage (from its worker threads, one call at a time).
    fn percent<'a>(
        stage: Stage,
        progress: &'a mut (dyn FnMut(Progress) + Send),
    ) -> impl FnMut(xatlas_rs::ProgressCategory, i32) + Send + 'a {
        move |_, done| {
            progress(Progress {
                stage,
                done: done.clamp(0, 100) as u64,
                total: 100,
            })
        }
    }
    atlas.compute_charts_with_progress(
        xatlas_rs::ChartOptions {
            max_chart_area,
            ..Default::default()
        },
        percent(Stage::Charts, progress),
    );
    atlas.parameterize_charts_with_progress(percent(Stage::Parameterize, progress));
    // Every defined texel is a depth map, so the page should hold as much surface as it can:
    // charts are packed by their conservative footprint with no padding (no texel centre can
    // fall in two charts, and the query's sender filter keeps to one chart), with many
    // placement attempts, and at the largest scale that fits (bisection once a scale fits).
    // On the 3,604-face church at atlas 128 this holds 6,920 depth maps instead of 4,990.
    let mut attempts = 0;
    let mut pack = |atlas: &mut xatlas_rs::Xatlas, texels_per_unit: f32| {
        attempts += 1;
        progress(Progress {
            stage: Stage::Pack,
            done: attempts,
            total: 0,
        });
        atlas.pack_charts(xatlas_rs::PackOptions {
            attempts: 4096,
            texels_per_unit,
            resolution,
            conservative: true,
            padding: 0,
            ..Default::default()
        });
        on_one_page(atlas, resolution)
    };
    let mut fits = false;
    let mut too_big = None;
    for _attempt in 0..32 {
        if pack(&mut atlas, texels_per_unit) {
            fits = true;
            break;
        }
        too_big = Some(texels_per_unit);
        texels_per_unit *= SHRINK;
    }
    if fits && let Some(mut high) = too_big {
        // The scale lies in (texels_per_unit, high): four halvings bring it within 0.5%.
        let mut low = texels_per_unit;
        let mut packed_at_low = true;
        for _ in 0..4 {
            let mid = 0.5 * (low + high);
            packed_at_low = pack(&mut atlas, mid);
            if packed_at_low {
                low = mid;
            } else {
                high = mid;
            }
        }
        if !packed_at_low {
            pack(&mut atlas, low);
        }
    }
    if !fits {
        return Err(BakeError::Atlas(format!(
            "xatlas could not fit the scene's {} charts on one {resolution}x{resolution} page \
             (every chart needs texels of its own); try a larger --atlas",
            atlas.meshes().first().map_or(0, |m| m.charts.len())
        )));
    }
    let meshes = atlas.meshes();
    let Some(mesh) = meshes.first() else {
        return Err(BakeError::Atlas("xatlas returned no mesh".into()));
    };
    if mesh.indices.len() != indices.len() {
        return Err(BakeError::Atlas(format!(
            "xatlas returned {} triangles for {} input triangles",
            mesh.indices.len() / 3,
            indices.len() / 3
        )));
    }
    // Chart of every output vertex: xatlas splits vertices along chart seams.
    let mut vertex_chart = vec![u32::MAX; mesh.vertices.len()];
    for (c, chart) in mesh.charts.iter().enumerate() {
        for &i in chart.indices {
            vertex_chart[i as usize] = c as u32;
        }
    }
    let mut next_chart = mesh.charts.len() as u32;
    let mut uvs = Vec::with_capacity(scene.triangles.len());
    let mut charts = Vec::with_capacity(scene.triangles.len());
    for tri in mesh.indices.chunks_exact(3) {
        let corner = |k: usize| mesh.vertices[tri[k] as usize].uv;
        uvs.push([corner(0), corner(1), corner(2)]);
        let mut chart = vertex_chart[tri[0] as usize];
        if chart == u32::MAX {
            // A triangle xatlas left out of every chart becomes a chart of its own.
            chart = next_chart;
            next_chart += 1;
        }
        charts.push(chart);
    }
    Ok((uvs, charts))
}

/// Refuses, before xatlas sees them, scenes of more separate pieces than it takes
/// ([`MAX_ATLAS_PIECES`]) or than the page has texels (every piece is a chart of its own, and a
/// chart needs at least one texel).
fn check_pieces(indices: &[u32], resolution: u32) -> Result<(), BakeError> {
    let pieces = count_pieces(indices);
    let texels = resolution as usize * resolution as usize;
    if pieces > MAX_ATLAS_PIECES {
        return Err(BakeError::Atlas(format!(
            "the scene is {pieces} separate pieces of surface (triangles joined to the rest by no \
             shared edge), more than the {MAX_ATLAS_PIECES} the atlas stage takes: xatlas' memory \
             and time grow with every piece; weld the pieces' vertices or remove small ones"
        )));
    }
    if pieces > texels {
        let side = (pieces as f64).sqrt().ceil() as u32;
        return Err(BakeError::Atlas(format!(
            "the scene is {pieces} separate pieces of surface, each a chart of its own, and a \
             {resolution}x{resolution} atlas has {texels} texels: use --atlas {} or larger",
            side.next_power_of_two().max(side)
        )));
    }
    Ok(())
}

/// The number of edge-connected pieces of the triangles `indices` (three per triangle), as
/// xatlas groups faces into charts.
fn count_pieces(indices: &[u32]) -> usize {
    let triangles = indices.len() / 3;
    let mut parent: Vec<u32> = (0..triangles as u32).collect();
    fn root(parent: &mut [u32], mut t: u32) -> u32 {
        while parent[t as usize] != t {
            let up = parent[parent[t as usize] as usize];
            parent[t as usize] = up;
            t = up;
        }
        t
    }
    let mut first_on_edge = std::collections::HashMap::with_capacity(indices.len());
    for (t, tri) in indices.chunks_exact(3).enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let other = *first_on_edge
                .entry((a.min(b), a.max(b)))
                .or_insert(t as u32);
            let (x, y) = (root(&mut parent, other), root(&mut parent, t as u32));
            parent[x as usize] = y;
        }
    }
    (0..triangles as u32)
        .filter(|&t| root(&mut parent, t) == t)
        .count()
}

/// Whether the last packing put every chart on a single `resolution`-sized page. xatlas reports
/// one page also when a chart larger than the page was placed anyway, the page grown around it
/// (a 20x10 floor at the scale that fills 75% of the page): such a pack does not fit.
fn on_one_page(atlas: &mut xatlas_rs::Xatlas, resolution: u32) -> bool {
    let (width, height) = atlas.size();
    let page = 0.0..=resolution as f32;
    atlas.atlas_count() == 1
        && width <= resolution
        && height <= resolution
        && atlas.meshes().iter().all(|mesh| {
            mesh.vertices
                .iter()
                .all(|v| v.uv.iter().all(|c| page.contains(c)))
        })
}

/// Merges vertices with bit-identical positions (`-0.0` and `0.0` alike); returns the distinct
/// positions in order of first use and the index of each input vertex among them.
fn weld(positions: &[Vec3]) -> (Vec<Vec3>, Vec<u32>) {
    let mut first: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    let mut out = Vec::new();
    let remap = positions
        .iter()
        .map(|p| {
            let key = p.to_array().map(|c| if c == 0.0 { 0 } else { c.to_bits() });
            *first.entry(key).or_insert_with(|| {
                out.push(*p);
                out.len() as u32 - 1
            })
        })
        .collect();
    (out, remap)
}

pub use cssm_raycast::triangle_area;

/// Barycentric coordinates of `p` in the 2D triangle `abc`, or `None` for a degenerate one.
fn barycentric(p: Vec2, a: Vec2, b: Vec2, c: Vec2) -> Option<Vec3> {
    let det = (b - a).perp_dot(c - a);
    if det.abs() < 1e-12 {
        return None;
    }
    let l1 = (p - a).perp_dot(c - a) / det;
    let l2 = (b - a).perp_dot(p - a) / det;
    Some(Vec3::new(1.0 - l1 - l2, l1, l2))
}

#[derive(Clone, Copy)]
struct Slot {
    triangle: u32,
    bary: Vec3,
    area: f32,
}

/// Rasterises every triangle into the atlas; returns the defined texels in row-major order.
fn rasterise(scene: &Scene, resolution: u32, uvs: &[[[f32; 2]; 3]], charts: &[u32]) -> Vec<Texel> {
    let r = resolution as usize;
    let mut grid: Vec<Option<Slot>> = vec![None; r * r];
    let mut owned: Vec<Vec<usize>> = vec![Vec::new(); scene.triangles.len()];
    let mut small: Vec<usize> = Vec::new();
    for (t, uv) in uvs.iter().enumerate() {
        let [a, b, c] = uv.map(Vec2::from);
        let lo = a.min(b).min(c);
        let hi = a.max(b).max(c);
        let x0 = (lo.x - 0.5).ceil().max(0.0) as usize;
        let y0 = (lo.y - 0.5).ceil().max(0.0) as usize;
        let x1 = ((hi.x - 0.5).floor() as i64).min(r as i64 - 1);
        let y1 = ((hi.y - 0.5).floor() as i64).min(r as i64 - 1);
        for y in y0 as i64..=y1 {
            for x in x0 as i64..=x1 {
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let Some(l) = barycentric(p, a, b, c) else {
                    continue;
                };
                if l.min_element() < -1e-6 {
                    continue;
                }
                let cell = y as usize * r + x as usize;
                if grid[cell].is_none() {
                    grid[cell] = Some(Slot {
                        triangle: t as u32,
                        bary: l.max(Vec3::ZERO) / l.max(Vec3::ZERO).element_sum(),
                        area: 0.0,
                    });
                    owned[t].push(cell);
                }
            }
        }
        if owned[t].is_empty() {
            small.push(t);
        }
    }
    // Area: each triangle's world area shared evenly by the texels it owns (§3.2.3 "area").
    for (t, cells) in owned.iter().enumerate() {
        if cells.is_empty() {
            continue;
        }
        let share = triangle_area(scene.triangle(t)) / cells.len() as f32;
        for &cell in cells {
            if let Some(slot) = grid[cell].as_mut() {
                slot.area += share;
            }
        }
    }
    // Triangles below texel size: give them the texel under their centroid.
    for t in small {
        let centroid = uvs[t].map(Vec2::from).iter().copied().sum::<Vec2>() / 3.0;
        let x = (centroid.x.floor() as i64).clamp(0, r as i64 - 1) as usize;
        let y = (centroid.y.floor() as i64).clamp(0, r as i64 - 1) as usize;
        let cell = y * r + x;
        let area = triangle_area(scene.triangle(t));
        match grid[cell].as_mut() {
            Some(slot) => slot.area += area,
            None => {
                grid[cell] = Some(Slot {
                    triangle: t as u32,
                    bary: Vec3::splat(1.0 / 3.0),
                    area,
                });
            }
        }
    }
    let mut texels = Vec::new();
    // Dense chart ids in order of first appearance (charts without texels vanish).
    let mut dense = vec![u32::MAX; charts.iter().copied().max().map_or(0, |m| m as usize + 1)];
    let mut next_chart = 0u32;
    for (cell, slot) in grid.iter().enumerate() {
        let Some(slot) = slot else { continue };
        let t = slot.triangle as usize;
        let [a, b, c] = scene.triangle(t);
        let position = a * slot.bary.x + b * slot.bary.y + c * slot.bary.z;
        let normal = (b - a).cross(c - a).normalize_or_zero();
        texels.push(Texel {
            position: position.to_array(),
            normal: normal.to_array(),
            area: slot.area,
            material: scene.triangle_materials[t],
            chart: {
                let c = &mut dense[charts[t] as usize];
                if *c == u32::MAX {
                    *c = next_chart;
                    next_chart += 1;
                }
                *c
            },
            object: scene.object_of(t) as u32,
            x: (cell % r) as u16,
            y: (cell / r) as u16,
        });
    }
    texels
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w` x `d` floor at height 0 with corner `(x, z)`, as two triangles.
    fn floor(
        positions: &mut Vec<Vec3>,
        triangles: &mut Vec<[u32; 3]>,
        x: f32,
        z: f32,
        w: f32,
        d: f32,
    ) {
        let base = positions.len() as u32;
        positions.extend([
            Vec3::new(x, 0.0, z),
            Vec3::new(x + w, 0.0, z),
            Vec3::new(x + w, 0.0, z + d),
            Vec3::new(x, 0.0, z + d),
        ]);
        triangles.extend([[base, base + 2, base + 1], [base, base + 3, base + 2]]);
    }

    #[test]
    fn pieces_are_the_edge_connected_sets_of_triangles() {
        assert_eq!(count_pieces(&[0, 1, 2, 0, 2, 3]), 1);
        assert_eq!(count_pieces(&[0, 1, 2, 3, 4, 5]), 2);
        // Sharing one vertex is not sharing an edge: xatlas charts them apart.
        assert_eq!(count_pieces(&[0, 1, 2, 0, 3, 4]), 2);
        assert_eq!(count_pieces(&[0, 1, 2, 3, 4, 5, 1, 2, 3, 3, 4, 2]), 1);
    }

    /// A single chart longer than it is wide (a 20x10 floor, a 2x1 rectangle, a triangle) was
    /// packed by xatlas on a page grown around it at the first scale and accepted as one page:
    /// the bake then failed its own file's check. Every chart now lies on the page.
    #[test]
    fn single_charts_of_any_shape_lie_on_the_page() {
        for (w, d) in [(20.0, 10.0), (2.0, 1.0), (1.0, 1.0), (7.0, 0.5)] {
            let (mut positions, mut triangles) = (Vec::new(), Vec::new());
            floor(&mut positions, &mut triangles, 0.0, 0.0, w, d);
            let scene = Scene::from_triangles(positions, triangles);
            for resolution in [32, 64, 256] {
                let atlas = build(&scene, resolution, &mut |_| {}).unwrap();
                let page = 0.0..=resolution as f32;
                assert!(
                    atlas
                        .triangle_uvs
                        .iter()
                        .flatten()
                        .flatten()
                        .all(|c| page.contains(c)),
                    "{w}x{d} at {resolution}: {:?}",
                    atlas.triangle_uvs
                );
                assert!(
                    atlas.texels.len() as f32
                        > 0.25 * (resolution * resolution) as f32 * (d / w).min(1.0)
                );
            }
        }
    }

    #[test]
    fn more_pieces_than_texels_or_than_the_limit_are_refused_before_xatlas() {
        let (mut positions, mut triangles) = (Vec::new(), Vec::new());
        for i in 0..40 * 40 {
            floor(
                &mut positions,
                &mut triangles,
                (i % 40) as f32 * 2.0,
                (i / 40) as f32 * 2.0,
                1.0,
                1.0,
            );
        }
        let scene = Scene::from_triangles(positions, triangles);
        let e = build(&scene, 32, &mut |_| {}).unwrap_err().to_string();
        assert!(
            e.contains("1600 separate pieces") && e.contains("--atlas 64"),
            "{e}"
        );
        let many: Vec<u32> = (0..3 * (MAX_ATLAS_PIECES as u32 + 1)).collect();
        assert_eq!(count_pieces(&many), MAX_ATLAS_PIECES + 1);
        let e = check_pieces(&many, 1024).unwrap_err().to_string();
        assert!(
            e.contains(&format!("more than the {MAX_ATLAS_PIECES}")),
            "{e}"
        );
    }
}
