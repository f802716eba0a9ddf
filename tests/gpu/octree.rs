//! The sparse voxel octree's structure on the GPU against the voxelisation: every level's
//! occupied nodes are the fragments' voxels at that level, and nothing else.

use cssm_formats::Scene;
use cssm_runtime::{
    common::{
        readback::read_buffer,
        timestamps::PassTimer,
        voxelize::{VoxelFragment, VoxelGrid, Voxelizer},
    },
    frame::FrameEncoder,
    load::SceneGpu,
    vct::octree::{OctreeBuild, occupied_cells, walk},
};

use super::gpu;

fn words(bytes: &[u8]) -> Vec<u32> {
    bytemuck::cast_slice(bytes).to_vec()
}

#[test]
fn octree_levels_match_the_voxelisation() {
    let gpu = gpu();
    for (name, resolution) in [("cornell-box", 32u32), ("cornell-glossy", 64)] {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
        let scene = Scene::load(&dir).expect("scene");
        let scene_gpu = SceneGpu::new(&gpu.device, &gpu.queue, &scene, None).expect("scene");
        let grid = VoxelGrid::of_scene(scene.bounds(), resolution);
        let voxelizer = Voxelizer::new(&gpu.device, &scene_gpu, grid, 1 << 18).expect("voxels");
        let octree = OctreeBuild::new(&gpu.device, &voxelizer, 1 << 16).expect("octree");
        let mut timer = PassTimer::new(&gpu.device, &gpu.queue);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        let mut frame = FrameEncoder {
            encoder: &mut encoder,
            timer: &mut timer,
            index: 0,
        };
        voxelizer.run(&mut frame);
        octree.run(&mut frame, &gpu.queue);
        gpu.queue.submit([encoder.finish()]);
        let read = |buffer, size| read_buffer(&gpu.device, &gpu.queue, buffer, 0, size).unwrap();
        let count = words(&read(&voxelizer.count, 4))[0];
        let size = count as u64 * std::mem::size_of::<VoxelFragment>() as u64;
        let fragments: Vec<VoxelFragment> =
            bytemuck::cast_slice(&read(&voxelizer.fragments, size)).to_vec();
        let nodes = words(&read(&octree.nodes, octree.tile_capacity as u64 * 32));
        let state = words(&read(&octree.state, 16));
        let (levels, tiles) = walk(&nodes, octree.max_level).expect("a well-formed pool");
        let expected = occupied_cells(&fragments, octree.max_level);
        let leaves = expected.last().unwrap().len();
        eprintln!(
            "octree {name} at {resolution}³: {count} fragments, {leaves} leaves, {} tiles \
             allocated ({} walked), {} bytes of nodes against {} voxels of a dense grid",
            state[0] - 1,
            tiles,
            state[0] as u64 * 32,
            (resolution as u64).pow(3)
        );
        assert_eq!(state[3], 0, "the pool overflowed");
        assert_eq!(
            state[0] as usize - 1,
            tiles,
            "every tile allocated is reached"
        );
        for (level, (got, want)) in levels.iter().zip(&expected).enumerate() {
            assert_eq!(got, want, "{name}: level {level}");
        }
    }
}
