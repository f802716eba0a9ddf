//! Short constructors for bind group layouts and bind groups, so passes declare what they read
//! and write in one line per binding.

use wgpu::{BindGroupLayoutEntry, BindingType, ShaderStages};

fn entry(binding: u32, visibility: ShaderStages, ty: BindingType) -> BindGroupLayoutEntry {
    BindGroupLayoutEntry {
        binding,
        visibility,
        ty,
        count: None,
    }
}

/// A uniform buffer.
pub fn uniform(binding: u32, visibility: ShaderStages) -> BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
    )
}

/// A storage buffer.
pub fn storage(binding: u32, read_only: bool, visibility: ShaderStages) -> BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
    )
}

/// An unfilterable float texture (read with `textureLoad`).
pub fn texture(
    binding: u32,
    dimension: wgpu::TextureViewDimension,
    visibility: ShaderStages,
) -> BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: dimension,
            multisampled: false,
        },
    )
}

/// A depth texture array (shadow maps).
pub fn depth_array(binding: u32, visibility: ShaderStages) -> BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Depth,
            view_dimension: wgpu::TextureViewDimension::D2Array,
            multisampled: false,
        },
    )
}

/// A comparison sampler.
pub fn comparison_sampler(binding: u32, visibility: ShaderStages) -> BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
    )
}

/// A write-only 2D storage texture of `format`.
pub fn storage_texture(
    binding: u32,
    format: wgpu::TextureFormat,
    visibility: ShaderStages,
) -> BindGroupLayoutEntry {
    storage_texture_of(binding, format, wgpu::TextureViewDimension::D2, visibility)
}

/// A write-only storage texture of `format` and `dimension`.
pub fn storage_texture_of(
    binding: u32,
    format: wgpu::TextureFormat,
    dimension: wgpu::TextureViewDimension,
    visibility: ShaderStages,
) -> BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format,
            view_dimension: dimension,
        },
    )
}

/// A filterable float texture (read with `textureSample*` through a filtering sampler).
pub fn filterable_texture(
    binding: u32,
    dimension: wgpu::TextureViewDimension,
    visibility: ShaderStages,
) -> BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: dimension,
            multisampled: false,
        },
    )
}

/// A filtering sampler.
pub fn filtering_sampler(binding: u32, visibility: ShaderStages) -> BindGroupLayoutEntry {
    entry(
        binding,
        visibility,
        BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
    )
}

/// A bind group layout of `entries`.
pub fn bind_group_layout(
    device: &wgpu::Device,
    label: &str,
    entries: &[BindGroupLayoutEntry],
) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries,
    })
}

/// A bind group with `resources` at bindings 0, 1, 2, ...
pub fn bind_group(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: &[wgpu::BindingResource],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = resources
        .iter()
        .enumerate()
        .map(|(i, resource)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource: resource.clone(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// A bind group of `resources` at the given bindings, for an entry point that uses some of a
/// module's bindings only.
pub fn bind_group_at(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: &[(u32, wgpu::BindingResource)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = resources
        .iter()
        .map(|(binding, resource)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: resource.clone(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

/// A compute pipeline running the entry point `main` of `module` with `layouts` at groups
/// 0, 1, ...
pub fn compute_pipeline(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    layouts: &[&wgpu::BindGroupLayout],
) -> wgpu::ComputePipeline {
    compute_pipeline_entry(device, label, module, "main", layouts)
}

/// A compute pipeline running the entry point `entry` of `module` (a module with several
/// kernels) with `layouts` at groups 0, 1, ...
pub fn compute_pipeline_entry(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    entry: &str,
    layouts: &[&wgpu::BindGroupLayout],
) -> wgpu::ComputePipeline {
    let layouts: Vec<Option<&wgpu::BindGroupLayout>> = layouts.iter().map(|l| Some(*l)).collect();
    compute_pipeline_with_gaps(device, label, module, entry, &layouts)
}

/// [`compute_pipeline_entry`] where some groups are unused (`None`: the module reads none of
/// its bindings and the pass binds nothing there), e.g. a pass reading the moving objects'
/// group (`shaders::MOVING_GROUP`) without the CSSM library's before it.
pub fn compute_pipeline_with_gaps(
    device: &wgpu::Device,
    label: &str,
    module: &wgpu::ShaderModule,
    entry: &str,
    layouts: &[Option<&wgpu::BindGroupLayout>],
) -> wgpu::ComputePipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: layouts,
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// A 2D texture of `width` x `height`, one mip level, one sample.
pub fn texture_2d(
    device: &wgpu::Device,
    label: &str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}

/// An `Rgba32Float` texture of `size` that a compute pass writes (storage), later passes read
/// (`textureLoad`) and read-back copies: the per-pixel radiance of the passes.
pub fn radiance_texture(device: &wgpu::Device, label: &str, size: wgpu::Extent3d) -> wgpu::Texture {
    let usage = wgpu::TextureUsages::STORAGE_BINDING
        | wgpu::TextureUsages::TEXTURE_BINDING
        | wgpu::TextureUsages::COPY_SRC;
    let format = wgpu::TextureFormat::Rgba32Float;
    texture_2d(device, label, (size.width, size.height), format, usage)
}

/// A colour attachment of `view` cleared to transparent black and stored: the raster passes'
/// targets (G-buffer, reflective shadow map).
pub fn cleared_colour(view: &wgpu::TextureView) -> Option<wgpu::RenderPassColorAttachment<'_>> {
    Some(wgpu::RenderPassColorAttachment {
        view,
        depth_slice: None,
        resolve_target: None,
        ops: wgpu::Operations {
            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
            store: wgpu::StoreOp::Store,
        },
    })
}

/// A shader module from WGSL source.
pub fn shader(device: &wgpu::Device, label: &str, source: String) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}
