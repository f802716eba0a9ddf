//! Bump and normal maps: the high-frequency surface detail of the CSSM paper's Fig. 1 (right),
//! which tilts the shading normal of the G-buffer (hence of the direct light and the final
//! gather) and of the CPU references (`docs/scene-format.md`, *Bump and normal maps*).
//!
//! Every map reaches the GPU as a tangent-space normal map, one layer of the scene's texture
//! array: a height map is turned into one on load ([`height_to_normals`]), a normal map is
//! decoded and scaled ([`decode_normals`]). A layer holds unit normals as floats in `[-1, 1]`
//! (the array is `Rgba32Float`), so the bilinear sample of `albedo_sample` on the GPU and of
//! [`crate::load::AlbedoTexture::sample`] on the CPU are the same numbers. Each triangle gets a
//! flat tangent frame from its positions and UVs ([`tangent_frame`], the vertex buffer carries
//! it) and [`perturb`] (twin of `perturb_normal` in `common/albedo.wgsl`) tilts the geometric
//! normal by the sample.

use glam::Vec3;

use crate::load::TEXTURE_SIZE;

/// Height of a white texel at bump multiplier 1, in units of the texture's side (UV 0 to 1):
/// a height map's grey level `g` is a height of `multiplier * g * BUMP_HEIGHT` (MTL `-bm`
/// multiplies it). One 512th of the texture, so at multiplier 1 a map rising from black to
/// white over one texel of a 512-texel image is a 45-degree slope. Fixed in UV units (not in
/// texels of [`TEXTURE_SIZE`], nor in world units), the look depends neither on the
/// resampling nor on the scene's scale.
pub const BUMP_HEIGHT: f32 = 1.0 / 512.0;

/// The least cosine between the shading normal and the geometric normal on the side the eye
/// sees: a tilt past it is pulled back to it, so no pixel shades from below its own surface
/// (black or light leaking from behind) whatever the map holds.
pub const MIN_SHADING_COS: f32 = 0.05;

/// Below this length a vector has no direction for [`perturb`].
const TINY: f32 = 1e-12;

/// A height map of [`TEXTURE_SIZE`]² grey levels (row-major, row 0 the top of the image, v
/// up) turned into unit tangent-space normals (x along +u, y along +v, z out of the surface):
/// central differences with repeat wrapping of the height `multiplier * g * BUMP_HEIGHT`
/// (UV units), the normal of the height field being `(-dh/du, -dh/dv, 1)` normalised.
pub fn height_to_normals(grey: &[f32], multiplier: f32) -> Vec<[f32; 3]> {
    let n = TEXTURE_SIZE as usize;
    assert_eq!(
        grey.len(),
        n * n,
        "a height map of TEXTURE_SIZE squared texels"
    );
    // Texels per unit of UV, over two texels of central difference.
    let per_uv = multiplier * BUMP_HEIGHT * TEXTURE_SIZE as f32 / 2.0;
    (0..n * n)
        .map(|i| {
            let (x, y) = (i % n, i / n);
            let at = |x: usize, y: usize| grey[(y % n) * n + (x % n)];
            let dh_du = (at(x + 1, y) - at(x + n - 1, y)) * per_uv;
            // Rows run down the image, v up it.
            let dh_dv = (at(x, y + n - 1) - at(x, y + 1)) * per_uv;
            Vec3::new(-dh_du, -dh_dv, 1.0).normalize().to_array()
        })
        .collect()
}

/// Texels of a tangent-space normal map (RGB in `[0, 1]` as stored, not sRGB-decoded) turned
/// into unit normals: `2c - 1` with x and y times `scale` (glTF `normalTexture.scale`),
/// normalised; a texel that decodes to zero length is the unperturbed `(0, 0, 1)`.
pub fn decode_normals(rgb: &[[f32; 3]], scale: f32) -> Vec<[f32; 3]> {
    rgb.iter()
        .map(|c| {
            let n = Vec3::new(
                (2.0 * c[0] - 1.0) * scale,
                (2.0 * c[1] - 1.0) * scale,
                2.0 * c[2] - 1.0,
            );
            n.try_normalize().unwrap_or(Vec3::Z).to_array()
        })
        .collect()
}

/// The flat tangent frame of a triangle with corners `p` and texture coordinates `uv`: the unit
/// tangent (the direction of +u in the triangle's plane) and the handedness, +1 when +v runs
/// along `normal x tangent` (`normal` the winding's, `(p1 - p0) x (p2 - p0)`), -1 where the UVs
/// are mirrored. `None` for a triangle whose UVs (or positions) span no area: it gets no
/// perturbation. The bitangent is `handedness * normal x tangent`, orthogonal to both.
pub fn tangent_frame(p: [Vec3; 3], uv: [[f32; 2]; 3]) -> Option<(Vec3, f32)> {
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let (du1, dv1) = (uv[1][0] - uv[0][0], uv[1][1] - uv[0][1]);
    let (du2, dv2) = (uv[2][0] - uv[0][0], uv[2][1] - uv[0][1]);
    let det = du1 * dv2 - du2 * dv1;
    let normal = e1.cross(e2).try_normalize()?;
    // dp/du and dp/dv solve [e1 e2] = [dp/du dp/dv] [du1 du2; dv1 dv2]; dividing by |det|
    // keeps their directions and makes a tiny UV area no worse than a large one.
    if det.abs() <= f32::EPSILON * (du1.abs() + du2.abs()) * (dv1.abs() + dv2.abs()) {
        return None;
    }
    let sign = det.signum();
    let dp_du = (e1 * dv2 - e2 * dv1) * sign;
    let dp_dv = (e2 * du1 - e1 * du2) * sign;
    let tangent = (dp_du - normal * normal.dot(dp_du)).try_normalize()?;
    let handedness = if normal.cross(tangent).dot(dp_dv) < 0.0 {
        -1.0
    } else {
        1.0
    };
    Some((tangent, handedness))
}

/// The shading normal at a point whose map sample (bilinear, [`crate::load::AlbedoTexture::sample`])
/// is `sample`, on a surface of unit geometric normal `n` (turned towards the eye) with the unit
/// tangent `t` and bitangent `b` of its frame turned with it (negated together with `n` when
/// the back is seen, so that the back's normal is the front's negated). Kept at least
/// [`MIN_SHADING_COS`] above the surface; a zero sample or a degenerate result gives `n`.
/// Twin of `perturb_normal` in `common/albedo.wgsl`.
pub fn perturb(sample: Vec3, n: Vec3, t: Vec3, b: Vec3) -> Vec3 {
    // The same operations, in the same order, as the WGSL twin.
    let p = t * sample.x + b * sample.y + n * sample.z;
    let length = p.length();
    if length.is_nan() || length <= TINY {
        return n;
    }
    let p = p / length;
    let d = p.dot(n);
    if d >= MIN_SHADING_COS {
        return p;
    }
    let along = p - n * d;
    let length = along.length();
    if length.is_nan() || length <= TINY {
        return n;
    }
    n * MIN_SHADING_COS + along / length * (1.0 - MIN_SHADING_COS * MIN_SHADING_COS).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).abs().max_element() <= tol
    }

    #[test]
    fn a_flat_height_map_gives_the_unperturbed_normal() {
        let n = TEXTURE_SIZE as usize;
        for g in [0.0, 0.5, 1.0] {
            let normals = height_to_normals(&vec![g; n * n], 3.0);
            assert!(normals.iter().all(|&v| v == [0.0, 0.0, 1.0]));
        }
    }

    /// A grey ramp rising along +u by `k` per texel is the height `m k g BUMP_HEIGHT` per
    /// texel, i.e. the slope `dh/du = m k BUMP_HEIGHT TEXTURE_SIZE`; the normal is
    /// `(-slope, 0, 1)` normalised (away from the wrap-around seam). Likewise along +v,
    /// which runs up the image.
    #[test]
    fn a_linear_ramp_gives_the_analytic_normal() {
        let n = TEXTURE_SIZE as usize;
        let k = 1.0 / 1024.0;
        let m = 64.0;
        let slope = m * k * BUMP_HEIGHT * TEXTURE_SIZE as f32;
        let along_u: Vec<f32> = (0..n * n).map(|i| (i % n) as f32 * k).collect();
        let expected = Vec3::new(-slope, 0.0, 1.0).normalize();
        let normals = height_to_normals(&along_u, m);
        for y in [0, 7, n - 1] {
            for x in 1..n - 1 {
                let got = Vec3::from(normals[y * n + x]);
                assert!(close(got, expected, 1e-5), "{x},{y}: {got} vs {expected}");
            }
        }
        // The seam (the ramp drops back to 0) tilts the other way.
        assert!(normals[0][0] > 0.0);
        // Rows run down the image: a grey rising down the rows falls along +v.
        let down_rows: Vec<f32> = (0..n * n).map(|i| (i / n) as f32 * k).collect();
        let normals = height_to_normals(&down_rows, m);
        let expected = Vec3::new(0.0, slope, 1.0).normalize();
        let got = Vec3::from(normals[100 * n + 3]);
        assert!(close(got, expected, 1e-5), "{got} vs {expected}");
        // A negative multiplier turns bumps into dents.
        let got = Vec3::from(height_to_normals(&along_u, -m)[100 * n + 3]);
        assert!(close(got, Vec3::new(slope, 0.0, 1.0).normalize(), 1e-5));
        // At -bm 1, black to white over one texel (2 texels of central difference) is 45
        // degrees: slope 1.
        let step: Vec<f32> = (0..n * n).map(|i| (i % n) as f32).collect();
        let got = Vec3::from(height_to_normals(&step, 1.0)[5]);
        assert!(
            close(got, Vec3::new(-1.0, 0.0, 1.0).normalize(), 1e-5),
            "{got}"
        );
    }

    #[test]
    fn normal_map_texels_decode_and_scale() {
        let got = decode_normals(&[[0.5, 0.5, 1.0], [1.0, 0.5, 0.5], [0.5, 0.5, 0.5]], 1.0);
        assert_eq!(got, vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
        let c = [0.75, 0.5, 0.5 + 0.5 * 0.75f32.sqrt()];
        let got = Vec3::from(decode_normals(&[c], 0.5)[0]);
        let expected = Vec3::new(0.25, 0.0, 0.75f32.sqrt()).normalize();
        assert!(close(got, expected, 1e-6), "{got} vs {expected}");
    }

    #[test]
    fn tangent_frames_follow_the_uvs() {
        let p = [
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.0, 3.0, 0.0),
        ];
        // u along x, v along y: tangent +x, right-handed about +z.
        let (t, s) = tangent_frame(p, [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]).unwrap();
        assert!(close(t, Vec3::X, 1e-6) && s == 1.0, "{t} {s}");
        // Mirrored in u: tangent -x, left-handed (bitangent = -(z x -x) = +y, still +v).
        let (t, s) = tangent_frame(p, [[1.0, 0.0], [0.0, 0.0], [1.0, 1.0]]).unwrap();
        assert!(close(t, Vec3::NEG_X, 1e-6) && s == -1.0, "{t} {s}");
        let b = s * Vec3::Z.cross(t);
        assert!(close(b, Vec3::Y, 1e-6), "{b}");
        // Rotated UVs: u along y, v along -x.
        let (t, s) = tangent_frame(p, [[0.0, 0.0], [0.0, -2.0], [3.0, 0.0]]).unwrap();
        assert!(close(t, Vec3::Y, 1e-6) && s == 1.0, "{t} {s}");
        // Skewed UVs: the tangent is dp/du (v held), not the gradient of u: corner 1 is
        // (u, v) = (1, 0.5), so dp/du = p1 - 0.5 (p2 - p0) = (2, -1.5, 0).
        let (t, _) = tangent_frame(p, [[0.0, 0.0], [1.0, 0.5], [0.0, 1.0]]).unwrap();
        assert!(close(t, Vec3::new(0.8, -0.6, 0.0), 1e-6), "{t}");
        // A tilted triangle: the tangent lies in its plane.
        let q = [
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        let (t, _) = tangent_frame(q, [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]).unwrap();
        assert!(close(t, Vec3::new(1.0, 0.0, 1.0).normalize(), 1e-6), "{t}");
        // Degenerate UVs (all equal, or on one line): no frame.
        assert!(tangent_frame(p, [[0.5, 0.5]; 3]).is_none());
        assert!(tangent_frame(p, [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]).is_none());
        // A degenerate triangle: no frame.
        assert!(tangent_frame([Vec3::ZERO; 3], [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]).is_none());
    }

    /// A 2 x 2 quad at z = 0 facing +z (UVs 0 to 1 along x and y) whose material has the
    /// normal map `map`, a spot light 2 above its centre pointing down, seen from +z.
    fn lit_quad(map: Option<cssm_formats::NormalMap>) -> cssm_formats::Scene {
        let positions = vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ];
        let mut scene = cssm_formats::Scene::from_triangles(positions, vec![[0, 1, 2], [0, 2, 3]]);
        scene.texcoords = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        scene.materials[0].normal_map = map;
        scene.lights.push(cssm_formats::SpotLight {
            position: Vec3::new(0.0, 0.0, 2.0),
            direction: Vec3::NEG_Z,
            cutoff_deg: 80.0,
            intensity: [4.0; 3],
        });
        scene
    }

    /// The path tracer sees the normal map: under a constant map tilted by 40 degrees about
    /// +v, the direct light on the plane is the untilted one times `(n_s . l) / (n_g . l)`,
    /// pixel by pixel (the cosine law with the shading normal).
    #[test]
    fn the_path_tracer_shades_with_the_tilted_normal() {
        use crate::common::{camera::View, compose::Component};
        use crate::reference::{EmitterSampling, ReferenceOptions, render_reference};
        let dir = tempfile::tempdir().unwrap();
        let tilt = 40f32.to_radians();
        let encoded = Vec3::new(tilt.sin(), 0.0, tilt.cos()) * 0.5 + 0.5;
        let rgb = (encoded * 255.0).round().to_array().map(|c| c as u8);
        let file = dir.path().join("tilted.png");
        image::RgbImage::from_pixel(8, 8, image::Rgb(rgb))
            .save(&file)
            .unwrap();
        // What the loader makes of the quantised texel.
        let ns = Vec3::from(decode_normals(&[rgb.map(|c| c as f32 / 255.0)], 1.0)[0]);
        assert!((ns.dot(Vec3::Z) - tilt.cos()).abs() < 0.01, "{ns}");
        let map = cssm_formats::NormalMap {
            source: cssm_formats::TextureSource::File(file),
            kind: cssm_formats::NormalMapKind::Tangent { scale: 1.0 },
        };
        let options = ReferenceOptions {
            samples_per_pixel: 1,
            bounces: 0,
            converge: 0.0,
            component: Component::Direct,
            seed: 1,
            clamp: None,
            emitters: EmitterSampling::Mis,
        };
        let render = |scene: &cssm_formats::Scene| {
            let (materials, textures) = crate::load::cpu_materials(scene).expect("textures");
            let bvh = cssm_raycast::SceneBvh::new(scene);
            let view = View::of_scene(scene, 32, 24);
            let image = render_reference(
                scene,
                &view,
                &materials,
                &textures,
                &bvh,
                &options,
                &|_, _| {},
            );
            (image, view)
        };
        let tilted_scene = lit_quad(Some(map));
        let (tilted, view) = render(&tilted_scene);
        let (flat, _) = render(&lit_quad(None));
        let mut compared = 0;
        for (i, (t, f)) in tilted.iter().zip(&flat).enumerate() {
            if f.x <= 0.0 {
                continue;
            }
            let dir = view.primary_ray(i as u32 % 32, i as u32 / 32);
            let p = view.eye + dir * (-view.eye.z / dir.z);
            let l = (tilted_scene.lights[0].position - p).normalize();
            let expected = ns.dot(l).max(0.0) / l.z;
            assert!(
                (t.x / f.x - expected).abs() < 1e-3,
                "pixel {i}: {} vs {expected}",
                t.x / f.x
            );
            compared += 1;
        }
        assert!(compared > 150, "{compared} lit pixels");
        // The tilt shows: the centre is darker by about cos 40 degrees.
        let centre = 12 * 32 + 16;
        assert!((tilted[centre].x / flat[centre].x - tilt.cos()).abs() < 0.05);
    }

    /// An image that does not decode, as a bump map or as a normal map, is an error naming the
    /// file and what it was read as, not a panic.
    #[test]
    fn an_undecodable_map_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("broken-bump.png");
        std::fs::write(&file, b"\x89PNG\r\n\x1a\n not an image").unwrap();
        for (kind, what) in [
            (
                cssm_formats::NormalMapKind::Height { multiplier: 1.0 },
                "bump map",
            ),
            (
                cssm_formats::NormalMapKind::Tangent { scale: 1.0 },
                "normal map",
            ),
        ] {
            let map = cssm_formats::NormalMap {
                source: cssm_formats::TextureSource::File(file.clone()),
                kind,
            };
            let e = crate::load::cpu_materials(&lit_quad(Some(map))).unwrap_err();
            assert!(matches!(e, crate::RuntimeError::Texture { .. }), "{e:?}");
            let message = e.to_string();
            assert!(
                message.contains("broken-bump.png") && message.contains(what),
                "{message}"
            );
        }
    }

    /// A glTF `normalTexture` embedded in a GLB reaches the texture array as a normal layer:
    /// decoded as stored (not sRGB), its x and y times `scale`, normalised.
    #[test]
    fn an_embedded_gltf_normal_texture_becomes_a_normal_layer() {
        let texel = [200u8, 100, 230];
        let mut png = Vec::new();
        image::RgbImage::from_pixel(4, 4, image::Rgb(texel))
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        // The binary chunk: 4 positions, 4 texture coordinates, 6 indices, then the PNG.
        let mut bin = Vec::new();
        let positions = [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]];
        let uvs = [[0f32, 1.], [1., 1.], [1., 0.], [0., 0.]];
        for v in positions.iter().flatten().chain(uvs.iter().flatten()) {
            bin.extend_from_slice(&v.to_le_bytes());
        }
        for i in [0u32, 1, 2, 0, 2, 3] {
            bin.extend_from_slice(&i.to_le_bytes());
        }
        let png_offset = bin.len();
        bin.extend_from_slice(&png);
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        let mut json = format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
            "nodes": [{{"mesh": 0}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}},
              "indices": 2, "material": 0}}]}}],
            "materials": [{{"name": "bumpy", "normalTexture": {{"index": 0, "scale": 0.5}}}}],
            "textures": [{{"source": 0}}],
            "images": [{{"bufferView": 3, "mimeType": "image/png"}}],
            "buffers": [{{"byteLength": {}}}],
            "bufferViews": [
              {{"buffer": 0, "byteOffset": 0, "byteLength": 48}},
              {{"buffer": 0, "byteOffset": 48, "byteLength": 32}},
              {{"buffer": 0, "byteOffset": 80, "byteLength": 24}},
              {{"buffer": 0, "byteOffset": {png_offset}, "byteLength": {}}}],
            "accessors": [
              {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                "min": [0, 0, 0], "max": [1, 1, 0]}},
              {{"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}},
              {{"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"}}]}}"#,
            bin.len(),
            png.len()
        );
        while json.len() % 4 != 0 {
            json.push(' ');
        }
        let mut glb = Vec::new();
        let total = 12 + 8 + json.len() + 8 + bin.len();
        glb.extend_from_slice(b"glTF");
        glb.extend_from_slice(&2u32.to_le_bytes());
        glb.extend_from_slice(&(total as u32).to_le_bytes());
        glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
        glb.extend_from_slice(b"JSON");
        glb.extend_from_slice(json.as_bytes());
        glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        glb.extend_from_slice(b"BIN\0");
        glb.extend_from_slice(&bin);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bumpy.glb");
        std::fs::write(&path, glb).unwrap();
        let scene = cssm_formats::Scene::load(&path).expect("the GLB loads");
        let (materials, textures) = crate::load::cpu_materials(&scene).expect("textures");
        let m = materials[0];
        assert!(m.normal_texture >= 0 && m.texture < 0, "{m:?}");
        let c = texel.map(|c| c as f32 / 255.0);
        let expected = Vec3::new(
            (2.0 * c[0] - 1.0) * 0.5,
            (2.0 * c[1] - 1.0) * 0.5,
            2.0 * c[2] - 1.0,
        )
        .normalize();
        let layer = &textures[m.normal_texture as usize];
        assert!(
            layer
                .texels
                .iter()
                .all(|&t| close(Vec3::from(t), expected, 1e-6))
        );
        // Every triangle has a frame (the quad's UVs span area).
        assert!((0..2).all(|t| crate::load::triangle_tangent(&scene, t)[3] != 0.0));
    }

    #[test]
    fn perturbation_stays_above_the_surface() {
        let (n, t, b) = (Vec3::Z, Vec3::X, Vec3::Y);
        assert_eq!(perturb(Vec3::Z, n, t, b), Vec3::Z);
        let tilt = Vec3::new(0.6, 0.0, 0.8);
        assert!(close(perturb(tilt, n, t, b), tilt, 1e-6));
        // Seen from the back, the frame turns with the normal: the normal is negated whole.
        assert!(close(perturb(tilt, -n, -t, -b), -tilt, 1e-6));
        // Below the surface or in it: pulled back to MIN_SHADING_COS, towards the tilt.
        for s in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(1.0, 0.0, -0.5)] {
            let p = perturb(s, n, t, b);
            assert!((p.length() - 1.0).abs() < 1e-6 && (p.z - MIN_SHADING_COS).abs() < 1e-6);
            assert!(p.x > 0.9, "{p}");
        }
        // Straight below, or zero: the geometric normal.
        assert_eq!(perturb(Vec3::NEG_Z, n, t, b), n);
        assert_eq!(perturb(Vec3::ZERO, n, t, b), n);
    }
}
