//! The filters' parameters ([`FilterOptions`]: reduction, blur radius and the tolerances of the
//! weights) with the check that refuses values the WGSL cannot take, and the `downsample` and
//! `blur` options through which a method sets them.

use super::{MAX_FACTOR, MAX_RADIUS};
use crate::{
    RuntimeError,
    method::{OptionKind, OptionSpec},
};

/// The `downsample` option of a method whose light the filters up-sample ([`FilterOptions`]'s
/// factor), with its own help and default.
pub(crate) const fn downsample_option(help: &'static str, default: u32) -> OptionSpec {
    OptionSpec {
        name: "downsample",
        help,
        kind: OptionKind::Count {
            default,
            min: 1,
            max: MAX_FACTOR,
        },
    }
}

/// The `blur` option of a method whose light the filters blur ([`FilterOptions`]'s radius),
/// with its own help and default.
pub(crate) const fn blur_option(help: &'static str, default: u32) -> OptionSpec {
    OptionSpec {
        name: "blur",
        help,
        kind: OptionKind::Count {
            default,
            min: 0,
            max: MAX_RADIUS,
        },
    }
}

/// Parameters of the filters.
///
/// The defaults are starting values: the thesis' kernel of 17 taps (radius 8) at half
/// resolution, and tolerances that keep neighbouring surfaces apart in the Cornell box. Each
/// technique's measurements set its own defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterOptions {
    /// Reduction per side, 1 to [`MAX_FACTOR`].
    pub factor: u32,
    /// Blur taps on each side of the centre, 0 (no blur) to [`MAX_RADIUS`].
    pub radius: u32,
    /// Standard deviation of the blur's Gaussian, in low-res pixels.
    pub spatial_sigma: f32,
    /// Depth tolerance, relative to the reference's distance from the eye.
    pub depth_sigma: f32,
    /// Exponent of the normal weight `max(0, n_c·n_t)`; 0 ignores normals.
    pub normal_power: f32,
}

impl Default for FilterOptions {
    fn default() -> Self {
        Self {
            factor: 2,
            radius: 8,
            spatial_sigma: 4.0,
            depth_sigma: 0.1,
            normal_power: 8.0,
        }
    }
}

impl FilterOptions {
    /// A method's light at 1/`factor` of the resolution per side, blurred with `radius` taps on
    /// each side, the other settings at their defaults.
    pub fn reduced(factor: u32, radius: u32) -> Self {
        Self {
            factor,
            radius,
            ..Default::default()
        }
    }

    /// Refuses a factor outside 1 to [`MAX_FACTOR`], a radius above [`MAX_RADIUS`], sigmas
    /// that are not finite and positive, and a normal power that is not finite and
    /// non-negative.
    ///
    /// # Errors
    /// [`RuntimeError::Unsupported`] naming the value.
    pub fn check(&self) -> Result<(), RuntimeError> {
        let refuse = |msg: String| Err(RuntimeError::Unsupported(msg));
        if !(1..=MAX_FACTOR).contains(&self.factor) {
            return refuse(format!(
                "filter factor {} is out of range 1..={MAX_FACTOR}",
                self.factor
            ));
        }
        if self.radius > MAX_RADIUS {
            return refuse(format!(
                "filter radius {} is out of range 0..={MAX_RADIUS}",
                self.radius
            ));
        }
        for (name, sigma) in [
            ("spatial sigma", self.spatial_sigma),
            ("depth sigma", self.depth_sigma),
        ] {
            if !(sigma.is_finite() && sigma > 0.0) {
                return refuse(format!("filter {name} {sigma} must be finite and > 0"));
            }
        }
        if !(self.normal_power.is_finite() && self.normal_power >= 0.0) {
            return refuse(format!(
                "filter normal power {} must be finite and >= 0",
                self.normal_power
            ));
        }
        Ok(())
    }
}
