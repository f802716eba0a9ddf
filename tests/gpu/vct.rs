//! The sparse voxel octree's light against its CPU twin (`cssm_runtime::vct::cpu`): the flux
//! injected into the leaves from the RSM read back, every node's MIP-mapped value and every
//! brick texel against a dense pyramid of the same values.

use std::collections::{BTreeMap, BTreeSet};

use cssm_runtime::{
    common::{
        readback::{read_buffer, read_texture},
        timestamps::PassTimer,
        voxelize::VoxelFragment,
    },
    frame::FrameEncoder,
    method::OptionValues,
    vct::{
        SparseVoxels,
        cpu::{self, Pyramid, RsmTexel},
        octree::{FLAG, node_index},
        radiance::BRICK,
    },
};
use glam::{Vec3, Vec4};

use super::{cornell, gpu, rsm::read_rsm, rsm::rsm_renderer};

fn words(bytes: &[u8]) -> Vec<u32> {
    bytemuck::cast_slice(bytes).to_vec()
}

fn close(got: Vec4, want: Vec4, relative: f32) -> bool {
    (got - want)
        .abs()
        .cmple(want.abs() * relative + Vec4::splat(1e-7))
        .all()
}

#[test]
fn voxel_light_matches_cpu_twin() {
    let gpu = gpu();
    let (scene, _) = cornell();
    let renderer = rsm_renderer(scene, &OptionValues::default(), (16, 16), 256);
    let ctx = renderer.context();
    let resolution = 32;
    let voxels = SparseVoxels::new(ctx, scene.bounds(), resolution).expect("voxels");
    let mut timer = PassTimer::new(&gpu.device, &gpu.queue);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    voxels.run(
        ctx,
        &mut FrameEncoder {
            encoder: &mut encoder,
            timer: &mut timer,
            index: 0,
        },
    );
    gpu.queue.submit([encoder.finish()]);
    gpu.wait().expect("the passes run");
    let read = |buffer, size| read_buffer(&gpu.device, &gpu.queue, buffer, 0, size).unwrap();
    let octree = &voxels.octree;
    let count = words(&read(&voxels.voxelizer.count, 4))[0];
    let size = count as u64 * std::mem::size_of::<VoxelFragment>() as u64;
    let fragments: Vec<VoxelFragment> =
        bytemuck::cast_slice(&read(&voxels.voxelizer.fragments, size)).to_vec();
    let node_words = octree.tile_capacity as u64 * 8;
    let nodes = words(&read(&octree.nodes, node_words * 4));
    let state = words(&read(&octree.state, 16));
    assert_eq!(state[3], 0, "the pool overflowed");
    let tile_cells = words(&read(&octree.tile_cells, octree.tile_capacity as u64 * 8));
    let flux = words(&read(&voxels.radiance.flux, node_words * 16));
    let values: Vec<Vec4> =
        bytemuck::cast_slice::<u8, [f32; 4]>(&read(&voxels.radiance.values, node_words * 16))
            .iter()
            .map(|&v| Vec4::from(v))
            .collect();
    let constants: Vec<f32> = bytemuck::cast_slice(&read(&voxels.radiance.constants, 8)).to_vec();
    let max_level = octree.max_level;
    let params = voxels.svo.params;

    // 1. The flux of every RSM texel in its leaf, the same integers.
    let (maps, lights) = read_rsm(&renderer);
    let approx = cpu::flux_constants(&lights, params.voxel);
    assert!(
        (approx[0] / constants[0] - 1.0).abs() < 1e-5,
        "{approx:?} {constants:?}"
    );
    assert!(
        (approx[1] / constants[1] - 1.0).abs() < 1e-5,
        "{approx:?} {constants:?}"
    );
    let occupied: BTreeSet<[u32; 3]> = fragments.iter().map(|f| f.cell()).collect();
    let texels = maps.iter().flat_map(|m| {
        (0..m.position.len()).map(|i| RsmTexel {
            position: m.position[i],
            normal: m.normal[i].truncate(),
            flux: m.flux[i].truncate(),
        })
    });
    let sums = cpu::inject(&params, texels, &occupied, constants[0]);
    let total_rsm: f32 = maps
        .iter()
        .flat_map(|m| m.flux.iter())
        .map(|f| f.x + f.y + f.z)
        .sum();
    let total_units: f64 = sums.values().flatten().map(|&u| u as f64).sum();
    let injected = (total_units / constants[0] as f64) as f32;
    eprintln!(
        "voxel light at {resolution}³: {count} fragments, {} leaves, {} lit, {} tiles; \
         {injected:.4} of {total_rsm:.4} W of RSM flux injected",
        occupied.len(),
        sums.len(),
        state[0]
    );
    assert!(
        (injected / total_rsm - 1.0).abs() < 1e-3,
        "every texel's flux lands in a leaf: {injected} of {total_rsm}"
    );
    let mut leaves = BTreeMap::new();
    for &cell in &occupied {
        let node = node_index(&nodes, cell, max_level, max_level).expect("a leaf per voxel");
        assert_eq!(nodes[node], FLAG);
        let got = [flux[4 * node], flux[4 * node + 1], flux[4 * node + 2]];
        let want = sums.get(&cell).copied().unwrap_or_default();
        assert_eq!(got, want, "flux of leaf {cell:?}");
        leaves.insert(cell, Vec3::from(want.map(|u| u as f32)) * constants[1]);
    }

    // 2. Every occupied node's value against the dense pyramid.
    let pyramid = Pyramid::from_leaves(max_level, &leaves);
    let cells = cssm_runtime::vct::octree::occupied_cells(&fragments, max_level);
    for level in 1..=max_level {
        for &cell in &cells[level as usize] {
            let leaf = cell.map(|c| c << (max_level - level));
            let node = node_index(&nodes, leaf, level, max_level).expect("an occupied node");
            let want = pyramid.cell(level, cell.map(i64::from));
            assert!(
                close(values[node], want, 1e-5),
                "level {level} cell {cell:?}: {} against {want}",
                values[node]
            );
        }
    }

    // 3. Every tile's brick: its parent recorded, its texels the vertices of its level.
    let bricks = &voxels.svo.bricks;
    let texels: Vec<Vec4> = bytemuck::cast_slice::<u8, [u16; 4]>(
        &read_texture(&gpu.device, &gpu.queue, bricks, 8).expect("bricks"),
    )
    .iter()
    .map(|t| Vec4::from(t.map(|bits| half::f16::from_bits(bits).to_f32())))
    .collect();
    let (w, h) = (bricks.width() as usize, bricks.height() as usize);
    let mut checked = 0;
    for level in 0..max_level {
        for &cell in &cells[level as usize] {
            let leaf = cell.map(|c| c << (max_level - level));
            let node = node_index(&nodes, leaf, level, max_level).unwrap();
            let tile = nodes[node] & !FLAG;
            let packed = cell[0] | (cell[1] << 10) | (cell[2] << 20);
            assert_eq!(
                &tile_cells[2 * tile as usize..2 * tile as usize + 2],
                &[packed, level],
                "tile {tile}'s parent"
            );
            let origin = params.brick_origin(tile);
            for t in 0..BRICK.pow(3) {
                let texel = [t % BRICK, (t / BRICK) % BRICK, t / (BRICK * BRICK)];
                let at = [0, 1, 2].map(|k| (origin[k] + texel[k]) as usize);
                let got = texels[at[0] + w * (at[1] + h * at[2])];
                let vertex = [0, 1, 2].map(|k| 4 * cell[k] as i64 + texel[k] as i64);
                let want = pyramid.vertex(level + 1, vertex);
                assert!(
                    close(got, want, 2e-3),
                    "tile {tile} texel {texel:?}: {got} against {want}"
                );
                checked += 1;
            }
        }
    }
    assert_eq!(checked as u32, (state[0] - 1) * BRICK.pow(3));
}
