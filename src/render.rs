//! `cssm render`: the command line's loop over the runtime's [`Renderer`], and the image files
//! it writes ([`readback::save_png`], [`readback::save_exr`]). Every method and option comes from the runtime's method table
//! ([`runtime::method::METHODS`]); every range is checked there.

use std::{path::Path, process::ExitCode};

use cssm::{bake, formats, runtime};
use formats::{CssmFile, Scene};
use runtime::{
    Renderer, RendererSettings,
    common::{converge::BouncePlan, readback},
    frame::FrameSettings,
    method::{Backend, CpuSetup},
};

use crate::{
    CliResult, bake_cmd::bake_with_progress, check_writable, cli::RenderConfig, load_scene,
    scene_dir,
};

pub fn run_render(config: RenderConfig) -> CliResult {
    if config.stats && config.animate.is_some() {
        return Err(
            "--stats counts one frame of the scene as it stands; leave out --animate".into(),
        );
    }
    if let Some(options) = &config.animate {
        return crate::animate::run_animate(&config, options);
    }
    let dir = scene_dir(config.scene.clone())?;
    let method = config.method;
    let scene = load_scene(&dir)?;
    // Neither output may be an input (the scene's files, the .cssm) or the other output.
    let mut inputs = scene.input_files();
    inputs.extend(config.cssm.clone());
    check_writable(&config.out, &inputs)?;
    if let Some(exr) = &config.exr {
        inputs.push(config.out.clone());
        check_writable(exr, &inputs)?;
        if formats::cssm::destination(exr).ok() == formats::cssm::destination(&config.out).ok() {
            return Err(format!(
                "--out and --exr name the same file ({}); give each its own",
                exr.display()
            ));
        }
    }
    let settings = renderer_settings(&config, &scene, &dir)?;
    let (width, height) = (settings.frame.width, settings.frame.height);
    let (camera, light) = posed(&config, &scene)?;
    let image = match method.backend {
        Backend::Cpu(run) => {
            // The path tracer reads the camera, lights and objects from the scene.
            let mut posed_scene = match config.time {
                Some(time) => scene.posed(&crate::animate::poses_at_time(&scene, time)?)?,
                None => scene.clone(),
            };
            posed_scene.camera = camera;
            if let Some(light) = light {
                posed_scene.lights[0] = light;
            }
            if config.stats {
                println!("--stats: {method} runs on the CPU; it has no GPU pass to count");
            }
            render_on_cpu(&config, &posed_scene, &settings, run)?
        }
        Backend::Gpu(_) => {
            let (gpu, mut renderer, file) = gpu_renderer(&config, &scene, &dir, &settings)?;
            let gpu_error = |e: runtime::RuntimeError| format!("{}: {e}", dir.display());
            let frames = config.frames + u32::from(config.timings);
            // The GPU works in one go (a lightmap's radiosity takes minutes on lavapipe): a
            // spinner with the time so far, on a terminal.
            let spinner = indicatif::ProgressBar::new_spinner().with_style(
                indicatif::ProgressStyle::with_template("{spinner} {msg}, {elapsed}")
                    .expect("valid template"),
            );
            spinner.set_message(format!(
                "rendering {method} at {width}x{height}, {frames} frame(s)"
            ));
            spinner.enable_steady_tick(std::time::Duration::from_millis(200));
            let image = readback::render_image(&mut renderer, frames);
            spinner.finish_and_clear();
            let image = image.map_err(gpu_error)?;
            gpu.wait().map_err(gpu_error)?;
            if config.timings {
                print_timings(&gpu.describe(), &image);
            }
            if config.stats {
                print_stats(&config, &gpu, &scene, file.as_ref(), &settings)
                    .map_err(|e| format!("{}: --stats: {e}", dir.display()))?;
            }
            eprintln!(
                "rendered {} with {method} at {width}x{height} on {}",
                scene.name,
                gpu.describe()
            );
            let automatic = renderer.method().option("bounces").is_some()
                && renderer.options().count("bounces") == 0;
            if let (true, Some(convergence)) = (automatic, renderer.convergence()) {
                bounces_said(convergence.map_err(gpu_error)?);
            }
            image
        }
    };
    let mut image = image;
    expose(&config, &mut image, &mut None);
    readback::save_png(&config.out, &image)?;
    if let Some(exr) = &config.exr {
        readback::save_exr(exr, &image)?;
    }
    eprintln!(
        "wrote {}{}",
        config.out.display(),
        config
            .exr
            .as_ref()
            .map(|p| format!(", {}", p.display()))
            .unwrap_or_default()
    );
    Ok(ExitCode::SUCCESS)
}

/// Says how many bounces a method running them until converged took, so that `--bounces` can
/// fix them.
fn bounces_said(convergence: runtime::common::converge::Convergence) {
    eprintln!(
        "bounces: automatic, {convergence} (--bounces {} fixes it)",
        convergence.bounces
    );
}

/// Without `--exposure`, tone-maps `image` anew at the automatic exposure
/// ([`runtime::common::tonemap::auto_exposure_stops`]) and says which it was, so that
/// `--exposure` can fix it; `metered` carries the first image's for the frames of an animation.
pub(crate) fn expose(
    config: &RenderConfig,
    image: &mut readback::Image,
    metered: &mut Option<f32>,
) {
    if config.exposure.is_some() {
        return;
    }
    let stops = match *metered {
        Some(stops) => stops,
        None => {
            let stops =
                runtime::common::tonemap::auto_exposure_stops(&image.radiance).unwrap_or(0.0);
            eprintln!(
                "exposure: automatic, {stops:+.2} stops (the lit pixels' log-average luminance \
                 at middle grey; --exposure {stops:.2} fixes it)"
            );
            *metered = Some(stops);
            stops
        }
    };
    image.retonemap(stops.exp2());
}

/// A headless GPU and a [`Renderer`] of `config`'s GPU method on `scene` (its `.cssm` read or
/// baked where the method needs one, returned too), with `config`'s camera and light set after
/// construction: what `cssm render` and `cssm render --animate` draw with. Errors name the
/// scene.
pub(crate) fn gpu_renderer(
    config: &RenderConfig,
    scene: &Scene,
    dir: &Path,
    settings: &RendererSettings,
) -> Result<(runtime::Gpu, Renderer, Option<CssmFile>), String> {
    let gpu = runtime::Gpu::new_headless().map_err(|e| e.to_string())?;
    let gpu_error = |e: runtime::RuntimeError| format!("{}: {e}", dir.display());
    // The device's limits before the .cssm is read or baked.
    settings
        .frame
        .check_limits(&gpu.device.limits(), scene.lights.len())
        .map_err(gpu_error)?;
    let file = if config.method.needs_cssm {
        Some(render_cssm(config, scene)?)
    } else {
        None
    };
    let mut renderer = Renderer::new(
        &gpu.device,
        &gpu.queue,
        scene,
        file.as_ref(),
        config.method,
        &config.values,
        settings,
    )
    .map_err(gpu_error)?;
    // Set after construction, as `cssm view` sets what its controls moved, so that the two
    // render the same bytes; nothing is set where nothing was given.
    let (camera, light) = posed(config, scene)?;
    if camera != scene.camera {
        renderer.set_camera(&camera).map_err(gpu_error)?;
    }
    if let Some(light) = &light
        && Some(light) != scene.lights.first()
    {
        renderer.set_light(0, light).map_err(gpu_error)?;
    }
    if let Some(time) = config.time {
        let poses = crate::animate::poses_at_time(scene, time)?;
        for (object, pose) in poses.into_iter().enumerate() {
            if scene.objects[object].kind == formats::ObjectKind::Rigid {
                renderer
                    .set_object_transform(object, pose)
                    .map_err(gpu_error)?;
            }
        }
    }
    Ok((gpu, renderer, file))
}

/// `--stats`: what `config`'s method's passes do, counted by their CPU twins
/// (`runtime::work::passes`), with the cost model's prediction. Today the final gather of
/// `lightcuts`; the other methods say they have no counted pass yet.
fn print_stats(
    config: &RenderConfig,
    gpu: &runtime::Gpu,
    scene: &Scene,
    file: Option<&CssmFile>,
    settings: &RendererSettings,
) -> Result<(), String> {
    let method = config.method.name;
    let gathers = matches!(method, "hrc" | "lightmap" | "lightcuts");
    let Some(file) = file.filter(|_| gathers) else {
        println!(
            "--stats: no pass of {method} is counted yet (the radiosity gather of hrc, lightmap \
             and lightcuts and the final gather of lightcuts are)"
        );
        return Ok(());
    };
    if config.camera.is_some() || config.light.is_some() || config.time.is_some() {
        return Err(
            "counts the scene's own camera, light and poses; leave out --camera, \
                    --light and --time"
                .into(),
        );
    }
    let bounces = config.resolved.count("bounces");
    let threshold = config.resolved.number("threshold");
    let exposure = settings.frame.exposure;
    // Node radiance after the radiosity bounces of `iterations`, on the GPU.
    let radiance = |iterations: BouncePlan| -> Result<Vec<glam::Vec3>, String> {
        let atlas = runtime::radiosity::atlas_radiosity(
            &gpu.device,
            &gpu.queue,
            scene,
            file,
            config.shadow_resolution,
            iterations,
            runtime::radiosity::RadiosityOptions {
                threshold,
                exposure,
            },
        )
        .map_err(|e| e.to_string())?;
        Ok(atlas
            .node_radiance
            .iter()
            .map(|r| glam::Vec3::new(r[0], r[1], r[2]))
            .collect())
    };
    // The radiosity's bounces (lightcuts': all but the last, which its final gather does).
    let plan = BouncePlan::from_option(bounces);
    let radiosity_plan = if method == "lightcuts" {
        plan.one_fewer()
    } else {
        plan
    };
    let radiosity_bounces = if radiosity_plan.fraction > 0.0 {
        format!("up to {} (until converged)", radiosity_plan.max)
    } else {
        radiosity_plan.max.to_string()
    };
    // The texels' bounce albedo, which the radiosity's oracle reads.
    let (materials, _) = runtime::load::cpu_materials(scene).map_err(|e| e.to_string())?;
    let albedo: Vec<glam::Vec3> = runtime::radiosity::texel_albedo(&materials, file)
        .iter()
        .map(|a| glam::Vec3::new(a[0], a[1], a[2]))
        .collect();
    let links_cached = config.resolved.choice("links") == "cached";
    let traversal = runtime::radiosity::cpu::Traversal {
        threshold,
        exposure,
    };
    if radiosity_plan.max > 0 {
        let direct = radiance(BouncePlan::exactly(0))?;
        let stats = runtime::work::passes::radiosity_gather_stats(
            file,
            &direct,
            &albedo,
            (threshold, exposure),
            (runtime::radiosity::cpu::FarSplit::WHOLE, &[]),
            STATS_WARPS,
        );
        println!(
            "{} of {method}, its first of {radiosity_bounces} bounce(s), counted by its CPU \
             twin:\n{stats}",
            stats.pass
        );
        if links_cached {
            let twin = (file, &[][..], &direct[..], &albedo[..]);
            print_product_stats(twin, &traversal, runtime::radiosity::cpu::FarSplit::WHOLE);
        }
    }
    if method == "lightcuts" {
        use runtime::lightcuts::{GatherForm, cpu::TwinGather};
        let options = runtime::lightcuts::LightcutsOptions::from_resolved(&config.resolved);
        let (width, height) = (settings.frame.width, settings.frame.height);
        let view = runtime::common::camera::View::of_scene(scene, width, height);
        let radiance = radiance(radiosity_plan)?;
        let near_radius = runtime::lightcuts::near_radius(&file.hierarchy, options.near);
        // The counts do not depend on the far field's values, only on where pixels look it up.
        let far = vec![glam::Vec3::ZERO; file.texels.len()];
        let lists = runtime::lightcuts::near_lists(file, options.near);
        let emitting = runtime::radiosity::emitting_materials(scene);
        let split = runtime::radiosity::cpu::FarSplit {
            near_radius,
            emitters_apart: options.emitters_apart,
        };
        let form = match options.form {
            GatherForm::Walk => TwinGather::Walk,
            GatherForm::Atlas => {
                let stats = runtime::work::passes::radiosity_gather_stats(
                    file,
                    &radiance,
                    &albedo,
                    (threshold, exposure),
                    (split, &emitting),
                    STATS_WARPS,
                );
                if links_cached {
                    let twin = (file, &emitting[..], &radiance[..], &albedo[..]);
                    print_product_stats(twin, &traversal, split);
                }
                println!(
                    "{} (the last bounce over the atlas, the near field of {} texel sizes{} \
                     left to the pixels), counted by its CPU twin:\n{stats}",
                    stats.pass,
                    options.near,
                    if options.emitters_apart {
                        " and the emitters"
                    } else {
                        ""
                    }
                );
                TwinGather::Atlas {
                    far: &far,
                    near_radius,
                    lists: lists.as_ref(),
                    emitters_apart: options.emitters_apart,
                }
            }
        };
        let stats = runtime::work::passes::final_gather_stats(
            scene,
            file,
            &view,
            &radiance,
            form,
            options.downsample,
            threshold,
            exposure,
            STATS_TILES,
        )
        .map_err(|e| e.to_string())?;
        println!(
            "{} of {method} at {width}x{height} (downsample {}), counted by its CPU twin:\n{stats}",
            stats.pass, options.downsample
        );
    }
    Ok(())
}

/// `--stats` of the product over cached links (`runtime::work::passes::link_product_stats`)
/// made for the node radiance of `twin` (the file, its materials' emission, the radiance, the
/// texels' albedo) with the oracle of `traversal` and the cuts of `split`: what a moved light
/// runs instead of the walk counted before it.
fn print_product_stats(
    (file, emitting, radiance, albedo): (&CssmFile, &[bool], &[glam::Vec3], &[glam::Vec3]),
    traversal: &runtime::radiosity::cpu::Traversal,
    split: runtime::radiosity::cpu::FarSplit,
) {
    use runtime::radiosity::cpu;
    let query = formats::visibility::VisibilityQuery::new(file, Default::default());
    let twin = cpu::TwinScene::baked(&query, emitting);
    let leaves: Vec<u32> = (file.hierarchy.nodes.iter())
        .filter(|n| n.count == 1)
        .map(|n| file.hierarchy.leaf_texels[n.first as usize])
        .collect();
    let cut = |leaf: usize| {
        let t = leaves[leaf];
        let texel = &file.texels[t as usize];
        let rho = albedo[t as usize].max_element();
        let (p, n) = (texel.pos(), texel.nrm());
        cpu::receiver_links(&twin, radiance, traversal, split, t, p, n, rho)
    };
    let far = split.near_radius > 0.0;
    let sizes = (leaves.len(), file.hierarchy.nodes.len());
    let stats = runtime::work::passes::link_product_stats(sizes, cut, far, STATS_WARPS);
    println!(
        "{} (links=cached: what a moved light runs instead; its cuts made here for the \
         radiance the walk above read, on the GPU for the solve before), counted by its CPU \
         twin:\n{stats}",
        stats.pass
    );
}

/// Warps of the radiosity gather `--stats` counts.
const STATS_WARPS: u32 = 32;

/// Tiles of the final gather `--stats` counts.
const STATS_TILES: u32 = 16;

fn print_timings(device: &str, image: &readback::Image) {
    if image.timings.is_empty() {
        println!("GPU timings: not supported by this adapter (no timestamp queries)");
        return;
    }
    let table = |title: &str, timings: &[(&'static str, f64)]| {
        println!("{title}");
        let mut total = 0.0;
        for (pass, ms) in timings {
            println!("  {pass:<30} {ms:8.3} ms");
            total += ms;
        }
        println!("  {:<30} {total:8.3} ms", "total");
    };
    table(
        &format!("GPU time per pass, first frame (with the view-independent passes; {device}):"),
        &image.first_timings,
    );
    table(
        &format!("GPU time per pass, last frame ({device}):"),
        &image.timings,
    );
}

/// The camera and first spot light `config` renders `scene` with: the scene's, with the eye and
/// target of `--camera` and the position and direction of `--light` where given, checked.
pub(crate) fn posed(
    config: &RenderConfig,
    scene: &Scene,
) -> Result<(formats::Camera, Option<formats::scene::SpotLight>), String> {
    let mut camera = scene.camera.clone();
    if let Some(pose) = config.camera {
        if pose.position == pose.aim {
            return Err(format!(
                "--camera {pose}: the eye and the target are the same point"
            ));
        }
        camera.position = pose.position;
        camera.target = pose.aim;
    }
    let mut light = scene.lights.first().cloned();
    if let Some(pose) = config.light {
        let Some(first) = &mut light else {
            return Err(format!(
                "--light {pose}: {} has no spot light to place",
                scene.name
            ));
        };
        if pose.aim.length() < 1e-6 {
            return Err(format!("--light {pose}: the direction is zero"));
        }
        first.position = pose.position;
        // A unit direction, as the scene's are; one that is unit already (what `cssm view`
        // prints) is kept bit for bit, so that the image is the window's.
        first.direction = if (pose.aim.length() - 1.0).abs() < 1e-5 {
            pose.aim
        } else {
            pose.aim.normalize()
        };
    }
    Ok((camera, light))
}

/// The renderer settings of `config` for `scene` (whose camera gives the default size),
/// checked: what `cssm render` and `cssm view` render with.
pub(crate) fn renderer_settings(
    config: &RenderConfig,
    scene: &Scene,
    dir: &Path,
) -> Result<RendererSettings, String> {
    let (width, height) = config
        .size
        .unwrap_or((scene.camera.resolution[0], scene.camera.resolution[1]));
    let settings = RendererSettings {
        frame: FrameSettings {
            width,
            height,
            exposure: config.exposure.unwrap_or(0.0).exp2(),
            shadow_resolution: config.shadow_resolution,
            visibility: config.visibility,
        },
        component: config.component,
        ..Default::default()
    };
    settings
        .frame
        .check()
        .map_err(|e| format!("{}: {e}", dir.display()))?;
    Ok(settings)
}

/// A CPU method (the reference path tracer), with a progress bar; tone-mapped on the CPU with
/// the GPU's curve.
fn render_on_cpu(
    config: &RenderConfig,
    scene: &Scene,
    settings: &RendererSettings,
    run: fn(&CpuSetup) -> Result<Vec<[f32; 4]>, runtime::RuntimeError>,
) -> Result<readback::Image, String> {
    let resolved = &config.resolved;
    let (w, h) = (settings.frame.width, settings.frame.height);
    let bar = indicatif::ProgressBar::new(h as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} {msg} [{bar:32}] {pos}/{len} rows, eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_message(format!("{} with {}", scene.name, config.method));
    let view = runtime::common::camera::View::of_scene(scene, w, h);
    let radiance = run(&CpuSetup {
        scene,
        view: &view,
        component: settings.component,
        options: resolved,
        progress: &|done, _| bar.set_position(done / w.max(1) as u64),
        on_bounces: &|convergence| bounces_said(convergence),
    })
    .map_err(|e| format!("{}: {e}", scene.path.display()))?;
    bar.finish_and_clear();
    let options: Vec<String> = resolved.iter().map(|(k, v)| format!("{k} {v}")).collect();
    eprintln!(
        "{} {} at {w}x{h} on the CPU ({})",
        config.method,
        scene.name,
        options.join(", ")
    );
    Ok(readback::Image::from_cpu(
        w,
        h,
        radiance,
        settings.frame.exposure,
    ))
}

/// The CSSM `cssm render` uses: `--cssm`, checked against the scene, else a small one baked in
/// memory.
pub(crate) fn render_cssm(config: &RenderConfig, scene: &Scene) -> Result<CssmFile, String> {
    if let Some(path) = &config.cssm {
        return runtime::load::read_cssm(path, scene).map_err(|e| e.to_string());
    }
    eprintln!(
        "no --cssm given: baking {} at atlas 64, cube 32 first (bake once with `cssm bake` and \
         pass --cssm to skip this)",
        scene.name
    );
    // A scene of many charts (the Sibenik's 6,913) does not fit 64²: the smallest page from
    // there up that holds them, as the query benchmark picks its atlas.
    let mut atlas = 64;
    loop {
        let options = bake::BakeOptions {
            atlas_resolution: atlas,
            cube_resolution: 32,
            ..Default::default()
        };
        match bake_with_progress(scene, &options) {
            Ok(baked) => return Ok(baked.file),
            Err(bake::BakeError::Atlas(e))
                if e.contains("could not fit") && atlas < LARGEST_IN_MEMORY_ATLAS =>
            {
                atlas *= 2;
                eprintln!(
                    "its charts do not fit atlas {}: baking at atlas {atlas}",
                    atlas / 2
                );
            }
            Err(e) => return Err(format!("{}: {e}", scene.path.display())),
        }
    }
}

/// The largest atlas `cssm render` bakes in memory when no `--cssm` is given.
const LARGEST_IN_MEMORY_ATLAS: u32 = 512;
