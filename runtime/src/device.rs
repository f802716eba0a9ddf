//! A headless wgpu device: the GPU when there is one, Mesa's lavapipe (a Vulkan CPU
//! implementation) where there is none.

use std::sync::{Arc, Mutex};

use crate::RuntimeError;

/// The least a device must allow for every method to build: WebGPU's default limits, but 64
/// bytes of colour attachments per sample (the G-buffer's four `Rgba32Float` targets) and 12
/// storage buffers per stage (the radiosity gather of `hrc`, `lightmap` and `lightcuts`: the
/// CSSM query's and its own; the other methods keep to the default 8). A caller that creates
/// its own device asks for at least these (`tests/gpu/methods.rs` builds every method on a
/// device of exactly these).
///
/// ```
/// let limits = cssm_runtime::required_limits();
/// assert_eq!(limits.max_storage_buffers_per_shader_stage, 12);
/// ```
pub fn required_limits() -> wgpu::Limits {
    wgpu::Limits {
        max_color_attachment_bytes_per_sample: 64,
        max_storage_buffers_per_shader_stage: 12,
        ..Default::default()
    }
}

/// The bytes of GPU memory `device`'s buffers and textures hold now, as wgpu's allocator counts
/// them (wgpu's `counters` feature; each resource's own allocation, not the blocks around it).
/// The difference before and after a [`crate::Renderer`] is built and renders is the memory it
/// holds. 0 on a backend that does not count (WebGPU, GL).
///
/// ```no_run
/// # fn demo(device: &wgpu::Device) {
/// let before = cssm_runtime::gpu_memory_bytes(device);
/// // ... build a renderer and render a frame ...
/// let held = cssm_runtime::gpu_memory_bytes(device).saturating_sub(before);
/// # }
/// ```
pub fn gpu_memory_bytes(device: &wgpu::Device) -> u64 {
    let hal = device.get_internal_counters().hal;
    (hal.buffer_memory.read() + hal.texture_memory.read()).max(0) as u64
}

/// A device and queue with what the runtime learned about them.
pub struct Gpu {
    /// The adapter the device was created on.
    pub adapter: wgpu::Adapter,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The first GPU error wgpu reported outside an error scope since the last [`Gpu::wait`]
    /// (wgpu would otherwise panic on it).
    errors: Arc<Mutex<Option<String>>>,
}

impl Gpu {
    /// Opens the first high-performance adapter (Vulkan, Metal or DX12; `WGPU_BACKEND` and
    /// `WGPU_ADAPTER_NAME` override) with the adapter's own limits, so that large `.cssm` files
    /// fit, and GPU timestamps where the adapter has them.
    ///
    /// # Errors
    /// [`RuntimeError::NoAdapter`] when no adapter is found (the message says how to install
    /// lavapipe), [`RuntimeError::NoDevice`] when the adapter refuses.
    pub fn new_headless() -> Result<Self, RuntimeError> {
        let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle();
        descriptor.backends = wgpu::Backends::PRIMARY;
        let instance = wgpu::Instance::new(descriptor.with_env());
        Self::for_surface(&instance, None)
    }

    /// As [`Gpu::new_headless`] (the same adapter choice, features and limits, so a window
    /// renders what an offscreen render does, byte for byte), on `instance`, with an adapter
    /// that can present to `surface` when one is given (a window's: `cssm view`).
    ///
    /// # Errors
    /// As [`Gpu::new_headless`]; no adapter when none can present to `surface`.
    pub fn for_surface(
        instance: &wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Self, RuntimeError> {
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: surface,
            apply_limit_buckets: false,
        }))
        .map_err(|e| RuntimeError::NoAdapter(e.to_string()))?;
        let wanted = wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::FLOAT32_FILTERABLE;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("cssm"),
            required_features: adapter.features() & wanted,
            required_limits: adapter.limits(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| RuntimeError::NoDevice {
            adapter: adapter.get_info().name,
            reason: e.to_string(),
        })?;
        Ok(Self::from_device(adapter, device, queue))
    }

    /// A device of your own (say, one requested with other limits) with the runtime's error
    /// capture: GPU errors outside an error scope are kept for [`Gpu::wait`] instead of
    /// panicking, and a device loss is reported by it (this sets the device's uncaptured-error
    /// handler and its device-lost callback).
    ///
    /// ```no_run
    /// # fn demo(adapter: wgpu::Adapter) {
    /// let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
    ///     required_limits: cssm_runtime::required_limits(),
    ///     ..Default::default()
    /// }))
    /// .expect("device");
    /// let gpu = cssm_runtime::Gpu::from_device(adapter, device, queue);
    /// # let _ = gpu; }
    /// ```
    pub fn from_device(adapter: wgpu::Adapter, device: wgpu::Device, queue: wgpu::Queue) -> Self {
        let errors = Arc::new(Mutex::new(None));
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let mut slot = sink.lock().unwrap_or_else(|p| p.into_inner());
            slot.get_or_insert_with(|| e.to_string());
        }));
        // A lost device is the cause of whatever failed after it: its message wins.
        let sink = errors.clone();
        device.set_device_lost_callback(move |reason, message| {
            let mut slot = sink.lock().unwrap_or_else(|p| p.into_inner());
            *slot = Some(format!("the GPU device was lost ({reason:?}): {message}"));
        });
        Self {
            adapter,
            device,
            queue,
            errors,
        }
    }

    /// "name (backend, driver)" of the adapter.
    pub fn describe(&self) -> String {
        let info = self.adapter.get_info();
        format!(
            "{} ({:?}, {} {})",
            info.name, info.backend, info.driver, info.driver_info
        )
    }

    /// Whether the device can time passes with timestamp queries.
    pub fn has_timestamps(&self) -> bool {
        self.device
            .features()
            .contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// Waits for all submitted work and turns any GPU error captured since the last call into
    /// an error.
    pub fn wait(&self) -> Result<(), RuntimeError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RuntimeError::Gpu(e.to_string()))?;
        let mut slot = self.errors.lock().unwrap_or_else(|p| p.into_inner());
        match slot.take() {
            Some(e) => Err(RuntimeError::Gpu(e)),
            None => Ok(()),
        }
    }
}
