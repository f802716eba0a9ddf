//! Renders global illumination with the cssm runtime inside a wgpu program of your own: your
//! device, your target texture, your command encoder; the runtime records its passes into it.
//!
//! ```sh
//! cargo run --release --manifest-path examples/bake-library/Cargo.toml -- \
//!     scenes/cornell-box cornell-box.cssm
//! cargo run --release --manifest-path examples/embed-runtime/Cargo.toml -- \
//!     scenes/cornell-box cornell-box.cssm embedded.png
//! ```

use std::path::PathBuf;

use cssm_runtime::{Renderer, RendererSettings, frame::FrameSettings, method};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene_dir = PathBuf::from(args.next().unwrap_or_else(|| "scenes/cornell-box".into()));
    let cssm_path = PathBuf::from(args.next().unwrap_or_else(|| "cornell-box.cssm".into()));
    let out = PathBuf::from(args.next().unwrap_or_else(|| "embedded.png".into()));
    let (width, height) = (320, 240);

    // Your application's own device (any adapter; here the first one, lavapipe without a GPU).
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_limits: adapter.limits(),
        ..Default::default()
    }))?;

    // The scene, its baked visibility, and a renderer of one method of the table.
    let scene = cssm_formats::Scene::load(&scene_dir)?;
    let cssm = cssm_runtime::load::read_cssm(&cssm_path, &scene)?;
    let settings = RendererSettings {
        frame: FrameSettings { width, height, ..Default::default() },
        ..Default::default()
    };
    let method = method::find("lightmap")?;
    let mut renderer =
        Renderer::new(&device, &queue, &scene, Some(&cssm), method, &Default::default(), &settings)?;

    // Your own target: the renderer draws into it within your encoder, like any pass of yours.
    let target = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("my target"),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: settings.target_format,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    renderer.render(&mut encoder, &target.create_view(&Default::default()));
    queue.submit([encoder.finish()]);

    // Back on the CPU, as a PNG.
    let rgba = cssm_runtime::common::readback::read_texture(&device, &queue, &target, 4)?;
    image::save_buffer(&out, &rgba, width, height, image::ColorType::Rgba8)?;
    println!("{} with {method} on {} -> {}", scene.name, adapter.get_info().name, out.display());
    Ok(())
}
