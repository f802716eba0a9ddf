//! Screen-space indirect illumination (`cssm_runtime::ssil`) against its CPU twins: the
//! G-buffer pyramid's vote and the light's mean, the solid voxels of the view frustum against
//! ray casts through their columns and their AND down the levels, every level's gather for
//! every pixel, the temporal filter; and the levels together against a brute-force sum over
//! every pixel of the G-buffer.

use cssm_formats::Scene;
use cssm_runtime::{
    Renderer, RendererSettings,
    common::{
        compose::Component,
        pyramid::{CpuLevel, mean_cpu, vote_cpu},
        readback::{read_buffer, read_texture, render_image, vec4s},
        timestamps::PassTimer,
    },
    frame::{FrameContext, FrameEncoder, FrameSettings},
    gpu_types::GpuMaterial,
    method::{self, OptionValues},
    ssil::{
        ScreenSpaceGi, SsilOptions, Visibility,
        cpu::{self, GatherInputs},
    },
};
use glam::{Mat4, Vec3, Vec4};

use super::{cornell, gpu};

/// A renderer of `direct` on `scene` at `size`, one frame rendered: the context (G-buffer,
/// shadow maps) the tests' own SSIL pipelines run over.
pub(super) fn context_renderer(scene: &Scene, size: (u32, u32)) -> Renderer {
    let mut renderer = renderer_of("direct", scene, size, Component::Indirect);
    render_image(&mut renderer, 1).expect("render");
    renderer
}

/// A renderer of method `name` on `scene` at `size` drawing `component`.
pub(super) fn renderer_of(
    name: &str,
    scene: &Scene,
    size: (u32, u32),
    component: Component,
) -> Renderer {
    let gpu = gpu();
    let settings = RendererSettings {
        frame: FrameSettings {
            width: size.0,
            height: size.1,
            shadow_resolution: 512,
            ..Default::default()
        },
        component,
        ..Default::default()
    };
    Renderer::new(
        &gpu.device,
        &gpu.queue,
        scene,
        None,
        method::find(name).unwrap(),
        &OptionValues::default(),
        &settings,
    )
    .expect("renderer")
}

/// `frames` frames of an SSIL pipeline of `options` over the renderer's context.
pub(super) fn run(
    ctx: &FrameContext,
    scene: &Scene,
    options: &SsilOptions,
    frames: u32,
) -> ScreenSpaceGi {
    let mut gi = ScreenSpaceGi::new(ctx, scene.bounds(), options).expect("ssil");
    for _ in 0..frames {
        encode(&mut gi, ctx);
    }
    gi
}

pub(super) fn read4(ctx: &FrameContext, buffer: &wgpu::Buffer) -> Vec<Vec4> {
    vec4s(&read_buffer(&ctx.device, &ctx.queue, buffer, 0, buffer.size()).expect("read"))
}

fn read_words(ctx: &FrameContext, buffer: &wgpu::Buffer) -> Vec<u32> {
    let bytes = read_buffer(&ctx.device, &ctx.queue, buffer, 0, buffer.size()).expect("read");
    bytemuck::cast_slice(&bytes).to_vec()
}

pub(super) fn texture4(ctx: &FrameContext, texture: &wgpu::Texture) -> Vec<Vec4> {
    vec4s(&read_texture(&ctx.device, &ctx.queue, texture, 16).expect("read texture"))
}

fn materials(ctx: &FrameContext) -> Vec<GpuMaterial> {
    let buffer = &ctx.scene.materials;
    let bytes = read_buffer(&ctx.device, &ctx.queue, buffer, 0, buffer.size()).expect("read");
    bytemuck::cast_slice(&bytes).to_vec()
}

pub(super) fn test_options() -> SsilOptions {
    SsilOptions {
        samples: 12,
        levels: 3,
        start_level: 1,
        radius: 6.0,
        bounces: 1,
        temporal: 0.0,
        ..Default::default()
    }
}

fn level_of(all: &[Vec4], gi: &ScreenSpaceGi, level: u32) -> Vec<Vec4> {
    let layout = gi.levels().pyramid;
    let (w, h) = layout.size(level);
    let start = layout.offset(level) as usize;
    all[start..start + (w * h) as usize].to_vec()
}

#[test]
fn pyramids_match_cpu_twins() {
    let (scene, _) = cornell();
    let renderer = context_renderer(scene, (45, 34));
    let ctx = renderer.context();
    let gi = run(ctx, scene, &test_options(), 1);
    let eye: Vec3 = ctx.gpu_view().eye.into();
    let mut fine = CpuLevel {
        size: ctx.size(),
        position: texture4(ctx, &ctx.gbuffer.position),
        normal: texture4(ctx, &ctx.gbuffer.normal),
        albedo: texture4(ctx, &ctx.gbuffer.albedo),
    };
    let pyramid = gi.pyramid();
    let [position, normal, albedo] =
        [&pyramid.position, &pyramid.normal, &pyramid.albedo].map(|b| read4(ctx, b));
    let sender = read4(ctx, gi.sender());
    let light = read4(ctx, &gi.light().signal);
    let mut signal = sender[..(ctx.size().0 * ctx.size().1) as usize].to_vec();
    let mut signal_size = ctx.size();
    for level in 1..=gi.levels().last {
        let cpu_level = vote_cpu(&fine, eye);
        let gpu_level = CpuLevel {
            size: gi.levels().pyramid.size(level),
            position: level_of(&position, &gi, level),
            normal: level_of(&normal, &gi, level),
            albedo: level_of(&albedo, &gi, level),
        };
        // The vote picks one child's values as they are; a near tie may fall either way in
        // the last bit of a score.
        let differ = (0..cpu_level.position.len())
            .filter(|&i| {
                cpu_level.position[i] != gpu_level.position[i]
                    || cpu_level.normal[i] != gpu_level.normal[i]
                    || cpu_level.albedo[i] != gpu_level.albedo[i]
            })
            .count();
        assert!(
            differ * 100 <= cpu_level.position.len(),
            "level {level}: {differ} of {} pixels voted otherwise",
            cpu_level.position.len()
        );
        assert!(gpu_level.position.iter().any(|p| p.w > 0.0));
        // The light's mean, from the GPU's finer level.
        let cpu_light = mean_cpu(&signal, signal_size);
        let gpu_light = level_of(&light, &gi, level);
        for (i, (c, g)) in cpu_light.iter().zip(&gpu_light).enumerate() {
            assert!(
                (*c - *g).abs().max_element() <= 1e-5 * c.abs().max_element().max(1e-3),
                "level {level} pixel {i}: light {g} against {c}"
            );
        }
        fine = gpu_level;
        signal = gpu_light;
        signal_size = fine.size;
    }
}

#[test]
fn voxels_match_ray_casts() {
    let (scene, _) = cornell();
    let size = (48, 36);
    let renderer = context_renderer(scene, size);
    let ctx = renderer.context();
    let options = test_options();
    let gi = run(ctx, scene, &options, 1);
    let levels = gi.levels();
    let grid = read_words(ctx, gi.grid());
    let params = gi.frame_params(ctx);
    let triangles: Vec<[Vec3; 3]> = (0..scene.triangles.len())
        .map(|t| scene.triangle(t))
        .collect();
    let view_proj = Mat4::from_cols_array_2d(&ctx.gpu_view().view_proj);
    let cpu_grid = cpu::voxelize(
        &triangles,
        view_proj,
        size,
        levels.start,
        (params.z_near, params.z_far),
    );
    let columns = cpu_grid.len() / 4;
    let differ = (0..columns)
        .filter(|&c| cpu_grid[4 * c..4 * c + 4] != grid[4 * c..4 * c + 4])
        .count();
    // The rasteriser's coverage of a triangle's edge differs from the ray casts' on a few
    // columns; everything else matches bit for bit.
    assert!(
        differ * 50 <= columns,
        "{differ} of {columns} columns differ from the ray casts"
    );
    let solid = cpu_grid.iter().map(|w| w.count_ones()).sum::<u32>();
    assert!(solid > 0, "the Cornell box's boxes are solid");
    for level in levels.start + 1..=levels.last {
        let fine_size = levels.pyramid.size(level - 1);
        let at = |l: u32| 4 * levels.grid_offset(l) as usize;
        let fine = &grid[at(level - 1)..at(level - 1) + 4 * (fine_size.0 * fine_size.1) as usize];
        let coarse = cpu::and_down(fine, fine_size);
        assert_eq!(
            &grid[at(level)..at(level) + coarse.len()],
            &coarse[..],
            "level {level}"
        );
    }
}

/// Every pixel of every gathered level against `gather_pixel` over the GPU's own inputs, with
/// and without visibility, on the plain and the glossy Cornell box.
#[test]
fn gather_matches_cpu_twin() {
    let glossy = Scene::load(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes/cornell-glossy")
            .as_path(),
    )
    .expect("glossy Cornell box");
    for (scene, visibility) in [
        (&cornell().0, Visibility::Voxels),
        (&cornell().0, Visibility::None),
        (&glossy, Visibility::Voxels),
    ] {
        let renderer = context_renderer(scene, (40, 30));
        let ctx = renderer.context();
        let options = SsilOptions {
            visibility,
            ..test_options()
        };
        let gi = run(ctx, scene, &options, 1);
        let levels = gi.levels();
        let view = ctx.gpu_view();
        let [position, normal] =
            [&gi.pyramid().position, &gi.pyramid().normal].map(|b| read4(ctx, b));
        let sender = read4(ctx, &gi.light().signal);
        let grid = read_words(ctx, gi.grid());
        let gathered = read4(ctx, gi.gathered());
        let materials = materials(ctx);
        let inputs = GatherInputs {
            view_proj: Mat4::from_cols_array_2d(&view.view_proj),
            eye: view.eye.into(),
            frame: gi.frame_params(ctx),
            materials: &materials,
            position: &position,
            normal: &normal,
            sender: &sender,
            grid: &grid,
            gathered: &gathered,
        };
        let pixels = levels.pyramid.pixels() as usize;
        let (mut checked, mut off, mut lit, mut glossy_lit) = (0, 0, 0, 0);
        for level in levels.start..=levels.last {
            let params = levels.gather_params(level, 0, &options);
            let (w, h) = levels.pyramid.size(level);
            for y in 0..h {
                for x in 0..w {
                    let [d, g] = cpu::gather_pixel(&inputs, &params, (x, y));
                    let i = levels.pyramid.index(level, (x, y));
                    let (gd, gg) = (gathered[i].truncate(), gathered[pixels + i].truncate());
                    checked += 1;
                    lit += usize::from(d.max_element() > 0.0);
                    glossy_lit += usize::from(g.max_element() > 0.0);
                    let near = |a: Vec3, b: Vec3| {
                        (a - b).abs().max_element() <= 1e-3 * b.abs().max_element().max(1e-4)
                    };
                    if !near(gd, d) || !near(gg, g) {
                        off += 1;
                    }
                }
            }
        }
        // A march may decide a sample's visibility otherwise where a point falls on a voxel's
        // edge in one and not the other; a pixel with such a sample is off.
        assert!(
            off * 50 <= checked,
            "{} {visibility:?}: {off} of {checked} pixels differ from the twin",
            scene.name
        );
        assert!(
            lit * 2 > checked,
            "{lit} of {checked} pixels gathered light"
        );
        if scene.name.contains("glossy") {
            assert!(glossy_lit > 0, "the glossy floor gathers its lobe");
        }
    }
}

/// The levels' rings together stand for the whole screen: the mean irradiance SSIL gathers
/// without visibility, over many frames' sample patterns, against the sum of Eq. 3 with Eq. 4
/// over every covered pixel of the finest gathered level (each its own disc), for that level's
/// receivers. The same sum over the G-buffer's full-res pixels is printed beside it: what the
/// reduced resolution itself loses (near-field light where the coarse pixels cannot resolve a
/// corner).
#[test]
fn the_levels_gather_the_whole_screen() {
    let (scene, _) = cornell();
    let size = (80, 60);
    let renderer = context_renderer(scene, size);
    let ctx = renderer.context();
    let options = SsilOptions {
        visibility: Visibility::None,
        samples: 32,
        levels: 4,
        radius: 8.0,
        ..test_options()
    };
    let mut gi = ScreenSpaceGi::new(ctx, scene.bounds(), &options).expect("ssil");
    let levels = gi.levels();
    let (lw, lh) = levels.pyramid.size(levels.start);
    let mut summed = vec![Vec3::ZERO; (lw * lh) as usize];
    let frames = 24;
    for _ in 0..frames {
        encode(&mut gi, ctx);
        for (s, v) in summed.iter_mut().zip(read4(ctx, gi.summed())) {
            *s += v.truncate() / frames as f32;
        }
    }
    let view = ctx.gpu_view();
    let view_proj = Mat4::from_cols_array_2d(&view.view_proj);
    let eye: Vec3 = view.eye.into();
    let pixel_area = gi.frame_params(ctx).pixel_area;
    let full = [&ctx.gbuffer.position, &ctx.gbuffer.normal].map(|t| texture4(ctx, t));
    let sender = read4(ctx, gi.sender());
    let level = [
        &gi.pyramid().position,
        &gi.pyramid().normal,
        &gi.light().signal,
    ]
    .map(|b| level_of(&read4(ctx, b), &gi, levels.start));
    let senders = |position, normal, light, scale| cpu::ScreenSenders {
        position,
        normal,
        light,
        view_proj,
        eye,
        pixel_area,
        scale,
    };
    let over_level_pixels = senders(
        &level[0],
        &level[1],
        &level[2],
        (1u32 << (2 * levels.start)) as f32,
    );
    let over_full_pixels = senders(&full[0], &full[1], &sender, 1.0);
    let always = |_: Vec3, _: Vec3, _: Vec3, _: Vec3| true;
    let sum = |(all, _): (Vec3, Vec3)| f64::from(all.element_sum());
    let (mut ssil, mut over_level, mut over_full) = (0.0f64, 0.0f64, 0.0f64);
    for (i, x4) in level[0].iter().enumerate() {
        if x4.w <= 0.0 {
            continue;
        }
        let (x, n) = (x4.truncate(), level[1][i].truncate());
        ssil += f64::from(summed[i].element_sum());
        over_level += sum(over_level_pixels.irradiance(x, n, Some(i), &always));
        over_full += sum(over_full_pixels.irradiance(x, n, None, &always));
    }
    let ratio = ssil / over_level;
    eprintln!(
        "ssil / the sum over its finest level's pixels: {ratio:.4}; that sum / the sum over \
         the full-res pixels: {:.4}",
        over_level / over_full
    );
    assert!(
        (ratio - 1.0).abs() < 0.08,
        "ssil gathers {ratio} of the level's light"
    );
}

fn encode(gi: &mut ScreenSpaceGi, ctx: &FrameContext) {
    let gpu = gpu();
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
}

/// The temporal filter of a frame after the camera moved against `temporal_pixel`, on the
/// glossy box (the lobe-weighted plane's weight follows the camera's turn).
#[test]
fn temporal_filter_matches_cpu_twin() {
    let glossy = Scene::load(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes/cornell-glossy")
            .as_path(),
    )
    .expect("glossy Cornell box");
    let mut renderer = context_renderer(&glossy, (40, 30));
    let options = SsilOptions {
        temporal: 0.8,
        ..test_options()
    };
    let mut gi = ScreenSpaceGi::new(renderer.context(), glossy.bounds(), &options).expect("ssil");
    encode(&mut gi, renderer.context());
    let (previous_view, history, history_position, history_normal) = {
        let ctx = renderer.context();
        (
            ctx.gpu_view(),
            read4(ctx, gi.blended()),
            texture4(ctx, &ctx.gbuffer.position),
            texture4(ctx, &ctx.gbuffer.normal),
        )
    };
    let mut camera = glossy.camera.clone();
    camera.position += Vec3::new(15.0, 5.0, 0.0);
    renderer.set_camera(&camera).expect("camera");
    render_image(&mut renderer, 1).expect("render");
    let ctx = renderer.context();
    encode(&mut gi, ctx);
    let materials = materials(ctx);
    let inputs = cpu::TemporalInputs {
        eye: ctx.gpu_view().eye.into(),
        previous_view_proj: Mat4::from_cols_array_2d(&previous_view.view_proj),
        previous_eye: previous_view.eye.into(),
        blend: options.temporal,
        size: ctx.size(),
        materials: &materials,
        position: &texture4(ctx, &ctx.gbuffer.position),
        normal: &texture4(ctx, &ctx.gbuffer.normal),
        history_position: &history_position,
        history_normal: &history_normal,
        current: &read4(ctx, gi.filtered()),
        history: &history,
    };
    let blended = read4(ctx, gi.blended());
    let (w, h) = ctx.size();
    let plane = (w * h) as usize;
    let (mut reprojected, mut off) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let [d, g] = cpu::temporal_pixel(&inputs, (x, y));
            let i = (y * w + x) as usize;
            reprojected += usize::from(d != inputs.current[i]);
            let near = |a: Vec4, b: Vec4| {
                (a - b).abs().max_element() <= 1e-4 * b.abs().max_element().max(1e-4)
            };
            if !near(blended[i], d) || !near(blended[plane + i], g) {
                off += 1;
            }
        }
    }
    assert!(
        off * 100 <= plane,
        "{off} of {plane} pixels differ from the twin"
    );
    assert!(
        reprojected * 2 > plane,
        "only {reprojected} of {plane} pixels found history"
    );
}

/// `--method ssil` through the renderer: a resize rebuilds the levels (another pyramid, grid
/// and history) and the next frames gather light again.
#[test]
fn the_renderer_resizes_ssil() {
    let (scene, _) = cornell();
    let mut renderer = renderer_of("ssil", scene, (48, 36), Component::Indirect);
    let lit = |image: &cssm_runtime::common::readback::Image| {
        image
            .radiance
            .iter()
            .filter(|p| p[0] + p[1] + p[2] > 0.0)
            .count()
    };
    let first = render_image(&mut renderer, 2).expect("render");
    assert!(lit(&first) * 2 > first.radiance.len());
    renderer.resize(37, 29).expect("resize");
    let resized = render_image(&mut renderer, 2).expect("render after resize");
    assert_eq!(resized.radiance.len(), 37 * 29);
    assert!(lit(&resized) * 2 > resized.radiance.len());
}

/// The light each pixel sends is its diffuse direct light: on the Cornell box, whose materials
/// have no Ks, the direct pass's own radiance (held to exact ray casts by
/// `direct_light_matches_cpu_reference`).
#[test]
fn the_sent_light_is_the_diffuse_direct_light() {
    let (scene, _) = cornell();
    let mut renderer = renderer_of("direct", scene, (40, 30), Component::Direct);
    render_image(&mut renderer, 1).expect("render");
    let ctx = renderer.context();
    let gi = run(ctx, scene, &test_options(), 1);
    let direct = texture4(ctx, renderer.radiance());
    let sender = read4(ctx, gi.sender());
    let mut lit = 0;
    for (i, (d, s)) in direct.iter().zip(&sender).enumerate() {
        let (d, s) = (d.truncate(), s.truncate());
        lit += usize::from(d.max_element() > 0.0);
        assert!(
            (d - s).abs().max_element() <= 1e-5 * d.max_element().max(1e-3),
            "pixel {i}: sent {s}, direct {d}"
        );
    }
    assert!(lit * 4 > direct.len(), "{lit} lit pixels");
}

/// Two bounces: the filters' input is the sum of both bounces' finest level, and the second
/// bounce's light is `accumulate`'s from the first (albedo / pi times its diffuse irradiance),
/// its coarser levels the means again. The first bounce's own result is what the sum holds
/// beyond the second's (which the gathered planes keep at the end of the frame).
#[test]
fn bounces_accumulate_as_the_twin() {
    let (scene, _) = cornell();
    let renderer = context_renderer(scene, (40, 30));
    let ctx = renderer.context();
    let options = SsilOptions {
        bounces: 2,
        visibility: Visibility::None,
        ..test_options()
    };
    let gi = run(ctx, scene, &options, 1);
    let levels = gi.levels();
    let (s, pixels) = (levels.start, levels.pyramid.pixels() as usize);
    let summed = read4(ctx, gi.summed());
    let gathered = read4(ctx, gi.gathered());
    let light = read4(ctx, &gi.light().signal);
    let albedo = level_of(&read4(ctx, &gi.pyramid().albedo), &gi, s);
    let plane = albedo.len();
    let mut lit = 0;
    for i in 0..plane {
        let j = levels.pyramid.offset(s) as usize + i;
        let second = [gathered[j].truncate(), gathered[pixels + j].truncate()];
        let sum = [summed[i].truncate(), summed[plane + i].truncate()];
        let first = [sum[0] - second[0], sum[1] - second[1]];
        let scale = sum[0].max_element().max(1e-6);
        let (_, sent) = cpu::accumulate(first, None, albedo[i].truncate(), true);
        let sent = sent.expect("a bounce follows");
        lit += usize::from(sent.max_element() > 0.0);
        assert!(
            (light[j].truncate() - sent).abs().max_element() <= 1e-4 * scale,
            "pixel {i}: sent {} against {sent}",
            light[j]
        );
    }
    assert!(
        lit * 2 > plane,
        "{lit} of {plane} pixels send light in the second bounce"
    );
    // The second bounce's coarser levels: the means of its finest.
    let mut fine = level_of(&light, &gi, s);
    for level in s + 1..=levels.last {
        let coarse = mean_cpu(&fine, levels.pyramid.size(level - 1));
        let got = level_of(&light, &gi, level);
        for (c, g) in coarse.iter().zip(&got) {
            assert!((*c - *g).abs().max_element() <= 1e-5 * c.abs().max_element().max(1e-3));
        }
        fine = got;
    }
}

/// `bounces=0` gathers until a bounce reflects at most 1% of the light so far, decided every
/// frame on the light pyramid's top level: the light each exact run's last pyramid holds (the
/// direct light's with one bounce, the first bounce's reflection with two, ...) gives the
/// shares, the rule on them says where the converging run stops, and its summed light is that
/// exact run's. At 1% the box runs out of its 4 bounces (shares 21%, 6%, 2%); at 5% it stops
/// after 3, the fourth gathering nothing.
#[test]
fn bounces_stop_once_converged() {
    use cssm_runtime::common::converge::{BouncePlan, CONVERGED_FRACTION, run_plan};
    let (scene, _) = cornell();
    let renderer = context_renderer(scene, (40, 30));
    let ctx = renderer.context();
    let with = |bounces| SsilOptions {
        bounces,
        visibility: Visibility::None,
        ..test_options()
    };
    // The light the last pyramid of an exact run of `n` bounces holds, summed over its top.
    let top = |gi: &ScreenSpaceGi| -> Vec3 {
        let light = read4(ctx, &gi.light().signal);
        level_of(&light, gi, gi.levels().last)
            .iter()
            .fold(Vec3::ZERO, |sum, v| sum + v.truncate())
    };
    let exact: Vec<ScreenSpaceGi> = (1..=4).map(|n| run(ctx, scene, &with(n), 1)).collect();
    gpu().wait().expect("the frames run");
    let tops: Vec<Vec3> = exact.iter().map(top).collect();
    let mut stopped = Vec::new();
    for fraction in [CONVERGED_FRACTION, 0.05] {
        let mut cumulative = tops[0];
        let expected = run_plan(BouncePlan { max: 3, fraction }, cumulative, |k| {
            cumulative += tops[k as usize];
            cumulative
        });
        let kept = if expected.converged {
            expected.bounces
        } else {
            4
        };
        let options = SsilOptions {
            converge: fraction,
            ..with(0)
        };
        let auto = run(ctx, scene, &options, 1);
        let ended = auto.convergence(ctx).expect("read");
        eprintln!("ssil until {fraction}: {ended}; the rule on the exact runs: {expected:?}");
        assert_eq!(ended.bounces, kept, "{ended} {expected:?}");
        assert_eq!(ended.converged, expected.converged);
        assert!(
            (ended.added - expected.added).abs() < 1e-4,
            "{ended} {expected:?}"
        );
        let summed = read4(ctx, auto.summed());
        let want = read4(ctx, exact[kept as usize - 1].summed());
        let scale = want.iter().map(|v| v.max_element()).fold(0.0f32, f32::max);
        for (a, b) in summed.iter().zip(&want) {
            assert!((*a - *b).abs().max_element() <= 1e-5 * scale, "{a} {b}");
        }
        stopped.push(ended.converged);
    }
    assert_eq!(
        stopped,
        [false, true],
        "one run stops early, its later gathers skipped"
    );
}
