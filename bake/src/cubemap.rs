//! Depth cube maps (§3.2.1): for one texel, a `6 x N x N` map of linear depth seen from the
//! texel position pushed off the surface by the near distance. Every pixel records the codes of
//! all depths between its ray's first and second intersection, any of which is a correct
//! stand-in (dual depth layers); pixels wholly behind the tangent plane are "don't care".
//! Beyond the paper, [`SecondLayer::Facing`] ends the range at the nearest intersection whose
//! surface faces the texel instead of at the second one.

use cssm_formats::{
    Texel,
    cube::{self, DEPTH_MAX, DepthQuantizer},
};

use crate::raycast::SceneBvh;

/// Acceptable code range `[lo, hi]` of one pixel; `[0, DEPTH_MAX]` means "don't care".
pub type Interval = (u16, u16);

/// Which intersection closes a pixel's interval.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SecondLayer {
    /// The second intersection, whichever way its surface faces (the paper, §3.2, after
    /// Weiskopf and Ertl's dual depth layers).
    #[default]
    Any,
    /// Beyond the paper: the nearest intersection beyond the first whose surface *faces* the
    /// texel. A point on a surface facing away (the far side of a wall, of a column, of a closed
    /// mesh) has a zero cosine towards the texel, so it exchanges no light with it and its
    /// visibility never matters; skipping it widens the interval from a wall's thickness to the
    /// room behind it, and runs grow longer.
    Facing,
}

impl SecondLayer {
    /// Every choice, default first.
    pub const ALL: [SecondLayer; 2] = [SecondLayer::Any, SecondLayer::Facing];

    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SecondLayer::Any => "any",
            SecondLayer::Facing => "facing",
        }
    }
}

impl std::fmt::Display for SecondLayer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for SecondLayer {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "any" => Ok(SecondLayer::Any),
            "facing" => Ok(SecondLayer::Facing),
            other => Err(format!(
                "unknown second layer '{other}': expected any or facing"
            )),
        }
    }
}

/// The don't-care interval.
pub const DONT_CARE: Interval = (0, DEPTH_MAX);

/// Renders one texel's cube map into `out` (`6 * n * n` intervals). Returns the number of rays
/// cast (pixels that were not don't-care).
pub fn render(
    bvh: &SceneBvh,
    texel: &Texel,
    n: u32,
    near: f32,
    quantizer: &DepthQuantizer,
    second_layer: SecondLayer,
    out: &mut [Interval],
) -> u64 {
    let normal = texel.nrm();
    let centre = texel.pos() + normal * near;
    // Hits closer together than a tenth of a depth code are the same surface.
    let separation = 0.1 * quantizer.far() / DEPTH_MAX as f32;
    let mut rays = 0;
    for (pixel, slot) in out.iter_mut().enumerate() {
        let pixel = pixel as u32;
        if cube::pixel_is_dont_care(n, pixel, normal) {
            *slot = DONT_CARE;
            continue;
        }
        rays += 1;
        // Straddling pixels whose centre points below the plane are cast along it (see
        // `cube::cast_direction`): otherwise they would only see the texel's own surface.
        let (dir, depth_scale) = cube::cast_direction(n, pixel, normal);
        if depth_scale < 1e-3 {
            *slot = DONT_CARE;
            continue;
        }
        let hit = match second_layer {
            SecondLayer::Any => bvh.dual_hit(centre, dir, separation),
            SecondLayer::Facing => bvh.front_dual_hit(centre, dir, separation),
        };
        *slot = quantizer.interval(hit.first * depth_scale, hit.second * depth_scale);
    }
    rays
}
