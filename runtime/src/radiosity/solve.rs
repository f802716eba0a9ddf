//! The radiosity solved once and read back: what the CPU references, the lab and the tests
//! compare (the view-independent part of a frame, [`AtlasGi`], on its own).

use cssm_formats::{CssmFile, Scene};
use glam::Affine3A;

use super::{AtlasGi, FarField, RadiosityOptions, cpu::FarSplit};
use crate::{
    RuntimeError,
    common::{converge::BouncePlan, converge::Convergence, readback, timestamps::PassTimer},
    frame::{FrameContext, FrameEncoder, FrameSettings},
};

/// Direct light in the atlas texels of `file` (baked from `scene`): diffuse radiance leaving
/// each texel, in texel order.
///
/// # Errors
/// As [`atlas_radiosity`].
pub fn render_atlas_direct(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    scene: &Scene,
    file: &CssmFile,
    shadow_resolution: u32,
) -> Result<Vec<[f32; 4]>, RuntimeError> {
    let options = RadiosityOptions::default();
    let solved = atlas_radiosity(device, queue, scene, file, shadow_resolution, 0, options)?;
    Ok(solved.direct)
}

/// The radiosity solution in the atlas, read back (what the view-independent part of a frame
/// computes).
#[derive(Clone, Debug)]
pub struct AtlasRadiosity {
    /// Direct radiance leaving every texel (texel order, rgb).
    pub direct: Vec<[f32; 4]>,
    /// Indirect irradiance of every texel after the iterations (texel order, rgb).
    pub irradiance: Vec<[f32; 4]>,
    /// Mean radiance of every hierarchy node after the iterations (rgb).
    pub node_radiance: Vec<[f32; 4]>,
    /// How many bounces ran.
    pub convergence: Convergence,
    /// GPU milliseconds per pass, empty without timestamps.
    pub timings: Vec<(&'static str, f64)>,
}

/// Runs the direct light into the atlas and the radiosity bounces (§4.1-§4.3) of `iterations`
/// (a count, or [`BouncePlan::converged`]) on `file` (baked from `scene`), and reads the
/// solution back.
///
/// # Errors
/// Unsupported lights, buffers beyond the device's limits, GPU errors.
pub fn atlas_radiosity(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    scene: &Scene,
    file: &CssmFile,
    shadow_resolution: u32,
    iterations: impl Into<BouncePlan>,
    options: RadiosityOptions,
) -> Result<AtlasRadiosity, RuntimeError> {
    atlas_radiosity_posed(
        device,
        queue,
        scene,
        file,
        shadow_resolution,
        iterations,
        options,
        &[],
    )
}

/// [`atlas_radiosity`] with objects moved first: each `(index, transform)` of `placed` puts
/// object `index` at `transform` (object to world, [`FrameContext::place_object`]), so its
/// texels receive, send and gather where it stands (§3.3).
///
/// # Errors
/// As [`atlas_radiosity`], and a placement [`FrameContext::place_object`] refuses.
#[allow(clippy::too_many_arguments)]
pub fn atlas_radiosity_posed(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    scene: &Scene,
    file: &CssmFile,
    shadow_resolution: u32,
    iterations: impl Into<BouncePlan>,
    options: RadiosityOptions,
    placed: &[(usize, Affine3A)],
) -> Result<AtlasRadiosity, RuntimeError> {
    let mut ctx = solve_context(device, queue, scene, file, shadow_resolution)?;
    for &(index, transform) in placed {
        ctx.place_object(index, transform)?;
    }
    let mut gi = AtlasGi::new(&ctx, file, options, iterations.into())?;
    solve_once(&ctx, &mut gi)
}

/// One solve of [`atlas_radiosity_lights`].
pub struct LinkedSolve {
    /// The solution.
    pub solved: AtlasRadiosity,
    /// How many links the bounces multiplied (`None`: the bounces walked).
    pub links: Option<u64>,
    /// The receivers the solve before found stale, and its re-cuts that overflowed
    /// ([`super::Radiosity::stale_links`]), as read back before this one.
    pub stale_before: (u32, u32),
    /// Wall-clock milliseconds of the solve: recorded, submitted, waited for and read back.
    pub wall_ms: f64,
    /// `lightcuts`' far field after the solve, where asked.
    pub far: Option<FarSolve>,
}

/// The far field of one [`LinkedSolve`] ([`super::FarField`], as `lightcuts` runs it).
pub struct FarSolve {
    /// Per texel, its far-field irradiance (texel order, rgb).
    pub irradiance: Vec<[f32; 4]>,
    /// How many links its product multiplied (`None`: it walked).
    pub links: Option<u64>,
    /// The receivers its pass before found stale, and the re-cuts that overflowed.
    pub stale_before: (u32, u32),
}

/// [`atlas_radiosity`] once per entry of `lights` (the scene's spot lights each time: a
/// light moved between solves), all with one [`AtlasGi`] as a renderer keeps it: the first
/// solve walks, the second builds the cached links for the first one's result and
/// multiplies them, the later ones re-cut where the products before found the cuts stale
/// ([`super::Radiosity::update_links`]). With `links` false every bounce walks. With `far`,
/// each solve ends with `lightcuts`' far field of that split, its links cached the same way.
///
/// # Errors
/// As [`atlas_radiosity`], and a light the shadow maps cannot hold.
#[allow(clippy::too_many_arguments)]
pub fn atlas_radiosity_lights(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    scene: &Scene,
    file: &CssmFile,
    shadow_resolution: u32,
    iterations: impl Into<BouncePlan>,
    (options, links, far): (RadiosityOptions, bool, Option<FarSplit>),
    lights: &[Vec<cssm_formats::scene::SpotLight>],
) -> Result<Vec<LinkedSolve>, RuntimeError> {
    let ctx = solve_context(device, queue, scene, file, shadow_resolution)?;
    let mut gi = AtlasGi::new(&ctx, file, options, iterations.into())?;
    if !links {
        gi.radiosity.walk_always();
    }
    let mut far = match far {
        Some(split) => Some(gi.radiosity.far_field(device, ctx.cssm()?, split)),
        None => None,
    };
    let mut solves = Vec::with_capacity(lights.len());
    for set in lights {
        let gpu: Result<Vec<_>, _> = set
            .iter()
            .map(|l| {
                crate::common::shadow_map::gpu_light(
                    &scene.name,
                    l,
                    scene.bounds(),
                    shadow_resolution,
                )
            })
            .collect();
        ctx.shadows.update(queue, &gpu?);
        let start = std::time::Instant::now();
        let solved = solve_with(&ctx, &mut gi, far.as_mut())?;
        let far = match &far {
            Some(far) => Some(FarSolve {
                irradiance: read_vec4s(
                    &ctx,
                    &far.irradiance,
                    16 * u64::from(gi.atlas.texel_count),
                )?,
                links: far.link_count(),
                stale_before: far.stale_links(),
            }),
            None => None,
        };
        solves.push(LinkedSolve {
            solved,
            links: gi.radiosity.link_count(),
            stale_before: gi.radiosity.stale_links(),
            wall_ms: start.elapsed().as_secs_f64() * 1e3,
            far,
        });
    }
    Ok(solves)
}

/// The frame context of a solve: `file` (baked from `scene`) loaded with shadow maps of
/// `shadow_resolution`, a one-pixel image, exposure 1.
fn solve_context(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    scene: &Scene,
    file: &CssmFile,
    shadow_resolution: u32,
) -> Result<FrameContext, RuntimeError> {
    let settings = FrameSettings {
        width: 1,
        height: 1,
        exposure: 1.0,
        shadow_resolution,
        ..FrameSettings::default()
    };
    FrameContext::new(device, queue, scene, Some(file), settings, false)
}

/// Records the shadow maps and `gi`'s passes, submits them and reads the solution back.
fn solve_once(ctx: &FrameContext, gi: &mut AtlasGi) -> Result<AtlasRadiosity, RuntimeError> {
    solve_with(ctx, gi, None)
}

/// `bytes` bytes of `buffer` read back as `vec4f`s.
fn read_vec4s(
    ctx: &FrameContext,
    buffer: &wgpu::Buffer,
    bytes: u64,
) -> Result<Vec<[f32; 4]>, RuntimeError> {
    let raw = readback::read_buffer(&ctx.device, &ctx.queue, buffer, 0, bytes)?;
    Ok(bytemuck::cast_slice(&raw).to_vec())
}

/// [`solve_once`], then `far`'s pass as `lightcuts` records it (its links updated before the
/// iteration).
fn solve_with(
    ctx: &FrameContext,
    gi: &mut AtlasGi,
    mut far: Option<&mut FarField>,
) -> Result<AtlasRadiosity, RuntimeError> {
    let (device, queue) = (&ctx.device, &ctx.queue);
    let mut timer = PassTimer::new(device, queue);
    let mut encoder = device.create_command_encoder(&Default::default());
    let mut frame = FrameEncoder {
        encoder: &mut encoder,
        timer: &mut timer,
        index: 0,
    };
    ctx.shadows.render(&mut frame, &ctx.scene);
    let cssm = ctx.cssm()?;
    if let Some(far) = far.as_deref_mut() {
        far.update_links(device, queue, cssm, &mut frame);
    }
    gi.run(ctx, &mut frame);
    if let Some(far) = far {
        far.run(&mut frame, cssm);
    }
    timer.resolve(&mut encoder);
    queue.submit([encoder.finish()]);
    let timings = timer.read(device, queue)?;
    let (atlas, radiosity) = (&gi.atlas, &gi.radiosity);
    let texels = 16 * atlas.texel_count as u64;
    let read = |buffer: &wgpu::Buffer, bytes: u64| read_vec4s(ctx, buffer, bytes);
    let node_count = ctx.cssm()?.hierarchy.node_count as u64;
    Ok(AtlasRadiosity {
        direct: read(&atlas.texel_radiance, texels)?,
        irradiance: read(&radiosity.texel_irradiance, texels)?,
        node_radiance: read(radiosity.radiance(), 16 * node_count)?,
        convergence: radiosity.convergence(device, queue)?,
        timings,
    })
}
