//! The sparse voxel octree's light against its CPU twin (`cssm_runtime::vct::cpu`): the flux
//! injected into the leaves from the RSM read back, every node's MIP-mapped value and every
//! brick texel against a dense pyramid of the same values.

use std::collections::{BTreeMap, BTreeSet};

use cssm_formats::Scene;
use cssm_runtime::{
    Renderer,
    common::{
        converge::{BouncePlan, added_fraction},
        readback::{read_buffer, read_texture},
        timestamps::PassTimer,
        voxelize::VoxelFragment,
    },
    frame::FrameEncoder,
    gpu_types::GpuMaterial,
    method::OptionValues,
    vct::{
        SparseVoxels,
        cpu::{self, Pyramid, Receiver, RsmTexel},
        octree::{FLAG, node_index},
        radiance::BRICK,
        trace::{ConeProbe, ConeTrace, Probe, TraceParams},
    },
};
use glam::{Vec3, Vec4};

use cssm_raycast::SplitMix64;

use super::{cornell, gpu, rsm::read_rsm, rsm::rsm_renderer};

/// The diffuse cones of the bounces in these tests: few and wide, to keep the twin quick.
fn bounce_cones() -> TraceParams {
    TraceParams::new(6, 20f32.to_radians(), 2.0)
}

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
    for anisotropic in [false, true] {
        voxel_light(anisotropic);
    }
}

fn voxel_light(anisotropic: bool) {
    let gpu = gpu();
    let (scene, _) = cornell();
    let resolution = 32;
    let (renderer, voxels) = voxelised(scene, (16, 16), anisotropic, true, 1);
    let faces = voxels.svo.params.faces;
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
    let values: Vec<Vec4> = bytemuck::cast_slice::<u8, [f32; 4]>(&read(
        &voxels.radiance.values,
        node_words * 16 * faces as u64,
    ))
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
    let texels = maps.iter().zip(&lights).flat_map(|(m, light)| {
        (0..m.position.len()).map(|i| RsmTexel {
            position: m.position[i],
            normal: m.normal[i].truncate(),
            flux: m.flux[i].truncate(),
            area: cpu::texel_area(light, m.position[i].truncate(), m.normal[i].truncate()),
        })
    });
    let sums = cpu::inject(&params, texels, &occupied, constants[0]);
    let total_rsm: f32 = maps
        .iter()
        .flat_map(|m| m.flux.iter())
        .map(|f| f.x + f.y + f.z)
        .sum();
    let total_units: f64 = sums.values().flat_map(|s| &s[..3]).map(|&u| u as f64).sum();
    let injected = (total_units / constants[0] as f64) as f32;
    eprintln!(
        "voxel light at {resolution}³ ({faces} faces): {count} fragments, {} leaves, {} lit, {} tiles; \
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
        let got: [u32; 4] = flux[4 * node..4 * node + 4].try_into().unwrap();
        let want = sums.get(&cell).copied().unwrap_or_default();
        assert_eq!(got[..3], want[..3], "flux of leaf {cell:?}");
        // The area's arithmetic (a square root, a division) may differ in the last bits.
        let area_off = (got[3] as f64 - want[3] as f64).abs() / (want[3] as f64).max(1.0);
        assert!(
            area_off < 1e-4,
            "area of leaf {cell:?}: {} against {}",
            got[3],
            want[3]
        );
        leaves.insert(cell, cpu::leaf_radiance(got, constants[1]));
    }

    // 2. Every occupied node's value against the dense pyramid.
    let pyramid = Pyramid::from_leaves(max_level, faces, &leaves);
    let cells = cssm_runtime::vct::octree::occupied_cells(&fragments, max_level);
    for level in 1..=max_level {
        for &cell in &cells[level as usize] {
            let leaf = cell.map(|c| c << (max_level - level));
            let node = node_index(&nodes, leaf, level, max_level).expect("an occupied node");
            for face in 0..faces {
                let got = values[node * faces as usize + face as usize];
                let want = pyramid.cell(level, cell.map(i64::from), face);
                assert!(
                    close(got, want, 1e-5),
                    "level {level} cell {cell:?} face {face}: {got} against {want}"
                );
            }
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
    let levels = words(&read(&octree.levels, (max_level as u64 + 1) * 8));
    let first_leaf_tile = levels[2 * max_level as usize] / 8;
    let mut checked = 0;
    let mut bricks_seen = BTreeSet::new();
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
            // A tile of leaves has one brick, the leaves the same from every side.
            let tile_faces = if level + 1 == max_level { 1 } else { faces };
            for face in 0..tile_faces {
                let brick = params
                    .brick(tile, face, level + 1, first_leaf_tile)
                    .expect("the pool holds every brick");
                assert!(bricks_seen.insert(brick), "brick {brick} twice");
                let origin = params.brick_origin(brick);
                for t in 0..BRICK.pow(3) {
                    let texel = [t % BRICK, (t / BRICK) % BRICK, t / (BRICK * BRICK)];
                    let at = [0, 1, 2].map(|k| (origin[k] + texel[k]) as usize);
                    let got = texels[at[0] + w * (at[1] + h * at[2])];
                    let vertex = [0, 1, 2].map(|k| 4 * cell[k] as i64 + texel[k] as i64);
                    let want = pyramid.vertex(level + 1, vertex, face);
                    assert!(
                        close(got, want, 2e-3),
                        "tile {tile} face {face} texel {texel:?}: {got} against {want}"
                    );
                    checked += 1;
                }
            }
        }
    }
    let leaf_tiles = cells[max_level as usize - 1].len() as u32;
    let inner_tiles = state[0] - 1 - leaf_tiles;
    assert_eq!(
        first_leaf_tile,
        1 + inner_tiles,
        "the leaves' tiles come last"
    );
    assert_eq!(
        checked as u32,
        (inner_tiles * faces + leaf_tiles) * BRICK.pow(3)
    );
    let (nodes_bytes, bricks_bytes, values_bytes) = voxels.svo.pool_bytes(octree);
    let dense = (resolution as u64).pow(3) * 8 * 8 / 7 * faces as u64;
    eprintln!(
        "  pools: nodes {nodes_bytes} B, bricks {bricks_bytes} B, values {values_bytes} B; a \
         dense mipmapped grid of rgba16f ({faces} faces) {dense} B"
    );
}

/// A renderer of `rsm` on `scene` at `size` (its G-buffer and RSM drawn) and the scene's
/// sparse voxel octree at 32³, built for `bounces` bounces with [`bounce_cones`], its cones' opacity
/// `correct`ed or not.
fn voxelised(
    scene: &Scene,
    size: (u32, u32),
    anisotropic: bool,
    correct: bool,
    bounces: u32,
) -> (Renderer, SparseVoxels) {
    // The bounces into the leaves: the cones' own is the last.
    let plan = BouncePlan::exactly(bounces.saturating_sub(1));
    voxelised_with(scene, size, anisotropic, correct, plan)
}

/// [`voxelised`] with the bounces into the leaves of `plan`.
fn voxelised_with(
    scene: &Scene,
    size: (u32, u32),
    anisotropic: bool,
    correct: bool,
    plan: BouncePlan,
) -> (Renderer, SparseVoxels) {
    let gpu = gpu();
    let renderer = rsm_renderer(scene, &OptionValues::default(), size, 256);
    let ctx = renderer.context();
    let voxels = SparseVoxels::new(
        ctx,
        scene.bounds(),
        32,
        anisotropic,
        correct,
        &bounce_cones(),
        plan,
    )
    .expect("voxels");
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
    (renderer, voxels)
}

/// The dense pyramid of the octree's leaves as the GPU has them (`voxel_light_matches_cpu_twin`
/// holds them to the twin's injection).
fn gpu_pyramid(voxels: &SparseVoxels) -> Pyramid {
    let gpu = gpu();
    let read = |buffer, size| read_buffer(&gpu.device, &gpu.queue, buffer, 0, size).unwrap();
    let octree = &voxels.octree;
    let max_level = octree.max_level;
    let node_words = octree.tile_capacity as u64 * 8;
    let nodes = words(&read(&octree.nodes, node_words * 4));
    let flux = words(&read(&voxels.radiance.flux, node_words * 16));
    let constants: Vec<f32> = bytemuck::cast_slice(&read(&voxels.radiance.constants, 8)).to_vec();
    let side = 1u32 << max_level;
    let mut leaves = BTreeMap::new();
    for z in 0..side {
        for y in 0..side {
            for x in 0..side {
                if let Some(node) = node_index(&nodes, [x, y, z], max_level, max_level) {
                    let sums: [u32; 4] = flux[4 * node..4 * node + 4].try_into().unwrap();
                    leaves.insert([x, y, z], cpu::leaf_radiance(sums, constants[1]));
                }
            }
        }
    }
    Pyramid::from_leaves(max_level, voxels.svo.params.faces, &leaves)
}

/// Cones through the Cornell box's octree on the GPU against the same cones through the dense
/// pyramid of the GPU's leaves: radiance and opacity, narrow to wide, from points inside the
/// box in every direction.
#[test]
fn cones_match_cpu_twin() {
    for (anisotropic, correct) in [(false, true), (true, false), (true, true)] {
        cones(anisotropic, correct);
    }
}

fn cones(anisotropic: bool, correct: bool) {
    let gpu = gpu();
    let (scene, _) = cornell();
    let (_renderer, voxels) = voxelised(scene, (16, 16), anisotropic, correct, 1);
    let pyramid = gpu_pyramid(&voxels);
    let mut rng = SplitMix64(18);
    let mut unit = || rng.next_f64() as f32;
    let probes: Vec<Probe> = (0..96)
        .map(|i| {
            let origin = Vec3::new(4.0, 4.0, 4.0) + Vec3::new(unit(), unit(), unit()) * 24.0;
            let dir = Vec3::new(unit(), unit(), unit()) * 2.0 - 1.0;
            let tan_half = [0.02, 0.15, 0.577, 1.2][i % 4];
            Probe::new(origin, dir, tan_half, 1.0)
        })
        .collect();
    let probe = ConeProbe::new(&gpu.device, &voxels.svo);
    let got = probe
        .trace(&gpu.device, &gpu.queue, &voxels.svo, &probes)
        .expect("probes");
    let want: Vec<Vec4> = probes
        .iter()
        .map(|p| {
            let (o, d) = (Vec3::from(p.origin), Vec3::from(p.dir));
            cpu::trace_cone(&pyramid, o, d, p.tan_half, p.start, correct)
        })
        .collect();
    let peak = want.iter().map(|w| w.max_element()).fold(0.0f32, f32::max);
    let lit = want
        .iter()
        .filter(|w| w.truncate().max_element() > 0.0)
        .count();
    assert!(lit > probes.len() / 2, "most cones see light: {lit}");
    let mut worst = 0.0f32;
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        let off = (*g - *w).abs();
        let radiance = off.truncate().max_element() / (w.truncate().max_element() + 0.01 * peak);
        worst = worst.max(radiance);
        assert!(
            radiance < 0.02 && off.w < 0.01,
            "cone {i} ({:?}): GPU {g} against CPU {w}",
            probes[i]
        );
    }
    eprintln!(
        "{} cones at 32³ ({} faces, opacity corrected {correct}): worst radiance off by \
         {worst:.2e}",
        probes.len(),
        pyramid.faces
    );
}

/// The per-pixel pass on the glossy Cornell box (diffuse cones and the mirror cone of the
/// glossy floor) at every pixel and, the spiral turned per pixel, at every other pixel per side,
/// against `cpu::trace_planes` on the G-buffer read back; and its ambient occlusion view against
/// `cpu::occlusion_view`.
#[test]
fn cone_tracing_matches_cpu_twin() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-glossy");
    let scene = Scene::load(&dir).expect("scene");
    let size = (24, 18);
    let (renderer, voxels) = voxelised(&scene, size, true, false, 1);
    let trace = TraceParams::new(12, 10f32.to_radians(), 2.0);
    for (occlusion_radius, factor, turn) in [(0.0, 1, 0), (0.0, 2, 1), (8.0, 1, 0)] {
        let params = TraceParams {
            occlusion_radius,
            factor,
            turn,
            ..trace
        };
        trace_pixels(&scene, &renderer, &voxels, size, params);
    }
}

fn trace_pixels(
    scene: &Scene,
    renderer: &Renderer,
    voxels: &SparseVoxels,
    size: (u32, u32),
    trace: TraceParams,
) {
    let gpu = gpu();
    let ctx = renderer.context();
    let low = cssm::runtime::common::filters::low_size(size, trace.factor);
    let low_pixels = u64::from(low.0 * low.1);
    let planes = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("vct planes"),
        size: 2 * 16 * low_pixels,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let pass = ConeTrace::new(ctx, &voxels.svo, trace, &planes);
    let mut timer = PassTimer::new(&gpu.device, &gpu.queue);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    pass.run(
        &mut FrameEncoder {
            encoder: &mut encoder,
            timer: &mut timer,
            index: 0,
        },
        &voxels.svo,
    );
    gpu.queue.submit([encoder.finish()]);
    gpu.wait().expect("the pass runs");
    let pixels = (size.0 * size.1) as u64;
    let vec4s = |bytes: Vec<u8>| -> Vec<Vec4> {
        bytemuck::cast_slice::<u8, [f32; 4]>(&bytes)
            .iter()
            .map(|&v| Vec4::from(v))
            .collect()
    };
    let occlusion_view = trace.occlusion_radius > 0.0;
    let got = if occlusion_view {
        vec4s(read_buffer(&gpu.device, &gpu.queue, &pass.occlusion, 0, 16 * pixels).unwrap())
    } else {
        vec4s(read_buffer(&gpu.device, &gpu.queue, &planes, 0, 2 * 16 * low_pixels).unwrap())
    };
    let texture = |t| vec4s(read_texture(&gpu.device, &gpu.queue, t, 16).unwrap());
    let (position, normal, albedo) = (
        texture(&ctx.gbuffer.position),
        texture(&ctx.gbuffer.normal),
        texture(&ctx.gbuffer.albedo),
    );
    let material_bytes = std::mem::size_of::<GpuMaterial>() as u64 * scene.materials.len() as u64;
    let materials: Vec<GpuMaterial> = bytemuck::cast_slice(
        &read_buffer(
            &gpu.device,
            &gpu.queue,
            &ctx.scene.materials,
            0,
            material_bytes,
        )
        .unwrap(),
    )
    .to_vec();
    let pyramid = gpu_pyramid(voxels);
    let mut want = vec![Vec3::ZERO; got.len()];
    let mut glossy = 0;
    for (l, (lx, ly)) in (0..low.1)
        .flat_map(|y| (0..low.0).map(move |x| (x, y)))
        .enumerate()
    {
        let pixel = cssm::runtime::common::filters::representative((lx, ly), trace.factor, size);
        let i = (pixel.1 * size.0 + pixel.0) as usize;
        if position[i].w <= 0.0 {
            continue;
        }
        let m = materials[normal[i].w as usize];
        glossy += usize::from(m.ks.iter().any(|&k| k > 0.0));
        let receiver = Receiver {
            position: position[i].truncate(),
            normal: normal[i].truncate(),
            albedo: albedo[i].truncate(),
            ks: Vec3::from(m.ks),
            ns: m.ns,
            eye: ctx.camera.eye,
        };
        if occlusion_view {
            want[l] = Vec3::splat(cpu::occlusion_view(
                &pyramid,
                &voxels.svo.params,
                &trace,
                &receiver,
            ));
        } else {
            let [d, g] = cpu::trace_planes(&pyramid, &voxels.svo.params, &trace, &receiver, pixel);
            want[l] = d;
            want[low_pixels as usize + l] = g;
        }
    }
    assert!(glossy > 0, "the glossy floor is in view");
    let view = match (occlusion_view, trace.factor, trace.turn) {
        (true, ..) => "ambient occlusion".to_string(),
        (false, f, t) => format!("indirect, 1/{f}, turned {t}"),
    };
    let peak = want.iter().map(|w| w.max_element()).fold(0.0f32, f32::max);
    let least = want
        .iter()
        .map(|w| w.min_element())
        .fold(f32::MAX, f32::min);
    assert!(
        peak > 0.0 && least < 0.9 * peak,
        "{view}: the image varies ({least} to {peak})"
    );
    let mut worst = 0.0f32;
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        let off = (g.truncate() - *w).abs().max_element() / (w.max_element() + 0.01 * peak);
        worst = worst.max(off);
        assert!(off < 0.02, "{view}, pixel {i}: GPU {g} against CPU {w}");
    }
    eprintln!(
        "cone tracing {}x{} ({view}): {glossy} glossy pixels, values {least:.3} to {peak:.3}, \
         worst off by {worst:.2e}",
        low.0, low.1
    );
}

/// A second bounce on the Cornell box at 32³: every leaf's fragments summed into its surface
/// as the twin sums them, and the leaves' radiance after the bounce (their direct light plus
/// their albedo times what their cones gather through the first bounce's bricks) against
/// `cpu::bounce` over the dense pyramid of the GPU's direct light.
#[test]
fn second_bounce_matches_cpu_twin() {
    let gpu = gpu();
    let (scene, _) = cornell();
    let (_renderer, voxels) = voxelised(scene, (16, 16), true, false, 2);
    let read = |buffer, size| read_buffer(&gpu.device, &gpu.queue, buffer, 0, size).unwrap();
    let octree = &voxels.octree;
    let max_level = octree.max_level;
    let node_words = octree.tile_capacity as u64 * 8;
    let nodes = words(&read(&octree.nodes, node_words * 4));
    let count = words(&read(&voxels.voxelizer.count, 4))[0];
    let size = count as u64 * std::mem::size_of::<VoxelFragment>() as u64;
    let fragments: Vec<VoxelFragment> =
        bytemuck::cast_slice(&read(&voxels.voxelizer.fragments, size)).to_vec();
    let surface = words(&read(&voxels.radiance.surface, node_words * 32));
    let faces = voxels.svo.params.faces as usize;
    let values: Vec<Vec4> = bytemuck::cast_slice::<u8, [f32; 4]>(&read(
        &voxels.radiance.values,
        node_words * 16 * faces as u64,
    ))
    .iter()
    .map(|&v| Vec4::from(v))
    .collect();
    // The first bounce's pyramid: the leaves' direct light (the flux is unchanged).
    let first = gpu_pyramid(&voxels);
    let side = 1usize << max_level;
    let direct: BTreeMap<[u32; 3], Vec3> = first.levels[max_level as usize]
        .chunks(faces)
        .enumerate()
        .filter(|(_, v)| v[0].w > 0.0)
        .map(|(i, v)| {
            let cell = [i % side, (i / side) % side, i / (side * side)].map(|c| c as u32);
            (cell, v[0].truncate())
        })
        .collect();
    let sums = cpu::surface_sums(&fragments);
    // A sample of the leaves keeps the twin quick in a debug build.
    let sample: BTreeMap<[u32; 3], Vec3> =
        direct.iter().step_by(5).map(|(c, v)| (*c, *v)).collect();
    let want = cpu::bounce(&first, &sample, &sums, &bounce_cones(), false);
    let peak = want
        .values()
        .map(|w| w.max_element())
        .fold(0.0f32, f32::max);
    let (mut worst, mut brighter) = (0.0f32, 0);
    for (cell, w) in &want {
        let node = node_index(&nodes, *cell, max_level, max_level).expect("a leaf");
        assert_eq!(
            &surface[8 * node..8 * node + 7],
            &sums[cell][..7],
            "surface of leaf {cell:?}"
        );
        let got = values[node * faces];
        for face in 0..faces {
            assert_eq!(
                values[node * faces + face],
                got,
                "a leaf is the same from every side"
            );
        }
        brighter += usize::from(w.max_element() > direct[cell].max_element());
        let off = (got.truncate() - *w).abs().max_element() / (w.max_element() + 0.01 * peak);
        worst = worst.max(off);
        assert!(off < 0.02, "leaf {cell:?}: GPU {got} against CPU {w}");
    }
    assert!(
        brighter > want.len() / 2,
        "the bounce adds light: {brighter} of {}",
        want.len()
    );
    eprintln!(
        "second bounce at 32³: {} leaves checked, {brighter} brighter, worst off by {worst:.2e}",
        want.len()
    );
}

/// The bounces into the leaves stop where the rule says, on the light of the octree's first
/// level (nodes 8 to 15, the root's children): exact runs of 1, 2 and 3 bounces measure each
/// bounce's share of the light; a converging run whose fraction lies between the second's and
/// the first's stops after the second, its later bounce dispatched with no workgroups, and its
/// voxels hold the light of the exact run of 2.
#[test]
fn vct_bounces_stop_once_converged() {
    let gpu = gpu();
    let (scene, _) = cornell();
    let values = |voxels: &SparseVoxels| -> Vec<Vec4> {
        let words = voxels.octree.tile_capacity as u64 * 8 * 16 * voxels.svo.params.faces as u64;
        let raw = read_buffer(&gpu.device, &gpu.queue, &voxels.radiance.values, 0, words).unwrap();
        bytemuck::cast_slice::<u8, [f32; 4]>(&raw)
            .iter()
            .map(|&v| Vec4::from(v))
            .collect()
    };
    let light = |values: &[Vec4], faces: usize| -> Vec3 {
        values[8 * faces..16 * faces]
            .iter()
            .fold(Vec3::ZERO, |sum, v| sum + v.truncate())
    };
    let exact: Vec<Vec<Vec4>> = (0..=3)
        .map(|k| values(&voxelised_with(scene, (16, 16), false, false, BouncePlan::exactly(k)).1))
        .collect();
    let lights: Vec<Vec3> = exact.iter().map(|v| light(v, 1)).collect();
    let shares: Vec<f32> = (1..=3)
        .map(|k| added_fraction(lights[k - 1], lights[k]))
        .collect();
    eprintln!("vct: each bounce's share of the first level's light {shares:?}");
    assert!(shares[1] < shares[0] && shares[1] > 0.0, "{shares:?}");
    let plan = BouncePlan {
        max: 3,
        fraction: 0.5 * (shares[0] + shares[1]),
    };
    let (_renderer, converging) = voxelised_with(scene, (16, 16), false, false, plan);
    let ended = converging
        .radiance
        .convergence(&gpu.device, &gpu.queue)
        .unwrap();
    assert_eq!((ended.bounces, ended.converged), (2, true), "{ended}");
    assert!((ended.added - shares[1]).abs() < 1e-4, "{ended} {shares:?}");
    // The octree's tiles are allocated in whatever order the GPU's threads take them, so the
    // same voxels sit at other nodes (and their bricks elsewhere) from run to run: compared by
    // the first level's light and the sum over every node, where a third bounce would add 2.7%.
    let kept = values(&converging);
    let total = |v: &[Vec4]| v.iter().fold(Vec3::ZERO, |sum, x| sum + x.truncate());
    for (got, want) in [
        (light(&kept, 1), lights[2]),
        (total(&kept), total(&exact[2])),
    ] {
        assert!(
            (got - want).abs().max_element() <= 1e-4 * want.max_element(),
            "the solution of 2 bounces is kept: {got} against {want}"
        );
    }
}
