//! GPU tests of the runtime against its CPU references. They run on any Vulkan device; on a
//! machine without a GPU that is Mesa's lavapipe (`apt-get install mesa-vulkan-drivers`, which
//! `.ci/run` does). They never skip: without a device they fail and say how to get one.

use std::sync::OnceLock;

#[path = "gpu/depth_maps.rs"]
mod depth_maps;
#[path = "gpu/direct.rs"]
mod direct;
#[path = "gpu/emissive.rs"]
mod emissive;
#[path = "gpu/filters.rs"]
mod filters;
#[path = "gpu/final_gather.rs"]
mod final_gather;
#[path = "gpu/links.rs"]
mod links;
#[path = "gpu/methods.rs"]
mod methods;
#[path = "gpu/moving.rs"]
mod moving;
#[path = "gpu/normal_maps.rs"]
mod normal_maps;
#[path = "gpu/octree.rs"]
mod octree;
#[path = "gpu/query.rs"]
mod query;
#[path = "gpu/radiosity.rs"]
mod radiosity;
#[path = "gpu/renderer.rs"]
mod renderer;
#[path = "gpu/rsm.rs"]
mod rsm;
#[path = "gpu/ssil.rs"]
mod ssil;
#[path = "gpu/vct.rs"]
mod vct;
#[path = "gpu/vf.rs"]
mod vf;
#[path = "gpu/visibility.rs"]
mod visibility;
#[path = "gpu/voxelize.rs"]
mod voxelize;

use cssm_bake::BakeOptions;
use cssm_formats::{
    CssmFile, Scene, Traversal, visibility::QueryOptions, visibility::VisibilityQuery,
};
use cssm_raycast::{SplitMix64, SurfaceSampler};
use cssm_runtime::{
    Gpu, Renderer, RendererSettings,
    common::{
        compose::Component,
        readback::{Image, render_image},
    },
    frame::FrameSettings,
    load::CssmGpu,
    method::{self, Backend, CpuSetup, Energy, MethodEntry, OptionValue, OptionValues},
    visibility::{QueryKernel, QueryPair},
};

// Helpers the technique files share, defined beside the tests that use them most.
use radiosity::{
    GI_SHADOW, cornell32, cpu_receivers, final_gather_vs_twin, image_difference, interior,
    solve_atlas, vec3s,
};
use renderer::{block_scene, block_scene_of};
use visibility::random_pairs;

fn gpu() -> &'static Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| match Gpu::new_headless() {
        Ok(gpu) => {
            eprintln!("GPU tests on {}", gpu.describe());
            gpu
        }
        Err(e) => panic!("GPU tests need a Vulkan device: {e}"),
    })
}

/// A built-in scene (`scenes/NAME`) and its bake with `options`.
fn baked(name: &str, options: BakeOptions) -> (Scene, CssmFile) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(name);
    let scene = Scene::load(&dir).expect("built-in scene loads");
    let baked = cssm_bake::bake(&scene, &options, &mut |_| {}).expect("bake");
    (scene, baked.file)
}

fn cornell() -> &'static (Scene, CssmFile) {
    static CORNELL: OnceLock<(Scene, CssmFile)> = OnceLock::new();
    CORNELL.get_or_init(|| {
        let options = BakeOptions {
            atlas_resolution: 64,
            cube_resolution: 32,
            traversal: Traversal::Spiral,
            ..Default::default()
        };
        baked("cornell-box", options)
    })
}

/// What the tests ask of a frame: the options of the one-shot `render` the tests were written
/// against, mapped onto the [`Renderer`] and its method table by [`render`].
#[derive(Clone, Debug)]
struct RenderOptions {
    width: u32,
    height: u32,
    exposure: f32,
    shadow_resolution: u32,
    frames: u32,
    bounces: u32,
    threshold: f32,
    jitter: bool,
    component: Component,
    samples: u32,
    /// `lightcuts`' gather resolution: 1 (every pixel) unless a test asks, so that the twin
    /// tests hold the kernel itself.
    downsample: u32,
    /// `lightcuts`' gather form (its default `atlas`, or `walk`).
    gather: &'static str,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            exposure: 1.0,
            shadow_resolution: cssm_runtime::common::shadow_map::DEFAULT_RESOLUTION,
            frames: 1,
            bounces: 1,
            threshold: cssm_runtime::radiosity::DEFAULT_THRESHOLD,
            jitter: false,
            component: Component::Full,
            samples: 256,
            downsample: 1,
            gather: "atlas",
        }
    }
}

impl RenderOptions {
    /// The options `method` declares, from these; the others keep their defaults.
    fn values(&self, method: &MethodEntry) -> OptionValues {
        let mut values = OptionValues::default();
        for spec in method.options {
            let value = match spec.name {
                "bounces" => OptionValue::Count(self.bounces),
                "threshold" => OptionValue::Number(self.threshold),
                "jitter" => OptionValue::Switch(self.jitter),
                "samples" => OptionValue::Count(self.samples),
                "downsample" if method.name == "lightcuts" => OptionValue::Count(self.downsample),
                "gather" if method.name == "lightcuts" => OptionValue::Choice(self.gather),
                _ => continue,
            };
            values.set(spec.name, value);
        }
        values
    }

    fn settings(&self) -> RendererSettings {
        RendererSettings {
            frame: FrameSettings {
                width: self.width,
                height: self.height,
                exposure: self.exposure,
                shadow_resolution: self.shadow_resolution,
                ..Default::default()
            },
            component: self.component,
            ..Default::default()
        }
    }
}

/// `options.frames` frames of `method` through the persistent renderer, read back.
fn render(
    gpu: &Gpu,
    scene: &Scene,
    file: Option<&CssmFile>,
    method: &str,
    options: &RenderOptions,
) -> Result<Image, cssm_runtime::RuntimeError> {
    render_entry(gpu, scene, file, method::find(method)?, options)
}

/// [`render`] of a method's entry, in the table or not.
fn render_entry(
    gpu: &Gpu,
    scene: &Scene,
    file: Option<&CssmFile>,
    method: &'static MethodEntry,
    options: &RenderOptions,
) -> Result<Image, cssm_runtime::RuntimeError> {
    let values = options.values(method);
    let mut renderer = Renderer::new(
        &gpu.device,
        &gpu.queue,
        scene,
        file,
        method,
        &values,
        &options.settings(),
    )?;
    let image = render_image(&mut renderer, options.frames)?;
    gpu.wait()?;
    Ok(image)
}

/// The reference path tracer through its table entry.
fn render_reference(
    scene: &Scene,
    options: &RenderOptions,
) -> Result<Image, cssm_runtime::RuntimeError> {
    let method = cssm_runtime::reference::METHOD;
    let resolved = method.resolve(&options.values(&method))?;
    let Backend::Cpu(run) = method.backend else {
        panic!("the reference runs on the CPU")
    };
    let view = cssm_runtime::common::camera::View::of_scene(scene, options.width, options.height);
    let radiance = run(&CpuSetup {
        scene,
        view: &view,
        component: options.component,
        options: &resolved,
        progress: &|_, _| {},
        on_bounces: &|_| {},
    })?;
    Ok(Image::from_cpu(
        options.width,
        options.height,
        radiance,
        options.exposure,
    ))
}

/// Writes the tone-mapped image to `path` (to look at after a failure).
fn save_png(image: &Image, path: &std::path::Path) {
    if let Some(png) =
        ::image::RgbaImage::from_raw(image.width, image.height, image.display.clone())
    {
        let _ = png.save(path);
    }
}

/// The scene's materials as the GPU and the CPU references see them.
fn materials(scene: &Scene) -> Vec<cssm_runtime::gpu_types::GpuMaterial> {
    cssm_runtime::load::cpu_materials(scene)
        .expect("textures load")
        .0
}

/// Holds `method`'s indirect image of a closed sphere to its energy rule (`Checks::energy` for
/// the sphere lit by a spot light, `Checks::emissive` for the sphere that emits), `expected`
/// being the closed form of the mean indirect radiance (each pixel's mean over its channels).
/// `lit_on_screen` says whether the wall the screen shows receives light (it emits): then an
/// [`Energy::OnScreenOnly`] method must show some (mean above 0), where the spot light's sphere,
/// whose camera looks away from the lit wall, only bounds it below by 0. Every non-finite pixel
/// fails. Returns the failure, if any, for the caller to collect over the method table.
fn energy_failure(
    name: &str,
    rule: Energy,
    image: &Image,
    expected: f32,
    lit_on_screen: bool,
) -> Option<String> {
    let values: Vec<f32> = image
        .radiance
        .iter()
        .map(|p| (p[0] + p[1] + p[2]) / 3.0)
        .collect();
    if values.iter().any(|v| !v.is_finite()) {
        return Some(format!("{name}: a pixel is not finite"));
    }
    let mean = values.iter().sum::<f32>() / values.len() as f32;
    match rule {
        Energy::NoIndirect => {
            eprintln!("{name}: no indirect light expected, mean {mean}");
            values
                .iter()
                .any(|&v| v != 0.0)
                .then(|| format!("{name}: indirect light where none is"))
        }
        Energy::OnScreenOnly => {
            eprintln!(
                "{name}: mean indirect radiance {mean:.5} from the pixels on screen, closed form \
                 {expected:.5} from the whole sphere"
            );
            // Written so that a NaN mean fails.
            let above_floor = if lit_on_screen {
                mean > 0.0
            } else {
                mean >= 0.0
            };
            (!above_floor || mean > expected * 1.02).then(|| {
                let floor = if lit_on_screen { "(0" } else { "[0" };
                format!("{name}: mean {mean} outside {floor}, the closed form {expected}]")
            })
        }
        Energy::Within(tolerance) => {
            let error = (mean / expected - 1.0).abs();
            eprintln!(
                "{name}: mean indirect radiance {mean:.5}, closed form {expected:.5}, relative \
                 error {:.2}% (tolerance {:.1}%)",
                100.0 * error,
                100.0 * tolerance
            );
            (error.is_nan() || error > tolerance)
                .then(|| format!("{name}: relative error {error} above {tolerance}"))
        }
    }
}

/// The energy rule's thresholds, on made-up images (no GPU): what each rule lets through and
/// what it fails, so that the method-table tests built on it cannot pass vacuously.
#[test]
fn energy_rule_thresholds() {
    let image = |values: &[f32]| Image {
        width: values.len() as u32,
        height: 1,
        radiance: values.iter().map(|&v| [v, v, v, 1.0]).collect(),
        display: Vec::new(),
        first_timings: Vec::new(),
        timings: Vec::new(),
    };
    let fails = |rule, values: &[f32], lit_on_screen| {
        energy_failure("m", rule, &image(values), 1.0, lit_on_screen).is_some()
    };
    for lit in [false, true] {
        for rule in [
            Energy::Within(0.05),
            Energy::NoIndirect,
            Energy::OnScreenOnly,
        ] {
            assert!(fails(rule, &[1.0, f32::NAN], lit), "{rule:?}");
            assert!(fails(rule, &[1.0, f32::INFINITY], lit), "{rule:?}");
        }
        assert!(!fails(Energy::Within(0.05), &[1.0, 1.08], lit));
        assert!(fails(Energy::Within(0.05), &[1.0, 1.12], lit));
        assert!(fails(Energy::Within(0.05), &[1.0, 0.88], lit));
        assert!(!fails(Energy::NoIndirect, &[0.0, 0.0], lit));
        assert!(fails(Energy::NoIndirect, &[0.0, 1e-6], lit));
        assert!(!fails(Energy::OnScreenOnly, &[0.5, 1.5], lit));
        assert!(!fails(Energy::OnScreenOnly, &[1.0, 1.03], lit));
        assert!(fails(Energy::OnScreenOnly, &[1.0, 1.05], lit));
        assert!(fails(Energy::OnScreenOnly, &[-0.5, 0.25], lit));
        // A black image: lost energy, allowed only where the screen shows no lit wall.
        assert_eq!(fails(Energy::OnScreenOnly, &[0.0, 0.0], lit), lit);
    }
}

/// Relative RMSE of `gpu` against `cpu` over the pixels `keep` marks.
fn relative_rmse(gpu: &[glam::Vec3], cpu: &[glam::Vec3], keep: &[bool]) -> f64 {
    let (mut err, mut norm) = (0.0f64, 0.0f64);
    for ((g, c), &k) in gpu.iter().zip(cpu).zip(keep) {
        if k {
            err += (*g - *c).length_squared() as f64;
            norm += c.length_squared() as f64;
        }
    }
    (err / norm.max(1e-30)).sqrt()
}
