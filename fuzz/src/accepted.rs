//! What is done with an input the library accepted: used as its callers use it
//! ([`check_file`], [`check_scene`]), which must not panic either.

use super::*;

/// Most run-data lookups one check makes (larger files are sampled).
pub(crate) const MAX_LOOKUPS: u64 = 1 << 20;
/// Largest run data (offsets plus runs) that gets the encode / decode round trip.
pub(crate) const MAX_ROUND_TRIP_WORDS: usize = 1 << 16;

/// Uses a file that [`cssm::decode`] accepted as the runtime and the tools do; none of it may
/// panic. With `scene` (a scene the file passed [`cssm::validate_for_scene`] against), also the
/// queries from the scene's triangles.
pub fn check_file(file: &CssmFile, scene: Option<&Scene>) {
    // Every (map, pixel) lookup (sampled when there are very many).
    let runs = &file.runs;
    let total = u64::from(runs.map_count) * u64::from(runs.pixel_count);
    let stride = total.div_ceil(MAX_LOOKUPS).max(1);
    let mut k = 0;
    while k < total {
        let (map, pixel) = (
            k / u64::from(runs.pixel_count),
            k % u64::from(runs.pixel_count),
        );
        let _ = runs.lookup(map as u32, pixel as u32);
        k += stride;
    }

    // The hierarchy: every node's leaves and children, and the cuts at both extremes.
    let h = &file.hierarchy;
    for i in 0..h.nodes.len() {
        let _ = h.leaves(i);
        if let Some((l, r)) = h.children(i) {
            assert!(
                l < h.nodes.len() && r < h.nodes.len(),
                "node {i}: children {l}, {r}"
            );
        }
    }
    let leaves_of =
        |cut: &[usize]| -> u64 { cut.iter().map(|&i| u64::from(h.nodes[i].count)).sum() };
    assert_eq!(leaves_of(&h.cut(|_, _| false)), file.texels.len() as u64);
    assert_eq!(leaves_of(&h.cut(|_, _| true)), file.texels.len() as u64);

    // Visibility queries between a few texels, with and without the filters.
    let count = file.texels.len() as u32;
    let few: Vec<u32> = (0..count).step_by((count as usize / 8).max(1)).collect();
    for options in [
        QueryOptions::default(),
        QueryOptions {
            bias_near: 1.0,
            bias_relative: 0.01,
            pcf: false,
            sender_filter: false,
            both_ends: false,
        },
    ] {
        let q = VisibilityQuery::new(file, options);
        for &sender in &few {
            for &receiver in &few {
                let t = &file.texels[receiver as usize];
                let _ = q.visibility(sender, t.pos());
                let _ = q.visibility_oriented(sender, t.pos(), Some(t.nrm()));
                let _ = q.depth_code(sender, receiver % runs.pixel_count);
            }
            let t = &file.texels[sender as usize];
            let at = glam::Vec2::new(f32::from(t.x) + 0.5, f32::from(t.y) + 0.5);
            let _ = q.visibility_from_atlas(at, glam::Vec3::ZERO, None);
        }
        if let Some(scene) = scene {
            // As a renderer does: a surface point of every triangle against a receiver.
            let n = scene.triangles.len();
            for tri in 0..n {
                let [a, b, c] = scene.triangle(n - 1 - tri);
                let p_i = (a + b + c) / 3.0;
                let third = [1.0 / 3.0; 3];
                let _ = q.visibility_from_surface(tri, third, p_i, Some((b - a).cross(c - a)));
                let _ = q.sender_texels(tri, [1.0, 0.0, 0.0]);
            }
        }
    }

    // An accepted file encodes (both codings) and decodes back to itself.
    if runs.offsets.len() + runs.runs.len() <= MAX_ROUND_TRIP_WORDS {
        for coding in [FileCoding::Plain, FileCoding::Packed] {
            let bytes = cssm::encode_with(file, coding)
                .unwrap_or_else(|e| panic!("a decoded file does not encode ({coding}): {e}"));
            let back = cssm::decode(&bytes)
                .unwrap_or_else(|e| panic!("an encoded file does not decode ({coding}): {e}"));
            assert!(
                back == *file,
                "decode(encode(file)) differs from file ({coding})"
            );
        }
    }
}

/// Uses a scene that [`Scene::load`] accepted as the bake and the renderers do: every index in
/// range, the lengths the fields' docs promise, finite geometry, no degenerate triangle.
pub fn check_scene(s: &Scene) {
    let n = s.positions.len();
    assert!(!s.triangles.is_empty(), "a loaded scene without triangles");
    assert!(
        s.positions.iter().all(|p| p.is_finite()),
        "a non-finite position"
    );
    assert!(
        s.texcoords.is_empty() || s.texcoords.len() == n,
        "{} texcoords for {n} positions",
        s.texcoords.len()
    );
    assert_eq!(
        s.triangle_materials.len(),
        s.triangles.len(),
        "triangle_materials and triangles differ in length"
    );
    for t in 0..s.triangles.len() {
        let tri = s.triangles[t];
        assert!(
            tri.iter().all(|&i| (i as usize) < n),
            "triangle {t} {tri:?} indexes past the {n} positions"
        );
        let m = s.triangle_materials[t];
        assert!(
            (m as usize) < s.materials.len(),
            "triangle {t} has material {m} of {}",
            s.materials.len()
        );
        let [a, b, c] = s.triangle(t).map(|v| v.as_dvec3());
        let area2 = (b - a).cross(c - a).length_squared();
        assert!(
            area2 > 0.0,
            "triangle {t} is degenerate (kept by the loader)"
        );
        assert!(
            s.object_of(t) < s.objects.len(),
            "triangle {t} has no object"
        );
    }
    if let Err(e) = s.check_objects() {
        panic!("Scene::objects broken: {e}");
    }
    for m in &s.materials {
        let values = m.kd.iter().chain(&m.ks).chain([&m.ns]);
        assert!(
            values.clone().all(|v| v.is_finite() && *v >= 0.0),
            "material `{}`: negative or non-finite Kd, Ks or Ns",
            m.name
        );
    }
    assert!(!s.lights.is_empty(), "a loaded scene without lights");
    assert!(
        s.diameter().is_finite(),
        "diameter {} not finite",
        s.diameter()
    );
    // Not crashes, but worth a look: a camera or light at infinity renders nothing useful.
    let c = &s.camera;
    if !(c.position.is_finite() && c.target.is_finite() && c.up.is_finite()) {
        note(
            "camera-not-finite",
            &format!(
                "the camera is not finite: position {}, target {}, up {} (scene diameter {})",
                c.position,
                c.target,
                c.up,
                s.diameter()
            ),
        );
    }
    for (i, l) in s.lights.iter().enumerate() {
        if !(l.position.is_finite()
            && l.direction.is_finite()
            && l.intensity.iter().all(|v| v.is_finite()))
        {
            note(
                "light-not-finite",
                &format!(
                    "light {i} is not finite: position {}, direction {}, intensity {:?} (scene \
                     diameter {})",
                    l.position,
                    l.direction,
                    l.intensity,
                    s.diameter()
                ),
            );
        }
    }
}
