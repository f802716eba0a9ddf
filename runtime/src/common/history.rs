//! A frame's history for the passes that reproject (temporal filtering, Soler et al. 2010 §4,
//! Eq. 6): the previous frame's camera and its G-buffer position and normal, so that a pixel's
//! world point can be found in the previous frame and checked to be the same surface. A
//! technique that filters over time keeps one, beside its own history of the filtered signal,
//! and records it at the end of each of its frames ([`FrameHistory::record`]).

use crate::{
    common::{gbuffer::GBuffer, layout},
    gpu_types::GpuView,
};

/// The previous frame's camera and G-buffer position and normal.
pub struct FrameHistory {
    previous: Option<GpuView>,
    /// The previous frame's world positions (w 1 where covered), as the G-buffer's.
    pub position: wgpu::Texture,
    /// The previous frame's normals (w material), as the G-buffer's.
    pub normal: wgpu::Texture,
}

fn texture(device: &wgpu::Device, label: &str, size: (u32, u32)) -> wgpu::Texture {
    let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
    layout::texture_2d(
        device,
        label,
        size,
        crate::common::gbuffer::TARGET_FORMAT,
        usage,
    )
}

impl FrameHistory {
    /// An empty history for a G-buffer of `size`.
    pub fn new(device: &wgpu::Device, size: (u32, u32)) -> Self {
        Self {
            previous: None,
            position: texture(device, "history position", size),
            normal: texture(device, "history normal", size),
        }
    }

    /// The previous frame's view constants; `None` before the first frame recorded and after
    /// a resize.
    pub fn previous(&self) -> Option<&GpuView> {
        self.previous.as_ref()
    }

    /// Records, at the end of a frame of `view` (after every pass that reads the history),
    /// the copy of `gbuffer`'s position and normal into the history.
    pub fn record(&mut self, encoder: &mut wgpu::CommandEncoder, gbuffer: &GBuffer, view: GpuView) {
        let extent = gbuffer.position.size();
        for (from, to) in [
            (&gbuffer.position, &self.position),
            (&gbuffer.normal, &self.normal),
        ] {
            encoder.copy_texture_to_texture(from.as_image_copy(), to.as_image_copy(), extent);
        }
        self.previous = Some(view);
    }

    /// An empty history for a G-buffer of the new `size`.
    pub fn resize(&mut self, device: &wgpu::Device, size: (u32, u32)) {
        *self = Self::new(device, size);
    }
}
