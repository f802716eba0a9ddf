//! What screen space cannot see: the one-bounce indirect light the pixels on screen send each
//! other with exact visibility (every pair of covered pixels, Eq. 1 over the G-buffer, a ray
//! cast per pair), against the path tracer's one bounce, which gathers from every surface, and
//! `ssil`'s own one bounce with and without its voxel visibility; and the path tracer's one
//! bounce split by where its bounce lands: on a surface the camera sees, on one facing the eye
//! but hidden (behind another, or outside the frustum), or on one facing away from the eye.
//!
//! ```text
//! cargo bench --bench ssil_screen -- [--scene DIR]... [--size 80x60] [--samples 1024]
//!     [--frames 16] [--out FILE.md]
//! ```
//!
//! Per scene, sums of luminance over the covered pixels: the screen's bound with exact
//! visibility and without any, the path tracer (`--samples` paths, one bounce), `ssil` (one
//! bounce, `--frames` frames, the camera at rest). The screen's bound over the path tracer is
//! the share of the light that comes from surfaces on screen; `ssil` over the bound, what the
//! method's levels, samples and voxels make of it. Only diffuse reflection is summed (the
//! scenes' Ks is ignored): measure diffuse scenes.

use std::path::PathBuf;

use cssm::{formats, raycast, runtime};
use glam::{Mat4, Vec3, Vec4, Vec4Swizzles};
use rayon::prelude::*;
use runtime::{
    Gpu, Renderer, RendererSettings,
    common::{
        camera::View,
        compose::Component,
        readback::{read_buffer, read_texture, render_image, vec4s},
        timestamps::PassTimer,
    },
    frame::{FrameEncoder, FrameSettings},
    method::{self, OptionValue, OptionValues},
    ssil::{ScreenSpaceGi, SsilOptions},
};

#[path = "common/mod.rs"]
mod common;

use common::{arg, parsed, write_report};

fn luminance(v: Vec3) -> f64 {
    f64::from(0.2126 * v.x + 0.7152 * v.y + 0.0722 * v.z)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (width, height) = common::size(&args, (80, 60));
    let samples: u32 = parsed(&args, "--samples", 1024);
    let frames: u32 = parsed(&args, "--frames", 16);
    let mut dirs: Vec<PathBuf> = args
        .windows(2)
        .filter(|w| w[0] == "--scene")
        .map(|w| PathBuf::from(&w[1]))
        .collect();
    if dirs.is_empty() {
        dirs.push(cssm::builtin::cornell_box().expect("built-in scene"));
    }
    let out: Option<PathBuf> = arg(&args, "--out").map(PathBuf::from);
    let gpu = Gpu::new_headless().unwrap_or_else(|e| panic!("{e}"));
    let mut report = format!(
        "One bounce of diffuse indirect light at {width}x{height}: sums of luminance over the \
         covered pixels; the path tracer {samples} paths per pixel, `ssil` after {frames} \
         frames (defaults, one bounce), GPU passes on {}.\n\n\
         | scene | on-screen senders, exact visibility / path tracer | on-screen senders, no \
         visibility / path tracer | ssil / path tracer | ssil / on-screen, exact | \
         ssil:visibility=none / on-screen, none |\n| --- | ---: | ---: | ---: | ---: | ---: |\n",
        gpu.describe()
    );
    let mut split_table = format!(
        "\nThe path tracer's one bounce ({samples} paths per pixel, diffuse) split by where its \
         bounce lands: the share of the light sent by surfaces the camera sees, by surfaces \
         facing the eye but hidden behind others or outside the image, and by surfaces facing \
         away from the eye.\n\n\
         | scene | seen | facing the eye, hidden | facing away |\n| --- | ---: | ---: | ---: |\n"
    );
    for dir in &dirs {
        let scene = formats::Scene::load(dir).unwrap_or_else(|e| panic!("{e}"));
        let settings = RendererSettings {
            frame: FrameSettings {
                width,
                height,
                ..Default::default()
            },
            component: Component::Indirect,
            ..Default::default()
        };
        let ssil = |visibility: &'static str| {
            let mut values = OptionValues::default();
            values.set("bounces", OptionValue::Count(1));
            values.set("visibility", OptionValue::Choice(visibility));
            let entry = method::find("ssil").expect("ssil");
            let mut renderer = Renderer::new(
                &gpu.device,
                &gpu.queue,
                &scene,
                None,
                entry,
                &values,
                &settings,
            )
            .expect("renderer");
            let image = render_image(&mut renderer, frames).expect("render");
            let sum: f64 = image
                .radiance
                .iter()
                .map(|p| luminance(Vec4::from(*p).truncate()))
                .sum();
            (renderer, sum)
        };
        let (renderer, ssil_sum) = ssil("voxels");
        let (_, ssil_none) = ssil("none");
        // The G-buffer and the light each pixel sends, from the renderer's context.
        let ctx = renderer.context();
        let options = SsilOptions::default();
        let mut gi = ScreenSpaceGi::new(ctx, scene.bounds(), &options).expect("ssil");
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let mut timer = PassTimer::new(&gpu.device, &gpu.queue);
        gi.encode(
            ctx,
            &mut FrameEncoder {
                encoder: &mut encoder,
                timer: &mut timer,
                index: 0,
            },
        );
        gpu.queue.submit([encoder.finish()]);
        let texture = |t| vec4s(&read_texture(&ctx.device, &ctx.queue, t, 16).expect("read"));
        let position = texture(&ctx.gbuffer.position);
        let normal = texture(&ctx.gbuffer.normal);
        let albedo = texture(&ctx.gbuffer.albedo);
        let sender = gi.sender();
        let sender =
            vec4s(&read_buffer(&ctx.device, &ctx.queue, sender, 0, sender.size()).expect("read"));
        let view = ctx.gpu_view();
        let view_proj = Mat4::from_cols_array_2d(&view.view_proj);
        let eye: Vec3 = view.eye.into();
        let pixel_area = runtime::ssil::pixel_area(&view_proj, (width, height));
        let bvh = raycast::SceneBvh::new(&scene);
        let extent = (scene.bounds().1 - scene.bounds().0).length();
        let covered: Vec<usize> = (0..position.len())
            .filter(|&i| position[i].w > 0.0)
            .collect();
        let senders = runtime::ssil::cpu::ScreenSenders {
            position: &position,
            normal: &normal,
            light: &sender,
            view_proj,
            eye,
            pixel_area,
            scale: 1.0,
        };
        let offset = 1e-4 * extent;
        let clear = |x: Vec3, n: Vec3, s: Vec3, ns: Vec3| {
            bvh.segment_clear(x + offset * n, s + offset * ns)
        };
        let (exact, open): (f64, f64) = covered
            .par_iter()
            .map(|&i| {
                let (x, n) = (position[i].truncate(), normal[i].truncate());
                let (all, seen) = senders.irradiance(x, n, None, &clear);
                let rho = albedo[i].truncate() / std::f32::consts::PI;
                (luminance(rho * seen), luminance(rho * all))
            })
            .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        // The path tracer's one bounce.
        let reference = method::find("reference").expect("reference");
        let mut values = OptionValues::default();
        values.set("samples", OptionValue::Count(samples));
        values.set("bounces", OptionValue::Count(1));
        let resolved = reference.resolve(&values).expect("options");
        let runtime::method::Backend::Cpu(run) = reference.backend else {
            panic!("the reference runs on the CPU")
        };
        let traced = run(&runtime::method::CpuSetup {
            scene: &scene,
            view: &View::of_scene(&scene, width, height),
            component: Component::Indirect,
            options: &resolved,
            progress: &|_, _| {},
            on_bounces: &|_| {},
        })
        .expect("path tracer");
        let traced: f64 = traced
            .iter()
            .map(|p| luminance(Vec4::from(*p).truncate()))
            .sum();
        let row = format!(
            "| {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} |\n",
            scene.name,
            exact / traced,
            open / traced,
            ssil_sum / traced,
            ssil_sum / exact,
            ssil_none / open
        );
        print!("{row}");
        report += &row;
        let [seen, hidden, away] = traced_split(&scene, &bvh, (width, height), samples);
        let total = (seen + hidden + away).max(f64::MIN_POSITIVE);
        let row = format!(
            "| {} | {:.3} | {:.3} | {:.3} |\n",
            scene.name,
            seen / total,
            hidden / total,
            away / total
        );
        print!("{row}");
        split_table += &row;
    }
    report += &split_table;
    write_report(out.as_deref(), &report);
}

/// The path tracer's one diffuse bounce over the covered pixels of the scene's camera, as sums
/// of luminance split by where the bounce lands: `[seen by the camera, facing the eye but
/// hidden, facing away]`. Per pixel `samples` cosine-distributed directions from the first hit
/// (the reference's estimator: albedo times the radiance the landing point sends back, the
/// spot lights' exactly shadowed). A landing point is seen when the side the bounce leaves
/// from faces the eye, the eye's ray towards it meets it first and it projects inside the
/// image.
fn traced_split(
    scene: &formats::Scene,
    bvh: &raycast::SceneBvh,
    (width, height): (u32, u32),
    samples: u32,
) -> [f64; 3] {
    use runtime::direct::cpu::{albedo_at, direct_radiance, facing_normal, ray_epsilon};
    let (materials, textures) = runtime::load::cpu_materials(scene).expect("materials");
    let view = View::of_scene(scene, width, height);
    let eps = ray_epsilon(scene);
    let material = |t: u32| &materials[scene.triangle_materials[t as usize] as usize];
    let seen = |y: Vec3| {
        let clip = view.view_proj * y.extend(1.0);
        let ndc = clip.xyz() / clip.w;
        if clip.w <= 0.0 || ndc.x.abs() > 1.0 || ndc.y.abs() > 1.0 {
            return false;
        }
        let to = y - view.eye;
        let dist = to.length();
        bvh.closest_hit(view.eye, to / dist, 0.0, f32::INFINITY)
            .is_some_and(|(t, _)| t > dist - 4.0 * eps)
    };
    (0..width * height)
        .into_par_iter()
        .map(|pixel| {
            let (px, py) = (pixel % width, pixel / width);
            let d = view.primary_ray(px, py);
            let mut sums = [0.0f64; 3];
            let Some((t, triangle)) = bvh.closest_hit(view.eye, d, 0.0, f32::INFINITY) else {
                return sums;
            };
            let x = view.eye + d * t;
            let n = facing_normal(scene, triangle, -d);
            let rho = albedo_at(scene, material(triangle), &textures, triangle, x);
            let (t1, t2) = runtime::radiosity::transfer::tangent_frame(n);
            let mut rng = raycast::SplitMix64(u64::from(pixel) * 0x9e37_79b9 + 1);
            for _ in 0..samples {
                let (u1, u2) = (rng.next_f64() as f32, rng.next_f64() as f32);
                let (r, phi) = (u1.sqrt(), std::f32::consts::TAU * u2);
                let wi = t1 * (r * phi.cos()) + t2 * (r * phi.sin()) + n * (1.0 - u1).sqrt();
                let origin = x + n * eps;
                let Some((s, hit)) = bvh.closest_hit(origin, wi, 0.0, f32::INFINITY) else {
                    continue;
                };
                let y = origin + wi * s;
                let ny = facing_normal(scene, hit, -wi);
                let m = material(hit);
                let albedo_y = albedo_at(scene, m, &textures, hit, y);
                let sent = direct_radiance(scene, bvh, eps, y, ny, ny, -wi, albedo_y, m).0;
                let light = luminance(rho * sent) / f64::from(samples);
                // The side the bounce leaves from must be the side the eye sees.
                let class = if ny.dot(view.eye - y) <= 0.0 {
                    2
                } else if seen(y) {
                    0
                } else {
                    1
                };
                sums[class] += light;
            }
            sums
        })
        .reduce(|| [0.0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]])
}
