//! The reflective shadow map and the `rsm` method against their CPU references: the RSM against
//! rays cast from the light through its texel centres, the sampling with the micro linear
//! buffer against its CPU twin (`cssm_runtime::rsm::cpu`).

use cssm_formats::Scene;
use cssm_runtime::{
    Renderer, RendererSettings,
    common::{
        compose::Component,
        readback::{read_buffer, read_texture, render_image, vec4s},
    },
    frame::FrameSettings,
    gpu_types::GpuSpotLight,
    method::{self, OptionValue, OptionValues},
    rsm::{RsmOptions, Visibility, cpu},
};
use glam::{Mat4, Vec3};

use super::{cornell, gpu};

/// A renderer of `rsm` with `values` on `scene` at `width` x `height`, one frame rendered.
pub(super) fn rsm_renderer(
    scene: &Scene,
    values: &OptionValues,
    size: (u32, u32),
    shadow: u32,
) -> Renderer {
    let gpu = gpu();
    let settings = RendererSettings {
        frame: FrameSettings {
            width: size.0,
            height: size.1,
            shadow_resolution: shadow,
            ..Default::default()
        },
        component: Component::Indirect,
        ..Default::default()
    };
    let method = method::find("rsm").unwrap();
    let mut renderer = Renderer::new(
        &gpu.device,
        &gpu.queue,
        scene,
        None,
        method,
        values,
        &settings,
    )
    .expect("rsm renderer");
    render_image(&mut renderer, 1).expect("render");
    renderer
}

/// The RSM of every light as read back, and the lights as the GPU has them.
pub(super) fn read_rsm(renderer: &Renderer) -> (Vec<cpu::CpuRsm>, Vec<GpuSpotLight>) {
    let ctx = renderer.context();
    let shadows = &ctx.shadows;
    let rsm = shadows.rsm.as_ref().expect("rsm has an RSM");
    assert_eq!(shadows.light_count, 1, "the tests' scenes have one light");
    let read = |t| vec4s(&read_texture(&ctx.device, &ctx.queue, t, 16).expect("read rsm"));
    let resolution = rsm.position.width();
    let maps = vec![cpu::CpuRsm {
        resolution,
        position: read(&rsm.position),
        normal: read(&rsm.normal),
        flux: read(&rsm.flux),
    }];
    let size = std::mem::size_of::<GpuSpotLight>() as u64;
    let bytes = read_buffer(&ctx.device, &ctx.queue, &shadows.lights, 0, size).expect("lights");
    (maps, bytemuck::cast_slice(&bytes).to_vec())
}

/// Every texel of the RSM against the first hit of a ray from the light through its centre:
/// the position, the normal turned towards the light, the flux (albedo, intensity, the texel's
/// solid angle, the cone).
#[test]
fn rsm_matches_ray_casts_from_the_light() {
    let (scene, _) = cornell();
    let renderer = rsm_renderer(scene, &OptionValues::default(), (16, 12), 64);
    let (maps, lights) = read_rsm(&renderer);
    let (rsm, light) = (&maps[0], &lights[0]);
    let (materials, _) = cssm_runtime::load::cpu_materials(scene).unwrap();
    let bvh = cssm_raycast::SceneBvh::new(scene);
    let inverse = Mat4::from_cols_array_2d(&light.view_proj).inverse();
    let origin = Vec3::from(light.position);
    let axis = Vec3::from(light.direction);
    let (lo, hi) = scene.bounds();
    let scale = (hi - lo).length();
    let n = rsm.resolution;
    let (mut compared, mut differ, mut worst_flux) = (0, 0, 0.0f32);
    for j in 0..n {
        for i in 0..n {
            let ndc = glam::Vec2::new(
                (i as f32 + 0.5) / n as f32 * 2.0 - 1.0,
                1.0 - (j as f32 + 0.5) / n as f32 * 2.0,
            );
            let far = inverse.project_point3(ndc.extend(0.5));
            let dir = (far - origin).normalize();
            let index = (j * n + i) as usize;
            let gpu_position = rsm.position[index];
            let Some((t, triangle)) = bvh.closest_hit(origin, dir, 0.0, f32::INFINITY) else {
                assert_eq!(
                    gpu_position.w, 0.0,
                    "texel {i},{j}: covered, but the ray misses"
                );
                continue;
            };
            compared += 1;
            let hit = origin + t * dir;
            if gpu_position.w == 0.0 || (gpu_position.truncate() - hit).length() > 1e-3 * scale {
                // A silhouette between the raster's and the ray's triangle.
                differ += 1;
                continue;
            }
            let [a, b, c] = scene.triangle(triangle as usize);
            let mut normal = (b - a).cross(c - a).normalize();
            if normal.dot(dir) > 0.0 {
                normal = -normal;
            }
            let gpu_normal = rsm.normal[index].truncate();
            assert!(
                gpu_normal.dot(normal) > 0.9999,
                "texel {i},{j}: {gpu_normal} vs {normal}"
            );
            let kd = Vec3::from(materials[scene.triangle_materials[triangle as usize] as usize].kd);
            let cos_axis = dir.dot(axis);
            let expected = if cos_axis >= light.cos_cutoff {
                kd * Vec3::from(light.intensity) * light.texel_solid_angle * cos_axis.powi(3)
            } else {
                Vec3::ZERO
            };
            let got = rsm.flux[index].truncate();
            let error = (got - expected).length() / expected.length().max(1e-30);
            if expected != Vec3::ZERO {
                worst_flux = worst_flux.max(error);
            } else {
                assert_eq!(got, Vec3::ZERO, "texel {i},{j}: flux outside the cone");
            }
        }
    }
    eprintln!(
        "rsm {n}x{n}: {compared} texels hit, {differ} differ in position (silhouettes), largest \
         relative flux error {worst_flux:.2e}"
    );
    assert!(compared > (n * n / 2) as usize);
    assert!(
        differ * 100 <= compared,
        "{differ} of {compared} texels differ"
    );
    assert!(worst_flux < 1e-3, "{worst_flux}");
}

/// The GPU's indirect light without the filters (`downsample` 1, `blur` 0: the up-sampling is
/// then the identity) against the CPU twin's gather and resolve, for every pixel, with and
/// without the micro linear buffer.
#[test]
fn rsm_sampling_matches_cpu_twin() {
    let (scene, _) = cornell();
    let (w, h) = (24u32, 18u32);
    let (materials, _) = cssm_runtime::load::cpu_materials(scene).unwrap();
    for visibility in ["micro-buffer", "none"] {
        let mut values = OptionValues::default();
        values
            .set("downsample", OptionValue::Count(1))
            .set("blur", OptionValue::Count(0))
            .set("visibility", OptionValue::Choice(visibility));
        let resolved = method::find("rsm").unwrap().resolve(&values).unwrap();
        let options = RsmOptions::from_resolved(&resolved);
        let mut renderer = rsm_renderer(scene, &values, (w, h), 128);
        let image = render_image(&mut renderer, 1).expect("second frame");
        let (maps, lights) = read_rsm(&renderer);
        let ctx = renderer.context();
        let read = |t| vec4s(&read_texture(&ctx.device, &ctx.queue, t, 16).expect("gbuffer"));
        let (position, normal, albedo) = (
            read(&ctx.gbuffer.position),
            read(&ctx.gbuffer.normal),
            read(&ctx.gbuffer.albedo),
        );
        let eye = ctx.camera.eye;
        let (mut worst, mut sum_sq, mut sum_ref, mut off) = (0.0f32, 0.0f64, 0.0f64, 0);
        let mut covered = 0;
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let gpu_value = Vec3::from_slice(&image.radiance[i][..3]);
                if position[i].w == 0.0 {
                    assert_eq!(gpu_value, Vec3::ZERO);
                    continue;
                }
                covered += 1;
                let material = materials[normal[i].w as usize];
                let receiver = cpu::Receiver {
                    pixel: (x, y),
                    position: position[i].truncate(),
                    normal: normal[i].truncate(),
                    material,
                    eye,
                };
                let [diffuse, glossy] = cpu::gather(&maps, &lights, &receiver, &options);
                let expected = albedo[i].truncate() / std::f32::consts::PI * diffuse
                    + Vec3::from(material.ks) * glossy;
                let error = (gpu_value - expected).length() as f64;
                sum_sq += error * error;
                sum_ref += expected.length_squared() as f64;
                let relative = error as f32 / expected.length().max(1e-6);
                if relative > 1e-3 {
                    off += 1;
                }
                worst = worst.max(relative);
            }
        }
        let rmse = (sum_sq / sum_ref.max(1e-30)).sqrt();
        eprintln!(
            "rsm sampling, {visibility}, {w}x{h}: GPU vs CPU twin relative RMSE {:.2e}, {off} \
             of {covered} pixels off by more than 0.1% (worst {worst:.2e})",
            rmse
        );
        assert!(options.visibility == Visibility::None || visibility == "micro-buffer");
        // A sample whose elevation sits on a slot boundary may fall on either side.
        assert!(rmse < 5e-3, "{rmse}");
        assert!(off * 50 <= covered, "{off} of {covered}");
    }
}
