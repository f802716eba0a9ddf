//! [`crate::BakeDevice::Gpu`] in a build without the crate's `gpu` feature: no GPU renderer can
//! be made, and the bake says so.

use cssm_formats::{
    Texel,
    cube::{DepthQuantizer, PixelGrid},
};

use crate::{BakeError, TexelGeometry, cubemap};

/// Never made: [`GpuMaps::new`] fails.
pub(crate) struct GpuMaps<'a> {
    never: std::convert::Infallible,
    _geometry: std::marker::PhantomData<&'a TexelGeometry>,
}

impl<'a> GpuMaps<'a> {
    pub(crate) fn new(_geometry: &'a TexelGeometry, _grid: PixelGrid) -> Result<Self, BakeError> {
        Err(BakeError::Gpu(
            "this build has no GPU support (build cssm-bake with its `gpu` feature)".into(),
        ))
    }

    pub(crate) fn describe(&self) -> String {
        match self.never {}
    }

    pub(crate) fn batch_maps(&self, _n: u32) -> usize {
        match self.never {}
    }

    #[allow(clippy::too_many_arguments)]
    pub(crate) fn render_in_order(
        &self,
        _texels: &[Texel],
        _sequence: &[u32],
        _n: u32,
        _near: f32,
        _quantizer: &DepthQuantizer,
        _second_layer: cubemap::SecondLayer,
        _batch: usize,
        _each: &mut dyn FnMut(usize, &[cubemap::Interval]),
    ) -> Result<u64, BakeError> {
        match self.never {}
    }
}
