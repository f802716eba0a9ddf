//! [`ScreenSpaceGi`]: the whole SSIL pipeline over a frame context, its passes in the order
//! the module doc of [`super`] lists them.

use glam::Vec3;

use super::{
    FrameParams, Levels, SsilOptions, Visibility,
    gather::{GatherGroups, GatherInputs, GatherPass},
    sender::SenderPass,
    temporal::{TemporalInputs, TemporalParams, TemporalPass},
    uniform_buffer,
    voxels::{VoxelGrid, VoxelParams, VoxelPass},
};
use crate::{
    RuntimeError,
    common::{
        converge::{ConvergeGpu, ConvergeInputs, Convergence},
        filters::{EdgeAwareFilter, LowGuide},
        history::FrameHistory,
        pyramid::{GBufferPyramid, SignalPyramid},
        resolve::PlaneResolve,
    },
    frame::{FrameContext, FrameEncoder},
};

/// The passes' pipelines and layouts, created once.
struct Passes {
    sender: SenderPass,
    voxels: VoxelPass,
    gather: GatherPass,
    temporal: TemporalPass,
}

/// What depends on the image size: buffers and bind groups.
struct Sized {
    levels: Levels,
    sender: wgpu::Buffer,
    acc: wgpu::Buffer,
    blended: wgpu::Buffer,
    history: wgpu::Buffer,
    sender_group: wgpu::BindGroup,
    voxels: VoxelGrid,
    gathers: GatherGroups,
    temporal_group: wgpu::BindGroup,
    /// The test that ends the bounces once converged (with `bounces` 0).
    converge: ConvergeGpu,
}

/// The uniforms the frame writes before its passes run.
struct Uniforms {
    frame: wgpu::Buffer,
    voxels: wgpu::Buffer,
    temporal: wgpu::Buffer,
}

/// The whole SSIL pipeline over a frame context: the method's engine, which the tests and
/// benchmarks also drive directly.
pub struct ScreenSpaceGi {
    options: SsilOptions,
    bounds: (Vec3, Vec3),
    passes: Passes,
    pyramid: GBufferPyramid,
    light: SignalPyramid,
    filter: EdgeAwareFilter,
    resolve: PlaneResolve,
    uniforms: Uniforms,
    sized: Sized,
    frame_history: FrameHistory,
    frames: u32,
}

impl ScreenSpaceGi {
    /// The pipeline of `options` over `ctx`, for a scene within `bounds` (the voxels' depth
    /// range).
    ///
    /// # Errors
    /// Options that [`SsilOptions::check`] or the filters refuse.
    pub fn new(
        ctx: &FrameContext,
        bounds: (Vec3, Vec3),
        options: &SsilOptions,
    ) -> Result<Self, RuntimeError> {
        options.check()?;
        let device = &ctx.device;
        let levels = Levels::new(ctx.size(), options);
        let passes = Passes {
            sender: SenderPass::new(device),
            voxels: VoxelPass::new(device),
            gather: GatherPass::new(device),
            temporal: TemporalPass::new(device),
        };
        let pyramid = GBufferPyramid::new(device, &ctx.gbuffer, &ctx.view, levels.last);
        let sender = ctx.pixel_buffer("ssil sender");
        let light = SignalPyramid::new(device, levels.pyramid, &sender);
        let filter = EdgeAwareFilter::new(
            device,
            &ctx.gbuffer,
            &ctx.view,
            2,
            options.filter(),
            Self::low_guide(&pyramid, &levels),
        )?;
        let uniforms = Uniforms {
            frame: uniform_buffer(device, "ssil frame", &FrameParams::default()),
            voxels: uniform_buffer(
                device,
                "ssil voxels",
                &VoxelParams {
                    z_near: 0.0,
                    z_far: 1.0,
                    columns: [0; 2],
                },
            ),
            temporal: uniform_buffer(
                device,
                "ssil temporal",
                &TemporalParams {
                    previous_view_proj: [[0.0; 4]; 4],
                    previous_eye: [0.0; 3],
                    blend: options.temporal,
                    history: 0,
                    padding: [0; 3],
                },
            ),
        };
        let frame_history = FrameHistory::new(device, ctx.size());
        let sized = Self::bind(
            ctx,
            options,
            &passes,
            (&pyramid, &light, &filter),
            &uniforms,
            sender,
            &frame_history,
        );
        let resolve = PlaneResolve::new(ctx, "ssil resolve", &sized.blended);
        Ok(Self {
            options: *options,
            bounds,
            passes,
            pyramid,
            light,
            filter,
            resolve,
            uniforms,
            sized,
            frame_history,
            frames: 0,
        })
    }

    fn low_guide<'a>(pyramid: &'a GBufferPyramid, levels: &Levels) -> LowGuide<'a> {
        LowGuide::Buffers {
            position: &pyramid.position,
            normal: &pyramid.normal,
            offset: levels.pyramid.offset(levels.start),
        }
    }

    /// Everything of one image size: the buffers between the passes and their bind groups.
    fn bind(
        ctx: &FrameContext,
        options: &SsilOptions,
        passes: &Passes,
        (pyramid, light, filter): (&GBufferPyramid, &SignalPyramid, &EdgeAwareFilter),
        uniforms: &Uniforms,
        sender: wgpu::Buffer,
        frames: &FrameHistory,
    ) -> Sized {
        let device = &ctx.device;
        let levels = Levels::new(ctx.size(), options);
        let pixels = u64::from(levels.pyramid.pixels());
        let acc = super::storage_buffer(device, "ssil gathered", 32 * pixels);
        let (w, h) = ctx.size();
        let planes = 32 * u64::from(w) * u64::from(h);
        let blended = super::storage_buffer(device, "ssil blended", planes);
        let history = super::storage_buffer(device, "ssil history", planes);
        let sender_group = passes.sender.bind(ctx, &sender);
        let voxels = passes.voxels.bind(ctx, &levels, &uniforms.voxels);

        // After the first light pyramid: the light so far; after each later one, the light the
        // bounce before reflects, from the pyramid's top level (every pixel's, box-filtered).
        let top = levels.pyramid.size(levels.last);
        let converge = ConvergeGpu::new(
            device,
            options.plan(),
            &ConvergeInputs {
                solution: [&light.signal, &light.signal],
                held: None,
                mean: (levels.pyramid.offset(levels.last), top.0 * top.1),
                additive: true,
                // The gathers read the state and gather nothing once converged.
                work_args: None,
            },
        );
        let gathers = passes.gather.bind(
            ctx,
            options,
            &levels,
            &GatherInputs {
                frame_params: &uniforms.frame,
                pyramid,
                light,
                grid: &voxels.grid,
                acc: &acc,
                summed: filter.input(),
                converge: &converge,
            },
        );
        let temporal_group = passes.temporal.bind(
            ctx,
            &TemporalInputs {
                params: &uniforms.temporal,
                frames,
                filtered: filter.output(),
                history: &history,
                blended: &blended,
            },
        );
        Sized {
            levels,
            sender,
            acc,
            blended,
            history,
            sender_group,
            voxels,
            gathers,
            temporal_group,
            converge,
        }
    }

    /// Rebuilds what depends on the size after the context's G-buffer was resized; the
    /// history starts again.
    pub fn resize(&mut self, ctx: &FrameContext) {
        let device = &ctx.device;
        let levels = Levels::new(ctx.size(), &self.options);
        self.pyramid.resize(device, &ctx.gbuffer, &ctx.view);
        let sender = ctx.pixel_buffer("ssil sender");
        self.light.resize(device, levels.pyramid, &sender);
        self.filter.resize(
            device,
            &ctx.gbuffer,
            &ctx.view,
            Self::low_guide(&self.pyramid, &levels),
        );
        self.frame_history.resize(device, ctx.size());
        self.sized = Self::bind(
            ctx,
            &self.options,
            &self.passes,
            (&self.pyramid, &self.light, &self.filter),
            &self.uniforms,
            sender,
            &self.frame_history,
        );
        self.resolve.resize(ctx, &self.sized.blended);
    }

    /// The levels' geometry.
    pub fn levels(&self) -> Levels {
        self.sized.levels
    }

    /// The options it was built with.
    pub fn options(&self) -> &SsilOptions {
        &self.options
    }

    /// The G-buffer pyramid.
    pub fn pyramid(&self) -> &GBufferPyramid {
        &self.pyramid
    }

    /// The light the last bounce gathered, per pyramid level (levels 1 and up).
    pub fn light(&self) -> &SignalPyramid {
        &self.light
    }

    /// The full-res diffuse direct light the first bounce sends.
    pub fn sender(&self) -> &wgpu::Buffer {
        &self.sized.sender
    }

    /// The solid voxels: four words per column of every gathered level, finest first.
    pub fn grid(&self) -> &wgpu::Buffer {
        &self.sized.voxels.grid
    }

    /// The last bounce's gathered planes per pyramid element (diffuse, then lobe-weighted,
    /// [`crate::common::pyramid::PyramidLayout::pixels`] apart), each level holding the coarser levels' too.
    pub fn gathered(&self) -> &wgpu::Buffer {
        &self.sized.acc
    }

    /// The bounces' sum at the finest gathered level: the filters' input (two planes).
    pub fn summed(&self) -> &wgpu::Buffer {
        self.filter.input()
    }

    /// The filters' output at full resolution (two planes), before the temporal filter.
    pub fn filtered(&self) -> &wgpu::Buffer {
        self.filter.output()
    }

    /// The temporally filtered planes at full resolution.
    pub fn blended(&self) -> &wgpu::Buffer {
        &self.sized.blended
    }

    /// The parameters of the last frame encoded.
    pub fn frame_params(&self, ctx: &FrameContext) -> FrameParams {
        FrameParams::new(&ctx.gpu_view(), self.bounds, self.frames.wrapping_sub(1))
    }

    /// The indirect radiance per pixel.
    pub fn indirect(&self) -> &wgpu::Buffer {
        self.resolve.indirect()
    }

    /// How many bounces the last frame gathered (read back; waits for the GPU); with
    /// `bounces` fixed, all of them and never converged (the test is not run, its state zero).
    ///
    /// # Errors
    /// GPU errors of the read-back.
    pub fn convergence(&self, ctx: &FrameContext) -> Result<Convergence, RuntimeError> {
        let ended = self.sized.converge.read(&ctx.device, &ctx.queue)?;
        // The test runs after every bounce but the last: a run that did not stop ran them all.
        Ok(if ended.converged {
            ended
        } else {
            Convergence {
                bounces: self.options.plan().max,
                ..ended
            }
        })
    }

    /// Records a frame: sender, pyramids, voxels, the bounces' gathers, filters, temporal
    /// filter, resolve.
    pub fn encode(&mut self, ctx: &FrameContext, frame: &mut FrameEncoder) {
        let view = ctx.gpu_view();
        let params = FrameParams::new(&view, self.bounds, self.frames);
        self.frames = self.frames.wrapping_add(1);
        let levels = self.sized.levels;
        let queue = &ctx.queue;
        queue.write_buffer(&self.uniforms.frame, 0, bytemuck::bytes_of(&params));
        let (cw, ch) = levels.pyramid.size(levels.start);
        queue.write_buffer(
            &self.uniforms.voxels,
            0,
            bytemuck::bytes_of(&VoxelParams {
                z_near: params.z_near,
                z_far: params.z_far,
                columns: [cw, ch],
            }),
        );
        let previous = *self.frame_history.previous().unwrap_or(&view);
        queue.write_buffer(
            &self.uniforms.temporal,
            0,
            bytemuck::bytes_of(&TemporalParams {
                previous_view_proj: previous.view_proj,
                previous_eye: previous.eye,
                blend: self.options.temporal,
                history: u32::from(self.frame_history.previous().is_some()),
                padding: [0; 3],
            }),
        );

        let sized = &self.sized;
        let passes = &self.passes;
        passes.sender.run(frame, &sized.sender_group, ctx.size());
        self.pyramid.run(frame);
        self.light.run(frame, "ssil light pyramid", 1);
        // With a fixed count (the default) the test is not recorded: its state stays as
        // created, zero, and every gather runs.
        let converging = self.options.plan().fraction > 0.0;
        if converging {
            let mut pass = frame.compute_pass("ssil converge");
            sized.converge.start(&mut pass);
        }
        if self.options.visibility == Visibility::Voxels {
            passes.voxels.run(ctx, frame, &sized.voxels, &levels);
        }
        let bounces = self.options.plan().max as usize;
        for bounce in 0..bounces {
            passes.gather.run(frame, &sized.gathers, &levels, bounce);
            if bounce + 1 < bounces {
                self.light
                    .run(frame, "ssil light pyramid", levels.start + 1);
                // The light this bounce reflects: the next bounces gather nothing once it is at
                // most 1% of the light so far.
                if converging {
                    let mut pass = frame.compute_pass("ssil converge");
                    sized.converge.check(&mut pass, bounce as u32 + 1);
                }
            }
        }
        self.filter.run(frame);
        passes
            .temporal
            .run(frame, &sized.temporal_group, ctx.size());
        self.resolve.run(frame);
        // The history of the next frame.
        frame
            .encoder
            .copy_buffer_to_buffer(&sized.blended, 0, &sized.history, 0, None);
        self.frame_history.record(frame.encoder, &ctx.gbuffer, view);
    }
}
