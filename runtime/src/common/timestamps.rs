//! GPU time per pass from timestamp queries, where the adapter has them.

use crate::{RuntimeError, common::readback};

/// Up to [`PassTimer::MAX_PASSES`] named passes, each bracketed by two timestamps.
pub struct PassTimer {
    queries: Option<wgpu::QuerySet>,
    resolve: Option<wgpu::Buffer>,
    names: Vec<&'static str>,
    period_ns: f32,
}

impl PassTimer {
    /// Most passes one timer holds.
    pub const MAX_PASSES: u32 = 32;

    /// A timer; inert (every pass untimed) when the device has no timestamp queries.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        let has = device.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let (queries, resolve) = if has {
            let count = 2 * Self::MAX_PASSES;
            (
                Some(device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("pass timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count,
                })),
                Some(device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("pass timestamps resolve"),
                    size: 8 * count as u64,
                    usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })),
            )
        } else {
            (None, None)
        };
        Self {
            queries,
            resolve,
            names: Vec::new(),
            period_ns: queue.get_timestamp_period(),
        }
    }

    /// Whether passes are actually timed.
    pub fn enabled(&self) -> bool {
        self.queries.is_some()
    }

    fn slot(&mut self, name: &'static str) -> Option<(&wgpu::QuerySet, u32)> {
        let queries = self.queries.as_ref()?;
        let index = self.names.len() as u32;
        if index >= Self::MAX_PASSES {
            return None;
        }
        self.names.push(name);
        Some((queries, index))
    }

    /// Timestamp writes for a compute pass called `name`.
    pub fn compute(&mut self, name: &'static str) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        self.slot(name)
            .map(|(query_set, i)| wgpu::ComputePassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: Some(2 * i),
                end_of_pass_write_index: Some(2 * i + 1),
            })
    }

    /// Timestamp writes for a render pass called `name`.
    pub fn render(&mut self, name: &'static str) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        self.slot(name)
            .map(|(query_set, i)| wgpu::RenderPassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: Some(2 * i),
                end_of_pass_write_index: Some(2 * i + 1),
            })
    }

    /// Forgets the passes recorded since the last [`Self::read`] (a frame whose timings nobody
    /// read), so the slots do not run out.
    pub fn begin_frame(&mut self) {
        self.names.clear();
    }

    /// Records the resolve of every timestamp written so far; call before submitting.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        if let (Some(q), Some(b)) = (&self.queries, &self.resolve)
            && !self.names.is_empty()
        {
            encoder.resolve_query_set(q, 0..2 * self.names.len() as u32, b, 0);
        }
    }

    /// Milliseconds of every timed pass, in the order they were recorded, passes of the same
    /// name summed; empty when timestamps are not supported. Call after the work was submitted.
    pub fn read(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Vec<(&'static str, f64)>, RuntimeError> {
        let Some(resolve) = &self.resolve else {
            return Ok(Vec::new());
        };
        if self.names.is_empty() {
            return Ok(Vec::new());
        }
        let bytes = readback::read_buffer(device, queue, resolve, 0, 16 * self.names.len() as u64)?;
        let ticks: &[u64] = bytemuck::cast_slice(&bytes);
        let mut out: Vec<(&'static str, f64)> = Vec::new();
        for (i, &name) in self.names.iter().enumerate() {
            let ms =
                ticks[2 * i + 1].wrapping_sub(ticks[2 * i]) as f64 * self.period_ns as f64 * 1e-6;
            match out.iter_mut().find(|(n, _)| *n == name) {
                Some((_, total)) => *total += ms,
                None => out.push((name, ms)),
            }
        }
        self.names.clear();
        Ok(out)
    }
}
