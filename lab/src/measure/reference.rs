//! The reference of `cssm report error` and `cssm compare`: the path tracer's image of a scene
//! in two independent halves (their difference measures its noise), cached beside the report by
//! the scene's content and the settings (a sidecar JSON beside the EXR), and its PNG.

use std::{
    path::{Path, PathBuf},
    time::Instant,
};

use cssm_formats::Scene;
use cssm_runtime::{
    self as runtime,
    common::{
        camera::View,
        compose::Component,
        readback::{self, Image},
    },
    frame::FrameSettings,
    reference::{EmitterSampling, ReferenceOptions, render_reference},
};

use super::{rows_bar, write_text};
use crate::report::{
    error::{self, ReferenceNoise},
    error_write::{ReferenceSettings, ReferenceSidecar, SceneReference},
};

/// Seeds of the reference's two halves; `--method reference` draws from seed 0, so its image
/// is independent of the reference's.
const REFERENCE_SEEDS: [u64; 2] = [1, 2];

/// What a reference image is path traced with.
pub struct ReferenceSpec {
    /// Image size, exposure (a multiplier) of its PNG.
    pub frame: FrameSettings,
    /// Paths per pixel in all (split into two halves).
    pub samples: u32,
    /// Indirect bounces.
    pub bounces: u32,
    /// Which light it holds.
    pub component: Component,
}

/// Where a reference is kept: its linear radiance (EXR), its sidecar (what it was rendered
/// from, its noise) and its tone-mapped PNG.
pub struct ReferenceFiles {
    /// The EXR.
    pub exr: PathBuf,
    /// The sidecar (JSON).
    pub json: PathBuf,
    /// The PNG.
    pub png: PathBuf,
}

/// A reference image and what is known of it.
pub struct Reference {
    /// The image (the mean of both halves).
    pub image: Image,
    /// Its noise, time and whether it came from the cache.
    pub summary: SceneReference,
}

/// The scene's reference: from `files` when `reuse` is set and its sidecar matches the scene's
/// content and `spec`, else path traced in two halves and written there; its PNG either way.
///
/// # Errors
/// A scene the path tracer cannot take, a file that cannot be written; each names its path.
pub fn reference_image(
    scene: &Scene,
    spec: &ReferenceSpec,
    files: &ReferenceFiles,
    reuse: bool,
) -> Result<Reference, String> {
    let (w, h) = (spec.frame.width, spec.frame.height);
    let samples = spec.samples;
    let halves = [samples.div_ceil(2), samples / 2];
    let settings = ReferenceSettings {
        // The workspace's one version, which the `cssm` command shares.
        cssm_version: env!("CARGO_PKG_VERSION").into(),
        light_model: runtime::reference::LIGHT_MODEL,
        scene: scene.name.clone(),
        content_hash: cssm_formats::hash_hex(&scene.content_hash),
        width: w,
        height: h,
        samples,
        bounces: spec.bounces,
        component: spec.component.name().into(),
        seeds: REFERENCE_SEEDS,
        halves,
    };
    let summary = |noise: ReferenceNoise, seconds: f64, cached: bool| SceneReference {
        scene: scene.name.clone(),
        noise_floor: noise.relative_rmse,
        flip_floor: noise.flip,
        bias_noise: noise.bias,
        seconds,
        cached,
    };
    if reuse {
        match cached_reference(&files.exr, &files.json, &settings) {
            Ok((radiance, sidecar)) => {
                eprintln!("{}: reusing {}", scene.name, files.exr.display());
                let image = Image::from_cpu(w, h, radiance, spec.frame.exposure);
                readback::save_png(&files.png, &image)?;
                let noise = ReferenceNoise {
                    relative_rmse: sidecar.noise_floor,
                    flip: sidecar.flip_floor,
                    bias: sidecar.bias_noise,
                };
                return Ok(Reference {
                    image,
                    summary: summary(noise, sidecar.seconds, true),
                });
            }
            Err(why) => eprintln!("{}: path tracing the reference ({why})", scene.name),
        }
    }
    let start = Instant::now();
    let fail = |e: runtime::RuntimeError| format!("{}: {e}", scene.path.display());
    runtime::frame::check_size(w, h).map_err(fail)?;
    let (materials, textures) = runtime::load::cpu_materials(scene).map_err(fail)?;
    let bvh = cssm_raycast::SceneBvh::new(scene);
    let view = View::of_scene(scene, w, h);
    let parts = halves.iter().filter(|&&n| n > 0).count() as u64;
    let bar = rows_bar(
        parts * h as u64,
        format!(
            "{}: reference ({}), {samples} paths per pixel",
            scene.name, spec.component
        ),
    );
    let mut images = Vec::new();
    for (i, (&n, &seed)) in halves.iter().zip(&REFERENCE_SEEDS).enumerate() {
        if n == 0 {
            continue;
        }
        let options = ReferenceOptions {
            samples_per_pixel: n,
            bounces: spec.bounces,
            converge: 0.0,
            component: spec.component,
            seed,
            clamp: None,
            emitters: EmitterSampling::Mis,
        };
        let before = i as u64 * h as u64;
        let image = render_reference(
            scene,
            &view,
            &materials,
            &textures,
            &bvh,
            &options,
            &|done, _| bar.set_position(before + done / w.max(1) as u64),
        );
        images.push(
            image
                .iter()
                .map(|c| [c.x, c.y, c.z, 1.0])
                .collect::<Vec<_>>(),
        );
    }
    bar.finish_and_clear();
    let radiance = match images.as_slice() {
        [a, b] => error::combine(a, halves[0], b, halves[1]),
        [a] => a.clone(),
        _ => unreachable!("at least one path per pixel"),
    };
    let image = Image::from_cpu(w, h, radiance, spec.frame.exposure);
    let noise = match images.as_slice() {
        [a, b] => ReferenceNoise::measure(
            (w, h),
            (a, halves[0]),
            (b, halves[1]),
            (
                &image.display,
                &Image::from_cpu(w, h, a.clone(), spec.frame.exposure).display,
            ),
        ),
        _ => ReferenceNoise::default(),
    };
    let seconds = start.elapsed().as_secs_f64();
    eprintln!(
        "{}: reference ({}) at {w}x{h}, {samples} paths per pixel, in {seconds:.1} s",
        scene.name, spec.component
    );
    // The sidecar goes first and comes back last, so a sidecar never describes another EXR.
    if files.json.exists() {
        std::fs::remove_file(&files.json).map_err(|e| format!("{}: {e}", files.json.display()))?;
    }
    readback::save_exr(&files.exr, &image)?;
    let sidecar = ReferenceSidecar {
        settings,
        noise_floor: noise.relative_rmse,
        flip_floor: noise.flip,
        bias_noise: noise.bias,
        seconds,
    };
    let text = serde_json::to_string_pretty(&sidecar).map_err(|e| e.to_string())?;
    write_text(&files.json, &(text + "\n"))?;
    readback::save_png(&files.png, &image)?;
    Ok(Reference {
        image,
        summary: summary(noise, seconds, false),
    })
}

/// The cached reference's radiance and sidecar, or why it cannot be used.
fn cached_reference(
    exr: &Path,
    json: &Path,
    settings: &ReferenceSettings,
) -> Result<(Vec<[f32; 4]>, ReferenceSidecar), String> {
    let text = std::fs::read_to_string(json).map_err(|_| format!("no {}", json.display()))?;
    let sidecar: ReferenceSidecar =
        serde_json::from_str(&text).map_err(|e| format!("{} unreadable: {e}", json.display()))?;
    if sidecar.settings != *settings {
        return Err(format!("{} has other settings", json.display()));
    }
    let (width, height, radiance) = readback::load_radiance(exr)?;
    if (width, height) != (settings.width, settings.height) {
        return Err(format!("{} has another size", exr.display()));
    }
    Ok((radiance, sidecar))
}
