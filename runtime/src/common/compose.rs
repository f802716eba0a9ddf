//! The last pass before tone mapping: a frame's radiance = its direct light per pixel plus its
//! indirect light per pixel, or either part alone (`--component`), in `compose.wgsl`.

use std::{fmt, str::FromStr};

use wgpu::util::DeviceExt;

use crate::{
    common::layout,
    frame::{FrameContext, FrameEncoder},
    shaders,
};

/// `common/compose.wgsl`.
pub const SHADER: crate::shaders::Shader =
    crate::shaders::shader!("compose", "common/compose.wgsl");

/// Which light paths an image holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Component {
    /// Light reaching the first surface straight from the lights (what `direct::cpu` renders).
    Direct = 0,
    /// Light that bounced off one surface or more before the first one: everything but
    /// [`Component::Direct`] (black when `bounces` is 0).
    Indirect = 1,
    /// Both: [`Component::Direct`] plus [`Component::Indirect`].
    #[default]
    Full = 2,
}

impl Component {
    /// Every component, in the order `--help` lists them.
    pub const ALL: [Component; 3] = [Component::Direct, Component::Indirect, Component::Full];

    /// Name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Component::Direct => "direct",
            Component::Indirect => "indirect",
            Component::Full => "full",
        }
    }

    /// One line on what the image holds.
    pub fn describe(self) -> &'static str {
        match self {
            Component::Direct => "direct light only (light -> surface -> eye)",
            Component::Indirect => "indirect light only (at least one bounce)",
            Component::Full => "direct plus indirect light",
        }
    }

    pub(crate) fn has_direct(self) -> bool {
        self != Component::Indirect
    }

    pub(crate) fn has_indirect(self) -> bool {
        self != Component::Direct
    }
}

impl fmt::Display for Component {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Component {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Component::ALL
            .into_iter()
            .find(|c| c.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Component::ALL.iter().map(|c| c.name()).collect();
                format!("unknown component '{s}' (available: {})", names.join(", "))
            })
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ComposeParams {
    component: u32,
    _pad: [u32; 3],
}

/// The compose pass: per pixel direct + indirect (or either alone) into [`Self::radiance`].
pub struct Compose {
    /// Linear radiance per pixel (`Rgba32Float`).
    pub radiance: wgpu::Texture,
    params: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

impl Compose {
    /// The pass adding `direct` (texture) and `indirect` (`vec4f` per pixel), keeping
    /// `component`.
    pub fn new(
        ctx: &FrameContext,
        direct: &wgpu::Texture,
        indirect: &wgpu::Buffer,
        component: Component,
    ) -> Self {
        let device = &ctx.device;
        let params = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("compose params"),
            contents: bytemuck::bytes_of(&ComposeParams {
                component: component as u32,
                _pad: [0; 3],
            }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let c = wgpu::ShaderStages::COMPUTE;
        let module = SHADER.create(device);
        let bind_layout = layout::bind_group_layout(
            device,
            "compose",
            &[
                layout::uniform(0, c),
                layout::uniform(1, c),
                layout::texture(2, wgpu::TextureViewDimension::D2, c),
                layout::storage(3, true, c),
                layout::storage_texture(4, wgpu::TextureFormat::Rgba32Float, c),
            ],
        );
        let pipeline = layout::compute_pipeline(device, "compose", &module, &[&bind_layout]);
        let (radiance, bind_group) = Self::bind(ctx, &bind_layout, &params, direct, indirect);
        Self {
            radiance,
            params,
            pipeline,
            bind_layout,
            bind_group,
            size: (direct.width(), direct.height()),
        }
    }

    fn bind(
        ctx: &FrameContext,
        bind_layout: &wgpu::BindGroupLayout,
        params: &wgpu::Buffer,
        direct: &wgpu::Texture,
        indirect: &wgpu::Buffer,
    ) -> (wgpu::Texture, wgpu::BindGroup) {
        let radiance = layout::radiance_texture(&ctx.device, "radiance", direct.size());
        let direct_view = direct.create_view(&Default::default());
        let out_view = radiance.create_view(&Default::default());
        let bind_group = layout::bind_group(
            &ctx.device,
            "compose",
            bind_layout,
            &[
                params.as_entire_binding(),
                ctx.view.as_entire_binding(),
                wgpu::BindingResource::TextureView(&direct_view),
                indirect.as_entire_binding(),
                wgpu::BindingResource::TextureView(&out_view),
            ],
        );
        (radiance, bind_group)
    }

    /// Reads new inputs of a new size.
    pub fn resize(&mut self, ctx: &FrameContext, direct: &wgpu::Texture, indirect: &wgpu::Buffer) {
        (self.radiance, self.bind_group) =
            Self::bind(ctx, &self.bind_layout, &self.params, direct, indirect);
        self.size = (direct.width(), direct.height());
    }

    /// Records the pass.
    pub fn run(&self, frame: &mut FrameEncoder) {
        let mut pass = frame.compute_pass("compose");
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        let (x, y) = shaders::groups_2d(self.size);
        pass.dispatch_workgroups(x, y, 1);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn compose_params_layout_matches_wgsl() {
        use std::mem::{offset_of, size_of};
        let module = crate::shaders::tests::module(super::SHADER);
        crate::shaders::tests::check_struct(
            &module,
            "ComposeParams",
            size_of::<super::ComposeParams>(),
            &[("component", offset_of!(super::ComposeParams, component))],
        );
    }
}
