//! The G-buffer pyramid and the pyramid of a signal over it (`pyramid.wgsl`), shared by the
//! screen-space techniques that gather at several scales (`ssil`, Soler et al. 2010 §4).
//!
//! Level 0 is the G-buffer; level `j` halves level `j - 1` per side, rounding up, so that a
//! coarse pixel stands for its 2x2 children and level `j` has the size of the image reduced
//! `2^j` times ([`crate::common::filters::low_size`]). Levels 1 and up live in storage buffers,
//! one `vec4f` per pixel, level `j` from element [`PyramidLayout::offset`].
//!
//! - [`GBufferPyramid`] (`vote`): position, normal and albedo of one child per coarse pixel,
//!   the child of largest score by Eq. 5 (its neighbours' agreement in depth and normal), so
//!   that levels keep large surfaces and never hold an average normal that belongs to none.
//! - [`SignalPyramid`] (`mean`): the mean of the children, uncovered ones counting as zero.
//!
//! CPU twins: [`vote_cpu`], [`mean_cpu`]; test `tests/gpu/ssil.rs::pyramids_match_cpu_twins`.

use glam::{Vec3, Vec4};
use wgpu::util::DeviceExt;

use crate::{
    common::{gbuffer::GBuffer, layout},
    frame::FrameEncoder,
    shaders,
};

/// `common/pyramid.wgsl`: the G-buffer pyramid's vote (`vote`) and a signal's mean (`mean`).
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("pyramid", "common/pyramid.wgsl");

/// Most levels above the G-buffer.
pub const MAX_LEVELS: u32 = 12;

/// The sizes and offsets of a pyramid's levels over a `full`-size image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PyramidLayout {
    /// Size of level 0.
    pub full: (u32, u32),
    /// Levels above level 0 (the buffers hold levels 1 to `levels`).
    pub levels: u32,
}

impl PyramidLayout {
    /// Size of `level` (0 is the full size).
    pub fn size(&self, level: u32) -> (u32, u32) {
        let mut size = self.full;
        for _ in 0..level {
            size = (size.0.div_ceil(2), size.1.div_ceil(2));
        }
        size
    }

    /// Element of `level`'s pixel (0, 0) in the buffers (`level` at least 1).
    pub fn offset(&self, level: u32) -> u32 {
        (1..level)
            .map(|j| {
                let (w, h) = self.size(j);
                w * h
            })
            .sum()
    }

    /// Elements of levels 1 to `levels`.
    pub fn pixels(&self) -> u32 {
        self.offset(self.levels + 1)
    }

    /// Element of pixel `(x, y)` of `level` (at least 1).
    pub fn index(&self, level: u32, (x, y): (u32, u32)) -> usize {
        (self.offset(level) + y * self.size(level).0 + x) as usize
    }

    /// Bytes of a buffer of one `vec4f` per element of levels 1 to `levels` times `planes`
    /// (at least 16, so that a one-pixel image still binds).
    pub fn bytes(&self, planes: u32) -> u64 {
        (16 * u64::from(self.pixels()) * u64::from(planes)).max(16)
    }
}

/// `pyramid.wgsl`'s `LevelParams`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct LevelParams {
    fine_size: [u32; 2],
    coarse_size: [u32; 2],
    fine_offset: u32,
    coarse_offset: u32,
    from_base: u32,
    padding: u32,
}

/// The parameters of building `level` (at least 1) from `level - 1`.
fn level_params(layout: &PyramidLayout, level: u32) -> LevelParams {
    let (fw, fh) = layout.size(level - 1);
    let (cw, ch) = layout.size(level);
    LevelParams {
        fine_size: [fw, fh],
        coarse_size: [cw, ch],
        fine_offset: if level > 1 {
            layout.offset(level - 1)
        } else {
            0
        },
        coarse_offset: layout.offset(level),
        from_base: u32::from(level == 1),
        padding: 0,
    }
}

fn params_buffer(device: &wgpu::Device, layout: &PyramidLayout, level: u32) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("pyramid level"),
        contents: bytemuck::bytes_of(&level_params(layout, level)),
        usage: wgpu::BufferUsages::UNIFORM,
    })
}

fn storage(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Position, normal and albedo per pixel of levels 1 and up, by Eq. 5's vote.
pub struct GBufferPyramid {
    layout: PyramidLayout,
    /// xyz world position, w 1 where covered.
    pub position: wgpu::Buffer,
    /// xyz normal towards the eye, w material index.
    pub normal: wgpu::Buffer,
    /// rgb albedo, w triangle index.
    pub albedo: wgpu::Buffer,
    bind_layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    groups: Vec<wgpu::BindGroup>,
}

impl GBufferPyramid {
    /// Levels 1 to `levels` over `gbuffer`, the eye read from the frame's `view` uniform.
    pub fn new(device: &wgpu::Device, gbuffer: &GBuffer, view: &wgpu::Buffer, levels: u32) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let bind_layout = layout::bind_group_layout(
            device,
            "gbuffer pyramid",
            &[
                layout::uniform(0, c),
                layout::uniform(1, c),
                layout::texture(2, d2, c),
                layout::texture(3, d2, c),
                layout::texture(4, d2, c),
                layout::storage(5, false, c),
                layout::storage(6, false, c),
                layout::storage(7, false, c),
            ],
        );
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline_entry(
            device,
            "gbuffer pyramid",
            &module,
            "vote",
            &[&bind_layout],
        );
        let layout = PyramidLayout {
            full: gbuffer.size(),
            levels,
        };
        let [position, normal, albedo] = ["position", "normal", "albedo"]
            .map(|name| storage(device, &format!("gbuffer pyramid {name}"), layout.bytes(1)));
        let mut pyramid = Self {
            layout,
            position,
            normal,
            albedo,
            bind_layout,
            pipeline,
            groups: Vec::new(),
        };
        pyramid.bind(device, gbuffer, view);
        pyramid
    }

    fn bind(&mut self, device: &wgpu::Device, gbuffer: &GBuffer, view: &wgpu::Buffer) {
        let views = [&gbuffer.position, &gbuffer.normal, &gbuffer.albedo]
            .map(|t| t.create_view(&Default::default()));
        self.groups = (1..=self.layout.levels)
            .map(|level| {
                let params = params_buffer(device, &self.layout, level);
                let mut resources = vec![params.as_entire_binding(), view.as_entire_binding()];
                resources.extend(views.iter().map(wgpu::BindingResource::TextureView));
                resources.extend(
                    [&self.position, &self.normal, &self.albedo].map(|b| b.as_entire_binding()),
                );
                layout::bind_group(device, "gbuffer pyramid", &self.bind_layout, &resources)
            })
            .collect();
    }

    /// New buffers over the resized `gbuffer` (the pipeline stays).
    pub fn resize(&mut self, device: &wgpu::Device, gbuffer: &GBuffer, view: &wgpu::Buffer) {
        self.layout.full = gbuffer.size();
        [self.position, self.normal, self.albedo] = ["position", "normal", "albedo"].map(|name| {
            storage(
                device,
                &format!("gbuffer pyramid {name}"),
                self.layout.bytes(1),
            )
        });
        self.bind(device, gbuffer, view);
    }

    /// The levels' sizes and offsets.
    pub fn layout(&self) -> PyramidLayout {
        self.layout
    }

    /// Records the vote of every level, finest first (timed as "gbuffer pyramid").
    pub fn run(&self, frame: &mut FrameEncoder) {
        let mut pass = frame.compute_pass("gbuffer pyramid");
        pass.set_pipeline(&self.pipeline);
        for (level, group) in (1..).zip(&self.groups) {
            pass.set_bind_group(0, group, &[]);
            let (x, y) = shaders::groups_2d(self.layout.size(level));
            pass.dispatch_workgroups(x, y, 1);
        }
    }
}

/// A signal's mean per pixel of levels 1 and up, from a full-res `base` (one `vec4f` per pixel,
/// row-major).
pub struct SignalPyramid {
    layout: PyramidLayout,
    /// Levels 1 and up, [`PyramidLayout::offset`] apart.
    pub signal: wgpu::Buffer,
    bind_layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    groups: Vec<wgpu::BindGroup>,
}

impl SignalPyramid {
    /// Levels 1 to `layout.levels` of `base`.
    pub fn new(device: &wgpu::Device, layout: PyramidLayout, base: &wgpu::Buffer) -> Self {
        let c = wgpu::ShaderStages::COMPUTE;
        let bind_layout = layout::bind_group_layout(
            device,
            "signal pyramid",
            &[
                layout::uniform(0, c),
                layout::storage(8, true, c),
                layout::storage(9, false, c),
            ],
        );
        let module = SHADER.create(device);
        let pipeline = layout::compute_pipeline_entry(
            device,
            "signal pyramid",
            &module,
            "mean",
            &[&bind_layout],
        );
        let signal = storage(device, "signal pyramid", layout.bytes(1));
        let mut pyramid = Self {
            layout,
            signal,
            bind_layout,
            pipeline,
            groups: Vec::new(),
        };
        pyramid.bind(device, base);
        pyramid
    }

    fn bind(&mut self, device: &wgpu::Device, base: &wgpu::Buffer) {
        self.groups = (1..=self.layout.levels)
            .map(|level| {
                let params = params_buffer(device, &self.layout, level);
                layout::bind_group_at(
                    device,
                    "signal pyramid",
                    &self.bind_layout,
                    &[
                        (0, params.as_entire_binding()),
                        (8, base.as_entire_binding()),
                        (9, self.signal.as_entire_binding()),
                    ],
                )
            })
            .collect();
    }

    /// New buffers for a full size of `layout.full` and a new `base`.
    pub fn resize(&mut self, device: &wgpu::Device, layout: PyramidLayout, base: &wgpu::Buffer) {
        self.layout = layout;
        self.signal = storage(device, "signal pyramid", layout.bytes(1));
        self.bind(device, base);
    }

    /// Records the mean of levels `first` to the last (`first` at least 1; level `first - 1`
    /// is read as it stands, the base when `first` is 1), in a pass timed as `name`.
    pub fn run(&self, frame: &mut FrameEncoder, name: &'static str, first: u32) {
        let mut pass = frame.compute_pass(name);
        pass.set_pipeline(&self.pipeline);
        for level in first.max(1)..=self.layout.levels {
            pass.set_bind_group(0, &self.groups[level as usize - 1], &[]);
            let (x, y) = shaders::groups_2d(self.layout.size(level));
            pass.dispatch_workgroups(x, y, 1);
        }
    }
}

/// One level of the G-buffer pyramid on the CPU: row-major `vec4f` per pixel, as the GPU's.
#[derive(Clone, Debug, PartialEq)]
pub struct CpuLevel {
    /// Width and height.
    pub size: (u32, u32),
    /// xyz position, w 1 where covered.
    pub position: Vec<Vec4>,
    /// xyz normal, w material.
    pub normal: Vec<Vec4>,
    /// rgb albedo, w triangle.
    pub albedo: Vec<Vec4>,
}

/// `pyramid.wgsl`: `NEIGHBOUR_WEIGHT`, `NORMAL_SIGMA`, `DEPTH_SIGMA`.
const NEIGHBOUR_WEIGHT: f32 = 0.606_530_66;
const NORMAL_SIGMA: f32 = 0.2;
const DEPTH_SIGMA: f32 = 0.05;

/// CPU twin of `vote`: the next coarser level of `fine` seen from `eye`.
pub fn vote_cpu(fine: &CpuLevel, eye: Vec3) -> CpuLevel {
    let (fw, fh) = fine.size;
    let (cw, ch) = (fw.div_ceil(2), fh.div_ceil(2));
    let at = |x: i32, y: i32| (y as u32 * fw + x as u32) as usize;
    let distance = |i: usize| eye.distance(fine.position[i].truncate());
    let affinity = |c: usize, o: usize| {
        let dn = (1.0 - fine.normal[c].truncate().dot(fine.normal[o].truncate())) / NORMAL_SIGMA;
        let zc = distance(c);
        let dz = (distance(o) - zc) / (DEPTH_SIGMA * zc.max(1e-6));
        (-0.5 * (dn * dn + dz * dz)).exp()
    };
    let n = (cw * ch) as usize;
    let mut out = CpuLevel {
        size: (cw, ch),
        position: vec![Vec4::ZERO; n],
        normal: vec![Vec4::ZERO; n],
        albedo: vec![Vec4::ZERO; n],
    };
    for y in 0..ch {
        for x in 0..cw {
            let mut best: Option<(usize, f32)> = None;
            for c in 0..4u32 {
                let (cx, cy) = ((2 * x + (c & 1)) as i32, (2 * y + (c >> 1)) as i32);
                if cx >= fw as i32 || cy >= fh as i32 {
                    continue;
                }
                let i = at(cx, cy);
                if fine.position[i].w <= 0.0 {
                    continue;
                }
                let mut score = 1.0f32;
                for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                    let (nx, ny) = (cx + dx, cy + dy);
                    if nx < 0 || ny < 0 || nx >= fw as i32 || ny >= fh as i32 {
                        continue;
                    }
                    let j = at(nx, ny);
                    if fine.position[j].w > 0.0 {
                        score += NEIGHBOUR_WEIGHT * affinity(i, j);
                    }
                }
                if best.is_none_or(|(_, s)| score > s) {
                    best = Some((i, score));
                }
            }
            if let Some((i, _)) = best {
                let o = (y * cw + x) as usize;
                out.position[o] = fine.position[i];
                out.normal[o] = fine.normal[i];
                out.albedo[o] = fine.albedo[i];
            }
        }
    }
    out
}

/// CPU twin of `mean`: the next coarser level of a `fine` signal of `size`.
pub fn mean_cpu(fine: &[Vec4], (fw, fh): (u32, u32)) -> Vec<Vec4> {
    let (cw, ch) = (fw.div_ceil(2), fh.div_ceil(2));
    let mut out = Vec::with_capacity((cw * ch) as usize);
    for y in 0..ch {
        for x in 0..cw {
            let (mut sum, mut count) = (Vec4::ZERO, 0.0f32);
            for c in 0..4u32 {
                let (cx, cy) = (2 * x + (c & 1), 2 * y + (c >> 1));
                if cx < fw && cy < fh {
                    sum += fine[(cy * fw + cx) as usize];
                    count += 1.0;
                }
            }
            out.push(sum / count);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "LevelParams",
            size_of::<LevelParams>(),
            &[
                ("fine_size", offset_of!(LevelParams, fine_size)),
                ("coarse_size", offset_of!(LevelParams, coarse_size)),
                ("fine_offset", offset_of!(LevelParams, fine_offset)),
                ("coarse_offset", offset_of!(LevelParams, coarse_offset)),
                ("from_base", offset_of!(LevelParams, from_base)),
            ],
        );
    }

    #[test]
    fn levels_halve_rounding_up_and_follow_each_other() {
        let layout = PyramidLayout {
            full: (5, 3),
            levels: 3,
        };
        assert_eq!(layout.size(0), (5, 3));
        assert_eq!(layout.size(1), (3, 2));
        assert_eq!(layout.size(2), (2, 1));
        assert_eq!(layout.size(3), (1, 1));
        assert_eq!(layout.offset(1), 0);
        assert_eq!(layout.offset(2), 6);
        assert_eq!(layout.offset(3), 8);
        assert_eq!(layout.pixels(), 9);
        assert_eq!(layout.index(2, (1, 0)), 7);
        // Level j is the image reduced 2^j times, as the shared filters size it.
        let big = PyramidLayout {
            full: (1283, 721),
            levels: 4,
        };
        for j in 0..=4 {
            assert_eq!(
                big.size(j),
                crate::common::filters::low_size(big.full, 1 << j)
            );
        }
    }

    /// A coarse pixel over a large wall and one stray pixel of another surface takes the wall,
    /// even when the stray pixel comes first among the children.
    #[test]
    fn the_vote_keeps_the_large_surface() {
        let (w, h) = (4u32, 4u32);
        let n = (w * h) as usize;
        let mut fine = CpuLevel {
            size: (w, h),
            position: (0..n)
                .map(|i| Vec4::new((i % 4) as f32 * 0.1, (i / 4) as f32 * 0.1, -2.0, 1.0))
                .collect(),
            normal: vec![Vec4::new(0.0, 0.0, 1.0, 0.0); n],
            albedo: vec![Vec4::new(0.5, 0.5, 0.5, 0.0); n],
        };
        // Pixel (0, 0): a nearer surface facing up, red.
        fine.position[0] = Vec4::new(0.0, 0.0, -1.0, 1.0);
        fine.normal[0] = Vec4::new(0.0, 1.0, 0.0, 1.0);
        fine.albedo[0] = Vec4::new(1.0, 0.0, 0.0, 0.0);
        // Pixel (1, 1) uncovered.
        fine.position[5] = Vec4::ZERO;
        let coarse = vote_cpu(&fine, Vec3::ZERO);
        assert_eq!(coarse.size, (2, 2));
        assert_eq!(coarse.normal[0], Vec4::new(0.0, 0.0, 1.0, 0.0));
        assert_eq!(coarse.albedo[0], Vec4::new(0.5, 0.5, 0.5, 0.0));
        assert!(coarse.position.iter().all(|p| p.w == 1.0));
        // All children uncovered: uncovered.
        let empty = CpuLevel {
            position: vec![Vec4::ZERO; n],
            ..fine.clone()
        };
        assert!(
            vote_cpu(&empty, Vec3::ZERO)
                .position
                .iter()
                .all(|p| p.w == 0.0)
        );
    }

    #[test]
    fn the_mean_keeps_the_screen_total_of_even_sizes() {
        let fine: Vec<Vec4> = (0..24).map(|i| Vec4::splat(i as f32)).collect();
        let coarse = mean_cpu(&fine, (6, 4));
        assert_eq!(coarse.len(), 6);
        let total = |v: &[Vec4]| v.iter().map(|p| p.x).sum::<f32>();
        assert_eq!(4.0 * total(&coarse), total(&fine));
        // An odd edge averages the children it has.
        assert_eq!(
            mean_cpu(&[Vec4::ONE, Vec4::splat(3.0)], (1, 2)),
            vec![Vec4::splat(2.0)]
        );
    }
}
