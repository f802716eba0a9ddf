//! Converged bounces: how many indirect bounces a method runs when the user names none.
//!
//! A bounce is the last when it adds at most [`CONVERGED_FRACTION`] of the light computed so far
//! (Rec. 709 luminance of the method's mean radiance), or when [`MAX_BOUNCES`] have run. Each
//! method measures the light it computes itself: the radiosity the hierarchy's root (the pull
//! leaves it holding the area-weighted mean radiance of every texel, §4.1.1), the voxel cone
//! tracing its octree's first level (the root's eight children), ssil the top of the pyramid of
//! each bounce's light, the path tracer its image. `bounces=0`, the default of every method but
//! ssil (which keeps its paper's 2), asks for this; `bounces=N` runs exactly `N`
//! ([`BouncePlan::from_option`]).
//!
//! On the GPU ([`ConvergeGpu`]) the test runs in one thread after each bounce and needs no read
//! back: once a bounce has converged it sets the later bounces' indirect dispatches to zero
//! workgroups and, for a method iterating between two buffers, copies the solution into the
//! other one (`converge.wgsl`, `check` and `hold`), so the frame is still one submission and
//! costs the bounces it needs.
//!
//! What is left out is bounded: with a mean albedo `rho`, the bounces after the last add about
//! `rho / (1 - rho)` times its share, 2.3% of the light at `rho` 0.7 for the fraction 1%.

use glam::Vec3;
use wgpu::util::DeviceExt;

use crate::{
    RuntimeError,
    common::{layout, readback, tonemap::luminance},
    shaders,
};

pub use crate::method::MAX_BOUNCES;

/// `common/converge.wgsl`: the test that ends a run of bounces (`check`) and the copy that holds
/// its solution (`hold`).
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("converge", "common/converge.wgsl");

/// A bounce that adds at most this share of the light computed so far is the last of a
/// converged run.
pub const CONVERGED_FRACTION: f32 = 0.01;

/// How many bounces a method runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BouncePlan {
    /// Bounces at most.
    pub max: u32,
    /// Stop after a bounce that adds at most this share of the light (0: run all `max`).
    pub fraction: f32,
}

impl BouncePlan {
    /// Exactly `n` bounces.
    pub const fn exactly(n: u32) -> Self {
        Self {
            max: n,
            fraction: 0.0,
        }
    }

    /// Until converged: at most [`MAX_BOUNCES`], stopping after a bounce that adds at most
    /// [`CONVERGED_FRACTION`].
    pub const fn converged() -> Self {
        Self {
            max: MAX_BOUNCES,
            fraction: CONVERGED_FRACTION,
        }
    }

    /// The plan of a method's `bounces` option: 0 until converged, `n` exactly `n`.
    pub const fn from_option(bounces: u32) -> Self {
        if bounces == 0 {
            Self::converged()
        } else {
            Self::exactly(bounces)
        }
    }

    /// The same plan with one bounce fewer at most (a method whose last bounce is computed
    /// elsewhere, like the lightcuts final gather).
    pub const fn one_fewer(self) -> Self {
        Self {
            max: self.max.saturating_sub(1),
            fraction: self.fraction,
        }
    }

    /// Whether the bounce that took the mean radiance from `before` to `after` is the last.
    pub fn ends(&self, before: Vec3, after: Vec3) -> bool {
        let (added, total) = added_light(before, after);
        self.fraction > 0.0 && added <= self.fraction * total
    }
}

impl From<u32> for BouncePlan {
    /// Exactly `n` bounces.
    fn from(n: u32) -> Self {
        Self::exactly(n)
    }
}

/// The luminance a bounce added and the total after it, from the mean radiance `before` and
/// `after` it (`converge.wgsl`'s `check`).
fn added_light(before: Vec3, after: Vec3) -> (f32, f32) {
    let total = luminance(after);
    ((total - luminance(before)).abs(), total)
}

/// The share of the light a bounce added (0 when there is none).
pub fn added_fraction(before: Vec3, after: Vec3) -> f32 {
    let (added, total) = added_light(before, after);
    if total > 0.0 { added / total } else { 0.0 }
}

/// How a run of bounces ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Convergence {
    /// Bounces computed.
    pub bounces: u32,
    /// Whether the last one added at most the plan's fraction (false: the plan's `max` ran out).
    pub converged: bool,
    /// The share of the light the last one added.
    pub added: f32,
}

impl std::fmt::Display for Convergence {
    /// `4 bounces, the last adding 0.8% of the light`, and `: not converged` when the plan's
    /// bounces ran out first.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let plural = if self.bounces == 1 { "" } else { "s" };
        write!(
            f,
            "{} bounce{plural}, the last adding {:.1}% of the light{}",
            self.bounces,
            100.0 * self.added,
            if self.converged {
                ""
            } else {
                ": not converged"
            }
        )
    }
}

/// `ConvergeParams` of `converge.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ConvergeParams {
    fraction: f32,
    start: u32,
    work_index: u32,
    hold_groups: u32,
    mean_index: u32,
    mean_count: u32,
    count: u32,
    bounce: u32,
    additive: u32,
    _pad: [u32; 3],
}

/// `ConvergeState` of `converge.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ConvergeState {
    done: u32,
    bounces: u32,
    added: f32,
    _pad: u32,
    light: [f32; 4],
}

/// Where a method's solution and its light are, for [`ConvergeGpu`].
pub struct ConvergeInputs<'a> {
    /// The solution after bounce `k` is `solution[k % 2]`: a method that iterates between two
    /// buffers names both, one that updates a buffer in place names it twice.
    pub solution: [&'a wgpu::Buffer; 2],
    /// Elements of each buffer of a pair (the copy that holds a converged solution in both);
    /// `None` for a solution updated in place.
    pub held: Option<u32>,
    /// The light is the sum of the solution's `vec4f`s from `mean.0`, `mean.1` of them.
    pub mean: (u32, u32),
    /// Whether that sum is the bounce's own light, added to the light so far (a method that
    /// keeps each bounce's light apart), rather than the light so far.
    pub additive: bool,
    /// A bounce's main dispatch arguments as the method computes them: a buffer of `u32`
    /// words (`STORAGE`) and the index of the first of the three. `None` for a method whose
    /// kernels read [`ConvergeGpu::state`] and do nothing once converged (its dispatches are
    /// direct, so the arguments the test copies go unused).
    pub work_args: Option<(&'a wgpu::Buffer, u32)>,
}

/// The GPU side of a [`BouncePlan`]: see the module docs.
pub struct ConvergeGpu {
    plan: BouncePlan,
    state: wgpu::Buffer,
    args: wgpu::Buffer,
    check: wgpu::ComputePipeline,
    hold: wgpu::ComputePipeline,
    /// Index 0 starts; index `k` checks bounce `k`.
    groups: Vec<wgpu::BindGroup>,
    /// `hold`'s after bounce `k` (its own: the arguments it is dispatched with cannot be bound
    /// in the same dispatch); empty for a solution updated in place.
    hold_groups: Vec<wgpu::BindGroup>,
}

impl ConvergeGpu {
    /// The test of `plan` over `inputs`.
    pub fn new(device: &wgpu::Device, plan: BouncePlan, inputs: &ConvergeInputs) -> Self {
        let state = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("converge state"),
            size: size_of::<ConvergeState>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let args = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("converge dispatch arguments"),
            size: 24,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
            mapped_at_creation: false,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let bind_layout = layout::bind_group_layout(
            device,
            "converge",
            &[
                layout::uniform(0, c),
                layout::storage(1, true, c),
                layout::storage(2, false, c),
                layout::storage(3, false, c),
                layout::storage(4, true, c),
            ],
        );
        let hold_layout = layout::bind_group_layout(
            device,
            "converge hold",
            &[
                layout::uniform(0, c),
                layout::storage(1, true, c),
                layout::storage(5, false, c),
            ],
        );
        let module = SHADER.create(device);
        let check =
            layout::compute_pipeline_entry(device, "converge", &module, "check", &[&bind_layout]);
        let hold = layout::compute_pipeline_entry(
            device,
            "converge hold",
            &module,
            "hold",
            &[&hold_layout],
        );
        let none;
        let (work_args, work_index) = match inputs.work_args {
            Some(given) => given,
            None => {
                none = crate::load::storage_buffer(
                    device,
                    "converge arguments (none)",
                    bytemuck::cast_slice(&[0u32; 3]),
                );
                (&none, 0)
            }
        };
        let mut groups = Vec::new();
        let mut hold_groups = Vec::new();
        for k in 0..=plan.max {
            let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("converge params"),
                contents: bytemuck::bytes_of(&ConvergeParams {
                    fraction: plan.fraction,
                    start: u32::from(k == 0),
                    work_index,
                    hold_groups: inputs.held.map_or(0, shaders::groups_1d),
                    mean_index: inputs.mean.0,
                    mean_count: inputs.mean.1,
                    count: inputs.held.unwrap_or(0),
                    bounce: k,
                    additive: u32::from(inputs.additive),
                    _pad: [0; 3],
                }),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            // Bounce k wrote buffer k % 2 from buffer (k - 1) % 2.
            let after = (k % 2) as usize;
            groups.push(layout::bind_group_at(
                device,
                "converge",
                &bind_layout,
                &[
                    (0, params.as_entire_binding()),
                    (1, inputs.solution[after].as_entire_binding()),
                    (2, state.as_entire_binding()),
                    (3, args.as_entire_binding()),
                    (4, work_args.as_entire_binding()),
                ],
            ));
            if inputs.held.is_some() {
                hold_groups.push(layout::bind_group_at(
                    device,
                    "converge hold",
                    &hold_layout,
                    &[
                        (0, params.as_entire_binding()),
                        (1, inputs.solution[after].as_entire_binding()),
                        (5, inputs.solution[1 - after].as_entire_binding()),
                    ],
                ));
            }
        }
        Self {
            plan,
            state,
            args,
            check,
            hold,
            groups,
            hold_groups,
        }
    }

    /// The plan.
    pub fn plan(&self) -> BouncePlan {
        self.plan
    }

    /// Records the reset before the first bounce into `pass` (the light so far measured, the
    /// main dispatch's arguments copied).
    pub fn start(&self, pass: &mut wgpu::ComputePass) {
        pass.set_pipeline(&self.check);
        pass.set_bind_group(0, &self.groups[0], &[]);
        pass.dispatch_workgroups(1, 1, 1);
    }

    /// Records the test after bounce `bounce` (1-based, at most the plan's `max`) into `pass`,
    /// and for a pair of buffers the copy that holds a converged solution.
    pub fn check(&self, pass: &mut wgpu::ComputePass, bounce: u32) {
        pass.set_pipeline(&self.check);
        pass.set_bind_group(0, &self.groups[bounce as usize], &[]);
        pass.dispatch_workgroups(1, 1, 1);
        if let Some(group) = self.hold_groups.get(bounce as usize) {
            pass.set_pipeline(&self.hold);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups_indirect(&self.args, 12);
        }
    }

    /// The arguments of the next bounce's main dispatch (zero workgroups once converged).
    pub fn bounce_args(&self) -> &wgpu::Buffer {
        &self.args
    }

    /// The state the test writes, for a method whose kernels read it themselves: its first
    /// word is 1 once converged.
    pub fn state(&self) -> &wgpu::Buffer {
        &self.state
    }

    /// How the last recorded run ended (read back; waits for the GPU).
    ///
    /// # Errors
    /// GPU errors of the read-back.
    pub fn read(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Convergence, RuntimeError> {
        let raw = readback::read_buffer(
            device,
            queue,
            &self.state,
            0,
            size_of::<ConvergeState>() as u64,
        )?;
        let state: ConvergeState = bytemuck::pod_read_unaligned(&raw);
        Ok(Convergence {
            bounces: state.bounces,
            converged: state.done != 0,
            added: state.added,
        })
    }
}

/// The CPU twin of a run: `bounce(k)` computes bounce `k` (1-based) and returns the mean
/// radiance after it; `start` is the mean before the first. Stops as the GPU does.
pub fn run_plan(plan: BouncePlan, start: Vec3, mut bounce: impl FnMut(u32) -> Vec3) -> Convergence {
    let mut before = start;
    let mut ended = Convergence {
        bounces: 0,
        converged: false,
        added: 0.0,
    };
    for k in 1..=plan.max {
        let after = bounce(k);
        ended = Convergence {
            bounces: k,
            converged: plan.ends(before, after),
            added: added_fraction(before, after),
        };
        if ended.converged {
            break;
        }
        before = after;
    }
    ended
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A geometric series of albedo `rho`: bounce `k` adds `rho^k`.
    fn series(rho: f32, plan: BouncePlan) -> Convergence {
        let mut mean = Vec3::ONE;
        run_plan(plan, mean, |k| {
            mean += Vec3::splat(rho.powi(k as i32));
            mean
        })
    }

    #[test]
    fn a_run_stops_at_the_first_bounce_adding_at_most_the_fraction() {
        // rho 0.5: bounce k adds 0.5^k of a total 2 - 0.5^k; 0.5^6 / 1.98 = 0.8% <= 1%.
        let ended = series(0.5, BouncePlan::converged());
        assert_eq!((ended.bounces, ended.converged), (6, true), "{ended:?}");
        assert!(ended.added <= CONVERGED_FRACTION);
        // A bright room runs out of bounces first, and says so.
        let bright = series(0.95, BouncePlan::converged());
        assert_eq!((bright.bounces, bright.converged), (MAX_BOUNCES, false));
        assert!(bright.to_string().contains("not converged"), "{bright}");
        // Exactly n: every bounce runs, whatever it adds.
        let exact = series(0.1, BouncePlan::from_option(3));
        assert_eq!((exact.bounces, exact.converged), (3, false));
        // No light: nothing to add, converged after the first.
        let dark = run_plan(BouncePlan::converged(), Vec3::ZERO, |_| Vec3::ZERO);
        assert_eq!((dark.bounces, dark.converged), (1, true));
        assert_eq!(BouncePlan::from_option(0), BouncePlan::converged());
        assert_eq!(BouncePlan::converged().one_fewer().max, MAX_BOUNCES - 1);
    }

    #[test]
    fn params_and_state_layouts_match_wgsl() {
        use std::mem::offset_of;
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "ConvergeParams",
            size_of::<ConvergeParams>(),
            &[
                ("fraction", offset_of!(ConvergeParams, fraction)),
                ("work_index", offset_of!(ConvergeParams, work_index)),
                ("mean_count", offset_of!(ConvergeParams, mean_count)),
                ("bounce", offset_of!(ConvergeParams, bounce)),
                ("additive", offset_of!(ConvergeParams, additive)),
            ],
        );
        crate::shaders::tests::check_struct(
            &module,
            "ConvergeState",
            size_of::<ConvergeState>(),
            &[
                ("bounces", offset_of!(ConvergeState, bounces)),
                ("added", offset_of!(ConvergeState, added)),
                ("light", offset_of!(ConvergeState, light)),
            ],
        );
    }
}
