//! The shared GPU voxeliser against its CPU twin: the same set of voxel fragments (voxel,
//! albedo, normal, triangle) for the built-in scenes.

use cssm_formats::Scene;
use cssm_runtime::{
    common::{
        readback::read_buffer,
        timestamps::PassTimer,
        voxelize::{CpuTriangle, VoxelFragment, VoxelGrid, Voxelizer, voxelize_cpu},
    },
    frame::FrameEncoder,
    load::SceneGpu,
};

use super::gpu;

/// The GPU's fragments of `scene` at `resolution`, sorted, and the CPU twin's.
fn both(scene: &Scene, resolution: u32) -> (Vec<VoxelFragment>, Vec<VoxelFragment>) {
    let gpu = gpu();
    let scene_gpu = SceneGpu::new(&gpu.device, &gpu.queue, scene, None).expect("scene");
    let grid = VoxelGrid::of_scene(scene.bounds(), resolution);
    let voxelizer = Voxelizer::new(&gpu.device, &scene_gpu, grid, 1 << 20).expect("voxelizer");
    let mut timer = PassTimer::new(&gpu.device, &gpu.queue);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    voxelizer.run(&mut FrameEncoder {
        encoder: &mut encoder,
        timer: &mut timer,
        index: 0,
    });
    gpu.queue.submit([encoder.finish()]);
    let count = read_buffer(&gpu.device, &gpu.queue, &voxelizer.count, 0, 4).expect("count");
    let count = u32::from_le_bytes(count[..4].try_into().unwrap());
    assert!(
        count <= voxelizer.capacity,
        "{count} fragments overflow the list"
    );
    let size = count as u64 * std::mem::size_of::<VoxelFragment>() as u64;
    let bytes = read_buffer(
        &gpu.device,
        &gpu.queue,
        &voxelizer.fragments,
        0,
        size.max(16),
    )
    .expect("fragments");
    let mut on_gpu: Vec<VoxelFragment> = bytemuck::cast_slice(&bytes[..size as usize]).to_vec();
    on_gpu.sort_unstable();
    let triangles: Vec<CpuTriangle> = (0..scene.triangles.len())
        .map(|t| CpuTriangle {
            corners: scene.triangle(t),
            uv: scene.triangles[t]
                .map(|v| scene.texcoords.get(v as usize).copied().unwrap_or([0.0; 2])),
            material: scene.triangle_materials[t],
        })
        .collect();
    let on_cpu = voxelize_cpu(
        &triangles,
        &grid,
        &scene_gpu.cpu_materials,
        &scene_gpu.cpu_textures,
    );
    (on_gpu, on_cpu)
}

#[test]
fn gpu_voxelisation_matches_brute_force() {
    for (name, resolution) in [("cornell-box", 32), ("cornell-glossy", 64)] {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
        let scene = Scene::load(&dir).expect("scene");
        let (on_gpu, on_cpu) = both(&scene, resolution);
        let gpu_set: std::collections::BTreeSet<_> = on_gpu.iter().collect();
        let cpu_set: std::collections::BTreeSet<_> = on_cpu.iter().collect();
        let only_gpu = gpu_set.difference(&cpu_set).count();
        let only_cpu = cpu_set.difference(&gpu_set).count();
        eprintln!(
            "voxelise {name} at {resolution}³: {} fragments on the GPU, {} on the CPU, {only_gpu} \
             only on the GPU, {only_cpu} only on the CPU",
            on_gpu.len(),
            on_cpu.len()
        );
        assert_eq!(gpu_set.len(), on_gpu.len(), "a fragment written twice");
        assert!(!on_cpu.is_empty());
        // A voxel whose face a triangle just touches may fall either side of f32 rounding.
        assert!(
            (only_gpu + only_cpu) * 1000 <= on_cpu.len(),
            "{only_gpu} + {only_cpu} of {}",
            on_cpu.len()
        );
    }
}

/// A textured, tilted quad: the albedo of each fragment is the texture's at the voxel, the same
/// on both sides.
#[test]
fn gpu_voxelisation_samples_textures_like_the_cpu() {
    let dir = tempfile::tempdir().unwrap();
    let mut checker = image::RgbImage::new(8, 8);
    for (x, y, p) in checker.enumerate_pixels_mut() {
        *p = if (x + y) % 2 == 0 {
            image::Rgb([250, 40, 10])
        } else {
            image::Rgb([20, 200, 90])
        };
    }
    checker.save(dir.path().join("checker.png")).unwrap();
    std::fs::write(
        dir.path().join("quad.mtl"),
        "newmtl tex\nKd 0.9 0.8 0.7\nKs 0 0 0\nNs 1\nmap_Kd checker.png\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("quad.obj"),
        "mtllib quad.mtl\nusemtl tex\nv 0 0 0\nv 1 0.3 0\nv 1 1.3 1\nv 0 1 1\n\
         vt 0 0\nvt 2 0\nvt 2 2\nvt 0 2\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
    )
    .unwrap();
    let scene = Scene::load(dir.path()).expect("quad");
    let (on_gpu, on_cpu) = both(&scene, 24);
    let colours: std::collections::BTreeSet<u32> = on_cpu.iter().map(|f| f.albedo).collect();
    eprintln!(
        "voxelise a textured quad at 24³: {} fragments on the GPU, {} on the CPU, {} colours",
        on_gpu.len(),
        on_cpu.len(),
        colours.len()
    );
    assert!(colours.len() > 10, "the texture shows in the albedo");
    assert_eq!(on_gpu, on_cpu);
}
