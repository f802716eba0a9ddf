//! Direct light from spot lights with shadow maps (§4.7): per pixel from the G-buffer
//! ([`ScreenDirect`], `shade.wgsl`) and per atlas texel ([`AtlasDirect`], `atlas.wgsl`), the
//! radiance the indirect bounces start from. Both call `light.wgsl`.
//!
//! CPU reference: [`cpu`], the same shading with exact ray-cast shadows. The two differ only
//! at shadow edges, where the shadow map's PCF blurs what the ray cast decides sharply, and
//! where the shadow map's resolution and its normal offset move an edge by a texel; the test
//! `direct_light_matches_cpu_reference` measures the difference away from those edges.
//!
//! Parameters: shadow-map resolution ([`crate::common::shadow_map::DEFAULT_RESOLUTION`], 2048
//! texels; 1024 is enough for the Cornell box at 640x480). Fails for spot cones wider than
//! [`crate::common::shadow_map::MAX_CUTOFF_DEG`].

pub mod cpu;

use crate::{
    common::{gbuffer::GBuffer, layout, shadow_map::ShadowMaps, timestamps::PassTimer},
    gpu_types::TYPES_WGSL,
    load::{CssmGpu, SceneGpu},
};

/// WGSL of the shared light model, after the types and the shadow lookup.
fn light_wgsl() -> String {
    format!(
        "{TYPES_WGSL}\n{}\n{}",
        crate::common::shadow_map::LOOKUP_WGSL,
        include_str!("light.wgsl")
    )
}

/// Layout entries 0 to 4 of both passes: view, materials, lights, shadow maps, sampler.
fn light_entries() -> [wgpu::BindGroupLayoutEntry; 5] {
    let c = wgpu::ShaderStages::COMPUTE;
    [
        layout::uniform(0, c),
        layout::storage(1, true, c),
        layout::storage(2, true, c),
        layout::depth_array(3, c),
        layout::comparison_sampler(4, c),
    ]
}

fn light_resources<'a>(
    view: &'a wgpu::Buffer,
    scene: &'a SceneGpu,
    shadows: &'a ShadowMaps,
) -> [wgpu::BindingResource<'a>; 5] {
    [
        view.as_entire_binding(),
        scene.materials.as_entire_binding(),
        shadows.lights.as_entire_binding(),
        wgpu::BindingResource::TextureView(&shadows.view),
        wgpu::BindingResource::Sampler(&shadows.sampler),
    ]
}

/// Direct light per pixel into an `Rgba32Float` radiance texture.
pub struct ScreenDirect {
    /// Linear radiance per pixel.
    pub radiance: wgpu::Texture,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    size: (u32, u32),
}

impl ScreenDirect {
    /// The pass shading `gbuffer`.
    pub fn new(
        device: &wgpu::Device,
        view: &wgpu::Buffer,
        scene: &SceneGpu,
        shadows: &ShadowMaps,
        gbuffer: &GBuffer,
    ) -> Self {
        let (w, h) = (gbuffer.position.width(), gbuffer.position.height());
        let radiance = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("direct radiance"),
            size: gbuffer.position.size(),
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let module = layout::shader(
            device,
            "direct screen",
            light_wgsl() + include_str!("shade.wgsl"),
        );
        let c = wgpu::ShaderStages::COMPUTE;
        let d2 = wgpu::TextureViewDimension::D2;
        let mut entries = light_entries().to_vec();
        entries.extend([
            layout::texture(5, d2, c),
            layout::texture(6, d2, c),
            layout::texture(7, d2, c),
            layout::storage_texture(8, wgpu::TextureFormat::Rgba32Float, c),
        ]);
        let bind_layout = layout::bind_group_layout(device, "direct screen", &entries);
        let pipeline = layout::compute_pipeline(device, "direct screen", &module, &[&bind_layout]);
        let views = [
            &gbuffer.position,
            &gbuffer.normal,
            &gbuffer.albedo,
            &radiance,
        ]
        .map(|t| t.create_view(&Default::default()));
        let mut resources = light_resources(view, scene, shadows).to_vec();
        resources.extend(views.iter().map(wgpu::BindingResource::TextureView));
        let bind_group = layout::bind_group(device, "direct screen", &bind_layout, &resources);
        Self {
            radiance,
            pipeline,
            bind_group,
            size: (w, h),
        }
    }

    /// Records the pass.
    pub fn run(&self, encoder: &mut wgpu::CommandEncoder, timer: &mut PassTimer) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("direct screen"),
            timestamp_writes: timer.compute("direct light"),
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.dispatch_workgroups(self.size.0.div_ceil(8), self.size.1.div_ceil(8), 1);
    }
}

/// Direct light into the atlas texels of a loaded CSSM: one `vec4f` per texel (rgb: diffuse
/// radiance leaving the texel's front side), in texel order.
pub struct AtlasDirect {
    /// The radiance per texel (`STORAGE | COPY_SRC`).
    pub texel_radiance: wgpu::Buffer,
    /// Number of texels.
    pub texel_count: u32,
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
}

impl AtlasDirect {
    /// The pass over the texels of `cssm`.
    pub fn new(
        device: &wgpu::Device,
        view: &wgpu::Buffer,
        scene: &SceneGpu,
        shadows: &ShadowMaps,
        cssm: &CssmGpu,
    ) -> Self {
        let texel_count = cssm.params.map_count;
        let texel_radiance = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("texel radiance"),
            size: 16 * texel_count.max(1) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let module = layout::shader(
            device,
            "direct atlas",
            light_wgsl() + include_str!("atlas.wgsl"),
        );
        let c = wgpu::ShaderStages::COMPUTE;
        let mut entries = light_entries().to_vec();
        entries.extend([layout::storage(5, true, c), layout::storage(6, false, c)]);
        let bind_layout = layout::bind_group_layout(device, "direct atlas", &entries);
        let pipeline = layout::compute_pipeline(device, "direct atlas", &module, &[&bind_layout]);
        let mut resources = light_resources(view, scene, shadows).to_vec();
        resources.extend([
            cssm.texels.as_entire_binding(),
            texel_radiance.as_entire_binding(),
        ]);
        let bind_group = layout::bind_group(device, "direct atlas", &bind_layout, &resources);
        Self {
            texel_radiance,
            texel_count,
            pipeline,
            bind_group,
        }
    }

    /// Records the pass.
    pub fn run(&self, encoder: &mut wgpu::CommandEncoder, timer: &mut PassTimer) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("direct atlas"),
            timestamp_writes: timer.compute("direct light into atlas"),
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.dispatch_workgroups(self.texel_count.max(1).div_ceil(64), 1, 1);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn shaders_validate_with_naga() {
        crate::tests::validate_wgsl(
            "direct/shade",
            &(super::light_wgsl() + include_str!("shade.wgsl")),
        );
        crate::tests::validate_wgsl(
            "direct/atlas",
            &(super::light_wgsl() + include_str!("atlas.wgsl")),
        );
    }
}
