//! Visibility filtering's pieces against their CPU twins: the shared GPU radix sort
//! (`cssm_runtime::common::sort`) against a stable sort, and the point proxies' voxel keys,
//! sort and cell ranges (`cssm_runtime::vf::proxies`).

use cssm_runtime::{
    common::{
        readback::read_buffer,
        sort::{KeySort, KeyValue, key_bits, sort_cpu},
        timestamps::PassTimer,
    },
    frame::FrameEncoder,
    vf::{
        filter::{FilterShape, VisibilityFilter, filter_cpu, unpack_lists},
        gather::{GatherInputs, GatherShape, Gathering, gather_cpu},
        light::{ProxyLight, SH_STRIDE, Vpl, voxel_sh_cpu, vpl_cpu},
        march::{MarchInputs, NO_VOXEL, RayShape, SparseRays, march_cpu},
        proxies::{ProxyGrid, cells_cpu, hash_cpu, place_proxies},
    },
};
use glam::Mat4;
use wgpu::util::DeviceExt;

use super::{cornell, gpu};

pub(super) fn read<T: bytemuck::Pod>(buffer: &wgpu::Buffer) -> Vec<T> {
    let gpu = gpu();
    let bytes = read_buffer(&gpu.device, &gpu.queue, buffer, 0, buffer.size()).expect("read");
    bytemuck::cast_slice(&bytes).to_vec()
}

/// Records what `record` records into one encoder and submits it.
fn submit(record: impl FnOnce(&mut FrameEncoder)) {
    let gpu = gpu();
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    let mut timer = PassTimer::new(&gpu.device, &gpu.queue);
    record(&mut FrameEncoder {
        encoder: &mut encoder,
        timer: &mut timer,
        index: 0,
    });
    gpu.queue.submit([encoder.finish()]);
}

/// The Cornell box's 4,096 proxies in a 6³ grid, hashed, sorted and lit over a context of
/// `size` (its shadow maps light them).
pub(super) struct LitProxies {
    pub(super) renderer: cssm_runtime::Renderer,
    pub(super) proxies: Vec<cssm_runtime::vf::proxies::Proxy>,
    pub(super) grid: ProxyGrid,
    pub(super) light: ProxyLight,
}

/// 8 rays per pixel of the G-buffer reduced `factor` times, discs `disc_scale` times their
/// share.
fn ray_shape(scene: &cssm_formats::Scene, factor: u32, disc_scale: f32) -> RayShape {
    RayShape {
        factor,
        rays: 8,
        offset: 1e-3 * (scene.bounds().1 - scene.bounds().0).length(),
        disc_scale,
    }
}

/// The context's G-buffer position and normal rows.
fn gbuffer_rows(ctx: &cssm_runtime::frame::FrameContext) -> (Vec<glam::Vec4>, Vec<glam::Vec4>) {
    let gpu = gpu();
    let texture = |t| {
        let bytes = cssm_runtime::common::readback::read_texture(&gpu.device, &gpu.queue, t, 16)
            .expect("read");
        bytemuck::cast_slice::<u8, glam::Vec4>(&bytes).to_vec()
    };
    (texture(&ctx.gbuffer.position), texture(&ctx.gbuffer.normal))
}

fn lit_proxies(size: (u32, u32)) -> LitProxies {
    lit_proxies_in(&cornell().0, 4096, 6, size)
}

/// `count` proxies of `scene` in a grid of `resolution`, hashed, sorted and lit over a context
/// of `size`.
pub(super) fn lit_proxies_in(
    scene: &cssm_formats::Scene,
    count: u32,
    resolution: u32,
    size: (u32, u32),
) -> LitProxies {
    let gpu = gpu();
    let proxies = place_proxies(scene, count).expect("proxies");
    let renderer = super::ssil::context_renderer(scene, size);
    let ctx = renderer.context();
    let mut grid = ProxyGrid::new(
        &gpu.device,
        &gpu.queue,
        &proxies,
        scene.bounds(),
        resolution,
        &ctx.scene.motion,
    )
    .expect("grid");
    let light = ProxyLight::new(ctx, &grid);
    submit(|frame| {
        grid.run(frame).expect("grid");
        light.run(frame);
    });
    LitProxies {
        renderer,
        proxies,
        grid,
        light,
    }
}

/// 100,000 pairs with many equal keys, sorted on the GPU, equal to the stable sort.
#[test]
fn gpu_sort_matches_a_stable_sort() {
    let gpu = gpu();
    let mut rng = cssm_raycast::SplitMix64(7);
    let bound = 5000;
    let pairs: Vec<KeyValue> = (0..100_000)
        .map(|i| KeyValue::new((rng.next_u64() % u64::from(bound)) as u32, i))
        .collect();
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
    let input = gpu
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("pairs"),
            contents: bytemuck::cast_slice(&pairs),
            usage,
        });
    let output = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("sorted"),
        size: input.size(),
        usage,
        mapped_at_creation: false,
    });
    let mut sort = KeySort::new(&gpu.device, &gpu.queue);
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    sort.record(
        &mut encoder,
        &input,
        &output,
        pairs.len() as u32,
        key_bits(bound),
    )
    .expect("sort");
    gpu.queue.submit([encoder.finish()]);
    assert_eq!(read::<KeyValue>(&output), sort_cpu(&pairs));
}

/// The Cornell box's proxies hashed, sorted and indexed on the GPU, equal to the twins.
#[test]
fn proxy_grid_matches_cpu_twins() {
    let (scene, _) = cornell();
    let LitProxies { proxies, grid, .. } = lit_proxies((16, 12));
    let motion = vec![Mat4::IDENTITY; scene.objects.len()];
    let pairs = hash_cpu(&proxies, &motion, &grid.grid);
    assert_eq!(read::<KeyValue>(&grid.pairs), pairs);
    let sorted = sort_cpu(&pairs);
    assert_eq!(read::<KeyValue>(&grid.sorted), sorted);
    let cells = cells_cpu(&sorted, grid.grid.cells());
    assert_eq!(read::<[u32; 2]>(&grid.cells), cells);
    // The box's walls fill the border cells of its 6x6x6 grid; the air inside holds none.
    let occupied = cells.iter().filter(|c| c[1] > c[0]).count();
    assert!(
        occupied > 100 && occupied < 216,
        "{occupied} of 216 cells hold proxies"
    );
}

/// The Cornell box's proxies lit as VPLs through the shadow map against exact shadow rays
/// (a proxy on a shadow's edge may fall either side), and every voxel's harmonics and centroid
/// against the twin over the GPU's own VPLs.
#[test]
fn vpl_light_and_voxel_sh_match_cpu_twins() {
    let (scene, _) = cornell();
    let LitProxies {
        proxies,
        grid,
        light,
        ..
    } = lit_proxies((16, 12));
    let [p, n, f] = [&light.position, &light.normal, &light.flux].map(read::<[f32; 4]>);
    let gpu_vpls: Vec<Vpl> = (0..p.len())
        .map(|i| Vpl {
            position: p[i].into(),
            normal: n[i].into(),
            flux: f[i].into(),
        })
        .collect();
    let (materials, textures) = cssm_runtime::load::cpu_materials(scene).expect("materials");
    let bvh = cssm_raycast::SceneBvh::new(scene);
    let motion = vec![Mat4::IDENTITY; scene.objects.len()];
    let cpu_vpls = vpl_cpu(scene, &bvh, &materials, &textures, &proxies, &motion);
    let (mut lit, mut off) = (0, 0);
    for (g, c) in gpu_vpls.iter().zip(&cpu_vpls) {
        assert!(
            (g.position - c.position).abs().max_element() < 1e-3,
            "{g:?} {c:?}"
        );
        lit += usize::from(c.flux.max_element() > 0.0);
        let near = (g.flux - c.flux).abs().max_element() <= 1e-3 * c.flux.max_element().max(1e-6);
        if !near || g.normal != c.normal {
            off += 1;
        }
    }
    assert!(
        lit * 4 > cpu_vpls.len(),
        "{lit} of {} proxies lit",
        cpu_vpls.len()
    );
    // The shadow map (512², filtered over its texels) softens the shadows' edges, which exact
    // rays keep hard: 8% of the proxies (on the floor around the blocks' shadows and along
    // the walls' feet) differ by more than 1e-3 there; the light in all agrees within 1%.
    assert!(
        off * 10 <= cpu_vpls.len(),
        "{off} of {} VPLs differ from exact shadow rays",
        cpu_vpls.len()
    );
    let total = |v: &[Vpl]| v.iter().map(|v| f64::from(v.flux.x)).sum::<f64>();
    let ratio = total(&gpu_vpls) / total(&cpu_vpls);
    eprintln!("VPL flux, shadow map / exact rays: {ratio:.4}; {off} VPLs differ");
    assert!(
        (ratio - 1.0).abs() < 0.03,
        "the VPLs' flux in all: {ratio} of the exact"
    );
    let sorted = read::<[u32; 2]>(&grid.sorted);
    let ranges = read::<[u32; 2]>(&grid.cells);
    let cpu_sh = voxel_sh_cpu(&gpu_vpls, &sorted, &ranges);
    let gpu_sh = read::<[f32; 4]>(&light.voxel_sh);
    assert_eq!(gpu_sh.len(), cpu_sh.len());
    for (i, (g, c)) in gpu_sh.iter().zip(&cpu_sh).enumerate() {
        let g = glam::Vec4::from(*g);
        assert!(
            (g - *c).abs().max_element() <= 1e-4 * c.abs().max_element().max(1e-3),
            "voxel {} entry {}: {g} against {c}",
            i / SH_STRIDE,
            i % SH_STRIDE
        );
    }
}

/// Every shadow ray of every reduced pixel of the Cornell box against `march_cpu` over the
/// GPU's own discs and ranges.
#[test]
fn shadow_rays_match_cpu_twin() {
    let (scene, _) = cornell();
    let LitProxies {
        renderer,
        grid,
        light,
        ..
    } = lit_proxies((32, 24));
    let ctx = renderer.context();
    let rays = SparseRays::new(ctx, &grid, &light, ray_shape(scene, 2, 1.0));
    submit(|frame| rays.run(frame));
    let [position, normal] = [&light.position, &light.normal].map(read::<glam::Vec4>);
    let sorted = read::<[u32; 2]>(&grid.sorted);
    let ranges = read::<[u32; 2]>(&grid.cells);
    let inputs = MarchInputs {
        grid: grid.grid,
        position: &position,
        normal: &normal,
        sorted: &sorted,
        ranges: &ranges,
    };
    let (gb_position, gb_normal) = gbuffer_rows(ctx);
    let visible = read::<u32>(&rays.visible);
    let params = rays.params;
    let (lw, lh) = (params.low_size[0], params.low_size[1]);
    let (mut off, mut hits) = (0, 0);
    for y in 0..lh {
        for x in 0..lw {
            let (fx, fy) = cssm_runtime::common::filters::representative((x, y), 2, ctx.size());
            let i = (fy * ctx.size().0 + fx) as usize;
            let cpu = march_cpu(
                &inputs,
                &params,
                glam::UVec2::new(x, y),
                gb_position[i],
                gb_normal[i].truncate(),
            );
            let base = ((y * lw + x) * params.rays) as usize;
            for (k, &c) in cpu.iter().enumerate() {
                hits += usize::from(c != NO_VOXEL);
                off += usize::from(visible[base + k] != c);
            }
        }
    }
    let total = (lw * lh * params.rays) as usize;
    // A ray that grazes a disc's rim or a voxel's face may go either way in the last bit.
    assert!(
        off * 100 <= total,
        "{off} of {total} rays differ from the twin"
    );
    // Discs of each proxy's share of the area leave gaps between them (and rays leave
    // through the box's open front): a third of the rays hit a disc at 4,096 proxies.
    assert!(hits * 4 > total, "{hits} of {total} rays hit a disc");
}

/// The shadow rays' lists filtered 7x7 on the GPU against `filter_cpu` over the GPU's own
/// rays, and a filtered list holding at least its own rays' voxels.
#[test]
fn visibility_filter_matches_cpu_twin() {
    let (scene, _) = cornell();
    let LitProxies {
        renderer,
        grid,
        light,
        ..
    } = lit_proxies((64, 48));
    let ctx = renderer.context();
    let rays = SparseRays::new(ctx, &grid, &light, ray_shape(scene, 4, 1.5));
    let shape = FilterShape {
        radius: 3,
        depth: 0.1,
        normal: 0.9,
    };
    let filter = VisibilityFilter::new(ctx, &rays, grid.grid.cells(), &shape).expect("filter");
    submit(|frame| {
        rays.run(frame);
        filter.run(frame);
    });
    let (position, normal) = gbuffer_rows(ctx);
    let visible = read::<u32>(&rays.visible);
    let gpu_lists = unpack_lists(&filter.params, &read::<u32>(&filter.lists));
    let eye = ctx.camera.eye;
    let cpu_lists = filter_cpu(&filter.params, &visible, &position, &normal, eye);
    assert_eq!(gpu_lists.len(), cpu_lists.len());
    let differ = gpu_lists
        .iter()
        .zip(&cpu_lists)
        .filter(|(g, c)| g != c)
        .count();
    // A neighbour right at a depth or normal threshold may go either way in the last bit.
    assert!(
        differ * 100 <= cpu_lists.len(),
        "{differ} of {} lists differ from the twin",
        cpu_lists.len()
    );
    let rays_per = filter.params.rays as usize;
    let (mut own, mut filtered) = (0usize, 0usize);
    for (i, list) in gpu_lists.iter().enumerate() {
        let mine: std::collections::BTreeSet<u32> = visible[i * rays_per..(i + 1) * rays_per]
            .iter()
            .copied()
            .filter(|&k| k != NO_VOXEL)
            .collect();
        assert!(
            mine.iter().all(|k| list.binary_search(k).is_ok()),
            "pixel {i}"
        );
        own += mine.len();
        filtered += list.len();
    }
    eprintln!("voxels per list: {own} own, {filtered} filtered");
    assert!(filtered > own, "the filter adds the neighbours' voxels");
}

/// Every gathering pixel of the Cornell box against `gather_cpu` over the GPU's own lists,
/// VPLs and harmonics, with VPLs near and harmonics far (R of one voxel), and Eq. 7's weight.
#[test]
fn gathering_matches_cpu_twin() {
    let gpu = gpu();
    let (scene, _) = cornell();
    let LitProxies {
        renderer,
        grid,
        light,
        ..
    } = lit_proxies((32, 24));
    let ctx = renderer.context();
    let rays = SparseRays::new(ctx, &grid, &light, ray_shape(scene, 4, 1.5));
    let shape = FilterShape {
        radius: 1,
        depth: 0.1,
        normal: 0.9,
    };
    let filter = VisibilityFilter::new(ctx, &rays, grid.grid.cells(), &shape).expect("filter");
    let (materials, _) = cssm_runtime::load::cpu_materials(scene).expect("materials");
    let ns: Vec<f32> = materials.iter().map(|m| m.ns).collect();
    let (position, normal) = gbuffer_rows(ctx);
    for sigma in [0.0, 0.5] {
        let gather = GatherShape {
            factor: 2,
            range: grid.grid.cell,
            depth_sigma: 0.1,
            normal_power: 8.0,
            sigma,
        };
        let size = cssm_runtime::common::filters::low_size(ctx.size(), 2);
        let planes = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("planes"),
            size: 2 * 16 * u64::from(size.0 * size.1),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let gathering = Gathering::new(ctx, (&grid, &light), (&rays, &filter), &gather, &planes);
        submit(|frame| {
            rays.run(frame);
            filter.run(frame);
            gathering.run(frame);
        });
        let lists = unpack_lists(&filter.params, &read::<u32>(&filter.lists));
        let [p, n, f] = [&light.position, &light.normal, &light.flux].map(read::<glam::Vec4>);
        let sorted = read::<[u32; 2]>(&grid.sorted);
        let ranges = read::<[u32; 2]>(&grid.cells);
        let voxel_sh = read::<glam::Vec4>(&light.voxel_sh);
        let inputs = GatherInputs {
            params: gathering.params,
            eye: ctx.camera.eye,
            position: &position,
            normal: &normal,
            ns: &ns,
            lists: &lists,
            vpls: [&p, &n, &f],
            sorted: &sorted,
            ranges: &ranges,
            voxel_sh: &voxel_sh,
        };
        let out = read::<glam::Vec4>(&planes);
        let plane = (size.0 * size.1) as usize;
        let (mut lit, mut worst) = (0, 0.0f32);
        for y in 0..size.1 {
            for x in 0..size.0 {
                let i = (y * size.0 + x) as usize;
                let cpu = gather_cpu(&inputs, (x, y));
                for (k, c) in cpu.iter().enumerate() {
                    let g = out[k * plane + i].truncate();
                    let err = (g - *c).abs().max_element() / c.max_element().max(1e-3);
                    worst = worst.max(err);
                }
                lit += usize::from(cpu[0].max_element() > 0.0);
            }
        }
        assert!(
            worst < 1e-3,
            "sigma {sigma}: worst relative difference {worst}"
        );
        assert!(
            lit * 2 > plane,
            "sigma {sigma}: {lit} of {plane} pixels lit"
        );
    }
}

/// In the closed sphere of `methods.rs` every voxel is visible from every point, and each
/// point's one-bounce irradiance is the closed form `rho Phi / A`: the gathering over lists of
/// every voxel (the visibility sampling taken out) must give it, with VPLs near and harmonics
/// far (R of one voxel) and with VPLs only.
#[test]
fn gathering_every_voxel_gives_the_spheres_closed_form() {
    use super::methods::{CUTOFF_DEG, INTENSITY, RHO, sphere};
    let gpu = gpu();
    let (scene, area, _) = sphere();
    let LitProxies {
        renderer,
        grid,
        light,
        ..
    } = lit_proxies_in(scene, 8192, 8, (32, 24));
    let ctx = renderer.context();
    let shape = RayShape {
        rays: 64,
        ..ray_shape(scene, 4, 1.5)
    };
    let rays = SparseRays::new(ctx, &grid, &light, shape);
    let filter_shape = FilterShape {
        radius: 3,
        depth: 0.1,
        normal: 0.9,
    };
    let filter =
        VisibilityFilter::new(ctx, &rays, grid.grid.cells(), &filter_shape).expect("filter");
    let ranges = read::<[u32; 2]>(&grid.cells);
    let every: Vec<u32> = (0..ranges.len() as u32)
        .filter(|&v| ranges[v as usize][1] > ranges[v as usize][0])
        .collect();
    let stride = filter.params.capacity as usize + 1;
    assert!(
        every.len() < stride,
        "{} voxels, room for {}",
        every.len(),
        stride - 1
    );
    let mut lists = vec![0u32; stride * filter.params.pixels() as usize];
    for chunk in lists.chunks_mut(stride) {
        chunk[0] = every.len() as u32;
        chunk[1..=every.len()].copy_from_slice(&every);
    }
    gpu.queue
        .write_buffer(&filter.lists, 0, bytemuck::cast_slice(&lists));
    let power = INTENSITY * std::f32::consts::TAU * (1.0 - CUTOFF_DEG.to_radians().cos());
    let expected = RHO * power / area;
    let mut errors = Vec::new();
    // Order-1 harmonics of a clamped cosine send 3/4 of it head-on (gather.rs), and the
    // camera looks at the wall opposite the lit patch: the far light falls short by about that.
    for (range, tolerance) in [(1.0, 0.25), (100.0, 0.02)] {
        let size = cssm_runtime::common::filters::low_size(ctx.size(), 2);
        let planes = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("planes"),
            size: 2 * 16 * u64::from(size.0 * size.1),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let gather = GatherShape {
            factor: 2,
            range: range * grid.grid.cell,
            depth_sigma: 0.1,
            normal_power: 8.0,
            sigma: 0.0,
        };
        let gathering = Gathering::new(ctx, (&grid, &light), (&rays, &filter), &gather, &planes);
        submit(|frame| gathering.run(frame));
        let out = read::<glam::Vec4>(&planes);
        let plane = &out[..(size.0 * size.1) as usize];
        let mean = plane
            .iter()
            .map(|e| e.truncate().element_sum() / 3.0)
            .sum::<f32>()
            / plane.len() as f32;
        let error = mean / expected - 1.0;
        eprintln!(
            "R {range} voxels: mean irradiance {mean:.5}, closed form {expected:.5}, {:+.2}%",
            100.0 * error
        );
        errors.push((range, tolerance, error));
    }
    for (range, tolerance, error) in errors {
        assert!(
            error.abs() < tolerance,
            "R {range}: {error:+} against the closed form"
        );
    }
}
