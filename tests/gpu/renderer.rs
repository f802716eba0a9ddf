//! The persistent renderer: updates that match a fresh one, moving lights, broken scenes,
//! memory accounting and a lost device.

use super::*;

/// The Cornell box with a white block as a rigid `[[objects]]` entry at `translation`, lit by
/// `light` (position, direction), written to `dir`.
pub(crate) fn block_scene(
    dir: &std::path::Path,
    translation: [f32; 3],
    light: ([f32; 3], [f32; 3]),
) -> Scene {
    block_scene_of(dir, translation, light, 1.0, false)
}

/// [`block_scene`] with the block scaled by `scale` and its faces wound outwards when
/// `outward` (their normals pointing out of the block; [`block_scene`]'s point in).
pub(crate) fn block_scene_of(
    dir: &std::path::Path,
    translation: [f32; 3],
    light: ([f32; 3], [f32; 3]),
    scale: f32,
    outward: bool,
) -> Scene {
    let box_dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box");
    for f in ["cornell-box.obj", "cornell-box.mtl"] {
        std::fs::copy(box_dir.join(f), dir.join(f)).unwrap();
    }
    let obj = format!(
        "mtllib cornell-box.mtl\nusemtl white\n{}",
        cssm::builtin::cube_obj([0.0; 3], 60.0, 0, outward)
    );
    std::fs::write(dir.join("block.obj"), obj).unwrap();
    let ([px, py, pz], [dx, dy, dz]) = light;
    let [tx, ty, tz] = translation;
    std::fs::write(
        dir.join("scene.toml"),
        format!(
            "name = \"block\"\nmesh = \"cornell-box.obj\"\n\n[camera]\n\
             position = [278.0, 273.0, -800.0]\ntarget = [278.0, 273.0, 0.0]\n\
             up = [0.0, 1.0, 0.0]\nfov_y_deg = 39.3\nresolution = [64, 48]\n\n\
             [[lights]]\ntype = \"spot\"\nposition = [{px}, {py}, {pz}]\n\
             direction = [{dx}, {dy}, {dz}]\ncutoff_deg = 60.0\n\
             intensity = [500000.0, 500000.0, 500000.0]\n\n\
             [[objects]]\nname = \"block\"\nmesh = \"block.obj\"\n\
             translation = [{tx}, {ty}, {tz}]\nrotation_deg = [0.0, 30.0, 0.0]\nscale = {scale:?}\n"
        ),
    )
    .unwrap();
    Scene::load(dir).expect("block scene loads")
}

/// A renderer moved to another size, camera, light and object position renders what a renderer
/// built for them renders (the persistent state follows every update).
#[test]
fn renderer_updates_match_a_fresh_renderer() {
    let gpu = gpu();
    let light_a = ([278.0, 540.0, 279.5], [0.0, -1.0, 0.0]);
    let light_b = ([200.0, 500.0, 250.0], [0.2, -1.0, 0.1]);
    let (dir_a, dir_b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let scene_a = block_scene(dir_a.path(), [150.0, 0.0, 150.0], light_a);
    let scene_b = block_scene(dir_b.path(), [300.0, 0.0, 250.0], light_b);
    let mut camera = scene_b.camera.clone();
    camera.position += glam::Vec3::new(40.0, -30.0, 60.0);
    camera.fov_y_deg = 45.0;
    let mut moved = scene_b.clone();
    moved.camera = camera.clone();
    let settings = |w, h| RendererSettings {
        frame: FrameSettings {
            width: w,
            height: h,
            shadow_resolution: 512,
            ..Default::default()
        },
        ..Default::default()
    };
    // `direct` (the shared passes), `rsm` (the RSM raster, reduced-resolution buffers and
    // filters that follow a resize, a light and an object) and `vct` (its octree rebuilt for the
    // light and the object, its cones' filters resized; a coarse grid, for time).
    let mut coarse = method::OptionValues::default();
    coarse.set("resolution", method::OptionValue::Count(32));
    for (name, options) in [
        ("direct", Default::default()),
        ("rsm", Default::default()),
        ("vct", coarse),
    ] {
        let entry = method::find(name).unwrap();
        let new = |scene: &Scene, w, h| {
            Renderer::new(
                &gpu.device,
                &gpu.queue,
                scene,
                None,
                entry,
                &options,
                &settings(w, h),
            )
            .expect("renderer")
        };
        let mut renderer = new(&scene_a, 64, 48);
        render_image(&mut renderer, 1).expect("first frame");
        renderer.resize(48, 40).unwrap();
        renderer.set_camera(&camera).unwrap();
        renderer.set_light(0, &scene_b.lights[0]).unwrap();
        renderer
            .set_object_transform(1, scene_b.objects[1].transform)
            .unwrap();
        let updated = render_image(&mut renderer, 1).expect("updated frame");
        let fresh = render_image(&mut new(&moved, 48, 40), 1).expect("fresh frame");
        let (rmse, largest) = image_difference(&updated, &fresh);
        eprintln!(
            "{name}: updated renderer vs fresh: relative RMSE {rmse:.2e}, largest {largest:.2e}"
        );
        // The block is drawn at motion * loaded position instead of at its loaded position: the
        // same point up to rounding, which can move a silhouette pixel.
        assert!(rmse < 1e-2, "{name}: relative RMSE {rmse}");
        // And the errors of the updates.
        assert!(renderer.resize(0, 10).is_err());
        assert!(renderer.set_light(7, &scene_b.lights[0]).is_err());
        assert!(
            renderer
                .set_object_transform(2, glam::Affine3A::IDENTITY)
                .is_err()
        );
        let singular = glam::Affine3A::from_scale(glam::Vec3::ZERO);
        assert!(renderer.set_object_transform(1, singular).is_err());
        let mut bad = camera.clone();
        bad.target = bad.position;
        assert!(renderer.set_camera(&bad).is_err());
    }
}

/// A light moved under `lightmap` or `lightcuts` runs the radiosity (and `lightcuts`' far field)
/// again. With `links=walk` the image equals a renderer built with the light there (same
/// `.cssm`, the geometry did not move); with the cached links (the default), whose cuts were
/// made for the first light, it stays within 1% of it (reports/final-gather.md, "Radiosity
/// with cached links"), and a second move follows too.
#[test]
fn moving_a_light_runs_the_radiosity_again() {
    let gpu = gpu();
    let (scene, file) = cornell32();
    let mut moved = scene.clone();
    moved.lights[0].position += glam::Vec3::new(-80.0, -40.0, 30.0);
    let mut again = moved.clone();
    again.lights[0].position += glam::Vec3::new(60.0, 0.0, -50.0);
    let settings = RendererSettings {
        frame: FrameSettings {
            width: 40,
            height: 30,
            shadow_resolution: 512,
            ..Default::default()
        },
        component: Component::Indirect,
        ..Default::default()
    };
    for (name, links) in [
        ("lightmap", "walk"),
        ("lightmap", "cached"),
        // Its walk's bounces are lightmap's: the cached far field is what it adds.
        ("lightcuts", "cached"),
    ] {
        let method = method::find(name).unwrap();
        let options = method
            // Two bounces: the converged default walks some eight at the first light.
            .parse_options(&format!("links={links},bounces=2"))
            .expect("options");
        let new = |scene: &Scene| {
            Renderer::new(
                &gpu.device,
                &gpu.queue,
                scene,
                Some(file),
                method,
                &options,
                &settings,
            )
            .expect("renderer")
        };
        let mut renderer = new(scene);
        let before = render_image(&mut renderer, 1).expect("frame");
        renderer.set_light(0, &moved.lights[0]).unwrap();
        let after = render_image(&mut renderer, 1).expect("frame");
        renderer.set_light(0, &again.lights[0]).unwrap();
        let twice = render_image(&mut renderer, 1).expect("frame");
        let fresh = render_image(&mut new(&moved), 1).expect("frame");
        let fresh_again = render_image(&mut new(&again), 1).expect("frame");
        let (same, _) = image_difference(&after, &fresh);
        let (same_again, _) = image_difference(&twice, &fresh_again);
        let (changed, _) = image_difference(&before, &fresh);
        eprintln!(
            "{name}, links={links}: moved light {same:.2e} from a fresh renderer, moved again \
             {same_again:.2e}, {changed:.2e} before the move"
        );
        if links == "walk" {
            assert_eq!(same, 0.0, "the indirect light follows the light exactly");
            assert_eq!(same_again, 0.0, "and again");
        } else {
            assert!(
                same < 0.01 && same_again < 0.01,
                "{name}: {same} {same_again}"
            );
        }
        assert!(
            changed > 0.05,
            "{name}: the indirect light changed: {changed}"
        );
    }
}

/// A hand-built scene whose objects do not cover its triangles is refused with an error, not a
/// panic.
#[test]
fn a_scene_with_broken_objects_is_an_error() {
    let gpu = gpu();
    let (scene, _) = cornell();
    let mut broken = scene.clone();
    broken.objects[0].triangles.end -= 1;
    let err = Renderer::new(
        &gpu.device,
        &gpu.queue,
        &broken,
        None,
        method::find("direct").unwrap(),
        &Default::default(),
        &RendererSettings::default(),
    )
    .err()
    .expect("refused");
    assert!(err.to_string().contains("cornell-box"), "{err}");
}

/// `gpu_memory_bytes` counts a buffer's bytes while it lives and not after (a device of its own,
/// so that the other tests' allocations do not count).
#[test]
fn gpu_memory_counts_what_is_allocated() {
    let gpu = Gpu::new_headless().expect("a Vulkan device");
    gpu.wait().unwrap();
    let before = cssm_runtime::gpu_memory_bytes(&gpu.device);
    let size = 4u64 << 20;
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("counted"),
        size,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    gpu.wait().unwrap();
    let during = cssm_runtime::gpu_memory_bytes(&gpu.device) - before;
    assert!(
        during >= size && during < size + (64 << 10),
        "{during} bytes for a buffer of {size}"
    );
    drop(buffer);
    gpu.wait().unwrap();
    assert_eq!(cssm_runtime::gpu_memory_bytes(&gpu.device), before);
}

/// A device lost mid-render (destroyed here, as a driver reset or an unplugged GPU would lose
/// it) makes the render an error, not a hang or a panic, and the error says the device was
/// lost. A device of its own, so that the other tests keep theirs.
#[test]
fn a_lost_device_is_an_error_not_a_hang() {
    let (sender, receiver) = std::sync::mpsc::channel();
    // The whole render in a thread of its own (the renderer is not Send), watched from here.
    std::thread::spawn(move || {
        let own = Gpu::new_headless().expect("a second device");
        let (scene, _) = cornell();
        let mut renderer = Renderer::new(
            &own.device,
            &own.queue,
            scene,
            None,
            method::find("direct").unwrap(),
            &Default::default(),
            &RendererSettings {
                frame: FrameSettings {
                    width: 32,
                    height: 24,
                    ..Default::default()
                },
                ..Default::default()
            },
        )
        .expect("renderer");
        own.device.destroy();
        let rendered = render_image(&mut renderer, 2).map(|_| ());
        let waited = own.wait();
        let _ = sender.send((rendered, waited));
    });
    let (rendered, waited) = receiver
        .recv_timeout(std::time::Duration::from_secs(60))
        .expect("the render after a device loss returned (no hang, no panic)");
    let err = rendered.expect_err("a render on a lost device is an error");
    assert!(err.to_string().contains("device was lost"), "{err}");
    let err = waited.expect_err("waiting on a lost device is an error");
    assert!(err.to_string().contains("device was lost"), "{err}");
}
