//! The tests every method gets from the method table (`cssm_runtime::METHODS`): an analytic
//! energy check in a closed sphere, and a golden image of the Cornell box compared with FLIP.
//! Each method declares the tolerances it meets (`MethodEntry::checks`); a new method of the
//! table is tested here without a line of its own, and a method written in a test, outside the
//! table, gets the same checks (`a_method_written_here_is_built_and_held_to_the_energy_check`).

use std::path::{Path, PathBuf};

use cssm_bake::BakeOptions;
use cssm_formats::{CssmFile, Scene};
use cssm_runtime::{
    METHODS, RuntimeError,
    common::{compose::Component, readback::Image},
    frame::{FrameContext, FrameEncoder, PassInfo, Slot, Stage},
    method::{self, Backend, Checks, Energy, GiMethod, MethodEntry, MethodSetup, Timing},
};

use super::{RenderOptions, cornell, energy_failure, gpu, render_entry, render_reference};

/// Albedo of the sphere's wall.
pub(super) const RHO: f32 = 0.5;
/// Radiant intensity of its spot light (W/sr, every channel) and the cone's half-angle.
pub(super) const INTENSITY: f32 = 10.0;
pub(super) const CUTOFF_DEG: f32 = 50.0;
/// Indirect bounces of the energy check.
pub(super) const BOUNCES: u32 = 2;

/// A closed UV sphere of radius 1 around the origin with its triangles facing inwards, the
/// camera at the centre and one spot light beside it (written to `dir`), and its wall area.
/// With `emission` `Some(le)`, no light: the wall emits `le` from its front, inwards.
pub(super) fn write_sphere(dir: &Path, emission: Option<f32>) -> f32 {
    let (rings, segments) = (12usize, 24usize);
    let mut v = vec![[0.0f32, 1.0, 0.0]];
    for i in 1..rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            v.push([
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ]);
        }
    }
    v.push([0.0, -1.0, 0.0]);
    let ring = |i: usize, j: usize| 2 + (i - 1) * segments + j % segments; // 1-based OBJ index
    let south = v.len();
    let mut faces = Vec::new();
    for j in 0..segments {
        faces.push([1, ring(1, j), ring(1, j + 1)]);
        faces.push([south, ring(rings - 1, j + 1), ring(rings - 1, j)]);
        for i in 1..rings - 1 {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j),
                ring(i + 1, j + 1),
            );
            faces.push([a, c, b]);
            faces.push([b, c, d]);
        }
    }
    // Inwards: every triangle's normal points at the centre (checked below).
    let p = |k: usize| glam::Vec3::from(v[k - 1]);
    let mut area = 0.0;
    for f in &faces {
        let n = (p(f[1]) - p(f[0])).cross(p(f[2]) - p(f[0]));
        assert!(n.dot(p(f[0])) < 0.0, "a sphere triangle faces outwards");
        area += 0.5 * n.length();
    }
    let mut obj = String::from("mtllib sphere.mtl\nusemtl wall\n");
    for p in &v {
        obj += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for f in &faces {
        obj += &format!("f {} {} {}\n", f[0], f[1], f[2]);
    }
    std::fs::write(dir.join("sphere.obj"), obj).unwrap();
    let ke = emission.map_or(String::new(), |le| format!("Ke {le} {le} {le}\n"));
    std::fs::write(
        dir.join("sphere.mtl"),
        format!("newmtl wall\nKd {RHO} {RHO} {RHO}\nKs 0 0 0\nNs 1\n{ke}"),
    )
    .unwrap();
    let light = if emission.is_some() {
        String::new()
    } else {
        format!(
            "\n[[lights]]\ntype = \"spot\"\nposition = [0.0, 0.3, 0.0]\n\
             direction = [0.0, -0.3, -1.0]\ncutoff_deg = {CUTOFF_DEG}\n\
             intensity = [{INTENSITY}, {INTENSITY}, {INTENSITY}]\n"
        )
    };
    std::fs::write(
        dir.join("scene.toml"),
        format!(
            "name = \"sphere\"\nmesh = \"sphere.obj\"\n\n[camera]\nposition = [0.0, 0.0, 0.0]\n\
             target = [0.0, 0.0, 1.0]\nup = [0.0, 1.0, 0.0]\nfov_y_deg = 60.0\n\
             resolution = [32, 24]\n{light}"
        ),
    )
    .unwrap();
    area
}

/// The sphere, its wall area and its bake (atlas 32, cube 16), made once.
pub(super) fn sphere() -> &'static (Scene, f32, CssmFile) {
    static SPHERE: std::sync::OnceLock<(Scene, f32, CssmFile)> = std::sync::OnceLock::new();
    SPHERE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let area = write_sphere(dir.path(), None);
        let scene = Scene::load(dir.path()).expect("sphere loads");
        let options = BakeOptions {
            atlas_resolution: 32,
            cube_resolution: 16,
            ..Default::default()
        };
        let file = cssm_bake::bake(&scene, &options, &mut |_| {})
            .expect("sphere bakes")
            .file;
        (scene, area, file)
    })
}

/// `method` on `scene` with `options`: the renderer for a GPU method, the CPU run otherwise.
pub(super) fn image_of(
    method: &'static MethodEntry,
    scene: &Scene,
    file: &CssmFile,
    options: &RenderOptions,
) -> Image {
    match method.backend {
        Backend::Gpu(_) => render_entry(gpu(), scene, Some(file), method, options),
        Backend::Cpu(_) => render_reference(scene, options),
    }
    .unwrap_or_else(|e| panic!("{}: {e}", method.name))
}

/// In a closed sphere of albedo rho every form factor from a point to a patch is the patch's
/// share of the wall, so each bounce's irradiance is uniform: `E_k = rho^k Phi / A` for the
/// power `Phi = I 2 pi (1 - cos cutoff)` of the spot light, and a diffuse wall sends
/// `rho / pi (E_1 + ... + E_B)` towards the eye from every pixel. A method without a
/// `bounces` option computes one bounce.
#[test]
fn every_method_conserves_energy_in_a_closed_sphere() {
    let failures: Vec<String> = METHODS.iter().filter_map(energy_check).collect();
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The energy check of [`every_method_conserves_energy_in_a_closed_sphere`] of one method: what
/// is wrong, if anything.
fn energy_check(method: &'static MethodEntry) -> Option<String> {
    let (scene, area, file) = sphere();
    let power = INTENSITY * std::f32::consts::TAU * (1.0 - CUTOFF_DEG.to_radians().cos());
    let options = RenderOptions {
        width: 32,
        height: 24,
        bounces: BOUNCES,
        component: Component::Indirect,
        samples: 64,
        shadow_resolution: 512,
        ..Default::default()
    };
    let image = image_of(method, scene, file, &options);
    let computed = if method.option("bounces").is_some() {
        BOUNCES
    } else {
        1
    };
    let bounces: f32 = (1..=computed).map(|k| RHO.powi(k as i32)).sum();
    let expected = RHO / std::f32::consts::PI * power / area * bounces;
    // The spot light falls on the wall behind the camera: a screen-space method may see none
    // of it.
    energy_failure(method.name, method.checks.energy, &image, expected, false)
}

/// Progressive radiosity's ambient term (Cohen, Chen, Wallace and Greenberg 1988), the light
/// the spot lights send once reflected, spread evenly over the scene and reflected `bounces`
/// times, with the scene's area-weighted mean albedo for every surface: one indirect radiance
/// for every pixel. Here as the smallest method there is, written outside the runtime's folders
/// and its table. `scale` makes it wrong on purpose.
struct Ambient {
    /// The radiance, in every pixel (rgba, a = 1).
    constant: wgpu::Buffer,
    /// What the renderer composes: the constant copied in every frame.
    indirect: wgpu::Buffer,
}

impl Ambient {
    fn build(setup: &MethodSetup, scale: f32) -> Result<Box<dyn GiMethod>, RuntimeError> {
        let scene = setup.scene;
        let (mut area, mut albedo) = (0.0f32, 0.0f32);
        for (t, &material) in scene.triangle_materials.iter().enumerate() {
            let [a, b, c] = scene.triangle(t);
            let triangle_area = (b - a).cross(c - a).length() / 2.0;
            let kd = scene.materials[material as usize].kd;
            area += triangle_area;
            albedo += triangle_area * (kd[0] + kd[1] + kd[2]) / 3.0;
        }
        let rho = albedo / area;
        let power: f32 = scene
            .lights
            .iter()
            .map(|l| {
                let intensity = (l.intensity[0] + l.intensity[1] + l.intensity[2]) / 3.0;
                intensity * std::f32::consts::TAU * (1.0 - l.cutoff_deg.to_radians().cos())
            })
            .sum();
        let bounces = setup.options.count("bounces").max(1);
        let reflected: f32 = (1..=bounces).map(|k| rho.powi(k as i32)).sum();
        let radiance = scale * rho / std::f32::consts::PI * power / area * reflected;
        let ctx = setup.ctx;
        let pixels = (ctx.settings.width * ctx.settings.height) as usize;
        let texel = [radiance, radiance, radiance, 1.0f32];
        let constant = wgpu::util::DeviceExt::create_buffer_init(
            &ctx.device,
            &wgpu::util::BufferInitDescriptor {
                label: Some("ambient"),
                contents: bytemuck::cast_slice(&vec![texel; pixels]),
                usage: wgpu::BufferUsages::COPY_SRC,
            },
        );
        let indirect = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ambient indirect"),
            size: constant.size(),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(Box::new(Ambient { constant, indirect }))
    }
}

impl GiMethod for Ambient {
    fn encode(&mut self, _: &FrameContext, frame: &mut FrameEncoder) {
        frame.encoder.copy_buffer_to_buffer(
            &self.constant,
            0,
            &self.indirect,
            0,
            self.constant.size(),
        );
    }

    fn indirect(&self) -> Option<&wgpu::Buffer> {
        Some(&self.indirect)
    }

    fn resize(&mut self, _: &FrameContext) -> Result<(), RuntimeError> {
        Err(RuntimeError::Unsupported(
            "the test's ambient term keeps its size".into(),
        ))
    }
}

/// An entry of [`Ambient`], right (`scale` 1) or wrong.
const fn ambient_entry(
    name: &'static str,
    build: fn(&MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError>,
) -> MethodEntry {
    MethodEntry {
        name,
        summary: "progressive radiosity's ambient term (Cohen et al. 1988), in a test",
        needs_cssm: false,
        options: &[method::BOUNCES],
        passes: &[PassInfo {
            name: "ambient",
            stage: Stage::Frame,
            reads: &[],
            writes: &[Slot::Indirect],
        }],
        backend: Backend::Gpu(build),
        checks: Checks {
            energy: Energy::Within(0.01),
            ..Checks::DEFAULT
        },
        timing: Timing::DEFAULT,
    }
}

static AMBIENT: MethodEntry = ambient_entry("ambient", build_ambient);
static AMBIENT_TEN_PERCENT_HIGH: MethodEntry = ambient_entry("ambient-high", build_ambient_high);

fn build_ambient(setup: &MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError> {
    Ambient::build(setup, 1.0)
}

fn build_ambient_high(setup: &MethodSetup) -> Result<Box<dyn GiMethod>, RuntimeError> {
    Ambient::build(setup, 1.1)
}

/// A method is its entry and the [`GiMethod`] it builds: the ambient term above, written in this
/// test, in no folder of the runtime and no line of its table, is built by the renderer, its
/// pass scheduled between the shared ones, and held to the energy check every method of the
/// table gets, which it meets (it is that check's closed form for one albedo), while the same
/// term 10% too high fails it. A method of the runtime is this plus its folder's WGSL, CPU twin
/// and one line of `method_table!`.
#[test]
fn a_method_written_here_is_built_and_held_to_the_energy_check() {
    assert!(METHODS.iter().all(|m| m.name != AMBIENT.name));
    cssm_runtime::frame::check_schedule(AMBIENT.passes, true).expect("its passes fit a frame");
    assert_eq!(energy_check(&AMBIENT), None);
    let wrong = energy_check(&AMBIENT_TEN_PERCENT_HIGH).expect("10% too much light fails");
    assert!(wrong.contains("relative error"), "{wrong}");
}

/// Where failed comparisons leave their images (`target/tmp/golden/`).
fn output_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("golden");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn save_rgb8(path: &Path, width: u32, height: u32, rgb: Vec<u8>) {
    image::RgbImage::from_raw(width, height, rgb)
        .expect("image size")
        .save(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// Every method's image of the Cornell box (64x48, one bounce) against its golden image in
/// `tests/golden/NAME.png`, by the mean of the FLIP error map (Andersson et al. 2020). On a
/// failure the test writes `NAME-actual.png` and `NAME-difference.png` (FLIP's magma map) to
/// `target/tmp/golden/`; `CSSM_BLESS=1` writes the golden images anew (look at them first),
/// `CSSM_BLESS=NAME,NAME` those of the methods named.
#[test]
fn every_method_matches_its_golden_image() {
    let (scene, file) = cornell();
    let options = RenderOptions {
        width: 64,
        height: 48,
        bounces: 1,
        samples: 16,
        shadow_resolution: 1024,
        ..Default::default()
    };
    let golden_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden");
    let bless_list = std::env::var("CSSM_BLESS").ok();
    let bless = |name: &str| match bless_list.as_deref() {
        None => false,
        Some("1") => true,
        Some(list) => list.split(',').any(|n| n.trim() == name),
    };
    let mut failures = Vec::new();
    for method in METHODS {
        let image = image_of(method, scene, file, &options);
        let rgb: Vec<u8> = image
            .display
            .chunks(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect();
        let golden_path = golden_dir.join(format!("{}.png", method.name));
        if bless(method.name) {
            save_rgb8(&golden_path, image.width, image.height, rgb);
            eprintln!("{}: wrote {}", method.name, golden_path.display());
            continue;
        }
        let Ok(golden) = image::open(&golden_path) else {
            failures.push(format!(
                "{}: no golden image at {} (run with CSSM_BLESS=1 to write it)",
                method.name,
                golden_path.display()
            ));
            continue;
        };
        let golden = golden.to_rgb8();
        assert_eq!(
            golden.dimensions(),
            (image.width, image.height),
            "{}",
            method.name
        );
        // The lab's FLIP (`cssm report error`'s), on RGBA8.
        let with_alpha = |rgb: &[u8]| -> Vec<u8> {
            rgb.chunks_exact(3)
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect()
        };
        let (golden, test) = (with_alpha(&golden), with_alpha(&rgb));
        let mean = cssm::report::error::mean_flip(image.width, image.height, &golden, &test);
        let tolerance = method.checks.golden_flip;
        eprintln!(
            "{}: mean FLIP {mean:.4} against its golden image (tolerance {tolerance})",
            method.name
        );
        if mean.is_nan() || mean > tolerance {
            let out = output_dir();
            let actual = out.join(format!("{}-actual.png", method.name));
            let difference = out.join(format!("{}-difference.png", method.name));
            save_rgb8(&actual, image.width, image.height, rgb);
            let colours = cssm::report::error::flip_map(image.width, image.height, &golden, &test);
            let colours = colours
                .chunks_exact(4)
                .flat_map(|p| [p[0], p[1], p[2]])
                .collect();
            save_rgb8(&difference, image.width, image.height, colours);
            failures.push(format!(
                "{}: mean FLIP {mean} above {tolerance}; see {} and {}",
                method.name,
                actual.display(),
                difference.display()
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A user embeds the runtime with their own device: every GPU method builds and renders on a
/// device of `required_limits` (WebGPU's defaults, 128 MiB bindings among them, but the
/// G-buffer's 64 bytes per sample and 12 storage buffers per stage), not only on one with the
/// adapter's; and the methods without the radiosity gather within WebGPU's default 8.
#[test]
fn every_gpu_method_builds_within_the_required_limits() {
    let adapter = &gpu().adapter;
    let device_of = |limits: wgpu::Limits| {
        pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("required limits"),
            required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
            required_limits: limits,
            ..Default::default()
        }))
        .expect("a device of the required limits")
    };
    let required = cssm_runtime::required_limits();
    let eight = wgpu::Limits {
        max_storage_buffers_per_shader_stage: 8,
        ..required.clone()
    };
    let (scene, file) = cornell();
    let options = RenderOptions {
        width: 32,
        height: 24,
        ..Default::default()
    };
    let mut failures = Vec::new();
    for (limits, names) in [
        (required, None),
        (eight, Some(["direct", "rsm", "vct"].as_slice())),
    ] {
        let storage = limits.max_storage_buffers_per_shader_stage;
        let (device, queue) = device_of(limits);
        let methods = METHODS
            .iter()
            .filter(|m| matches!(m.backend, Backend::Gpu(_)));
        for method in methods.filter(|m| names.is_none_or(|n| n.contains(&m.name))) {
            let values = options.values(method);
            let built = cssm_runtime::Renderer::new(
                &device,
                &queue,
                scene,
                Some(file),
                method,
                &values,
                &options.settings(),
            )
            .and_then(|mut r| cssm_runtime::common::readback::render_image(&mut r, 1));
            if let Err(e) = built {
                failures.push(format!("{} ({storage} storage buffers): {e}", method.name));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// Every pass a method's frames time is in its schedule under the same name, so that `cssm
/// compare` and `cssm report error` find each timing's stage (prepare or frame): the
/// radiosity's passes once carried other names than their declarations and their milliseconds
/// were counted as frame time.
#[test]
fn every_timed_pass_is_in_the_schedule() {
    let gpu = gpu();
    if !gpu
        .device
        .features()
        .contains(wgpu::Features::TIMESTAMP_QUERY)
    {
        eprintln!("skipped: the device has no timestamp queries");
        return;
    }
    let (scene, file) = cornell();
    let options = RenderOptions {
        width: 32,
        height: 24,
        ..Default::default()
    };
    let mut failures = Vec::new();
    for method in METHODS
        .iter()
        .filter(|m| matches!(m.backend, Backend::Gpu(_)))
    {
        let values = options.values(method);
        let mut renderer = cssm_runtime::Renderer::new(
            &gpu.device,
            &gpu.queue,
            scene,
            Some(file),
            method,
            &values,
            &options.settings(),
        )
        .unwrap_or_else(|e| panic!("{}: {e}", method.name));
        // The first frame, which runs the prepare passes too, into a target of our own (the
        // read-back loop reads the timings itself).
        let target = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("timed target"),
            size: wgpu::Extent3d {
                width: options.width,
                height: options.height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        renderer.render(&mut encoder, &target.create_view(&Default::default()));
        gpu.queue.submit([encoder.finish()]);
        let timings = renderer
            .read_timings()
            .unwrap_or_else(|e| panic!("{}: {e}", method.name));
        assert!(!timings.is_empty(), "{}: no pass was timed", method.name);
        let schedule = cssm_runtime::frame::schedule(method.passes);
        for (name, _) in timings {
            if !schedule.iter().any(|p| p.name == name) {
                failures.push(format!(
                    "{}: '{name}' is timed but not scheduled",
                    method.name
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
