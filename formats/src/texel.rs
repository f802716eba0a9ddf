//! The atlas texel table (§3.2.3): one entry per *defined* atlas texel, the surface patch that a
//! depth cube map stands for.

use serde::{Deserialize, Serialize};

/// One defined atlas texel: the surface patch whose centre carries a depth cube map.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Texel {
    /// World-space position of the texel centre on the surface.
    pub position: [f32; 3],
    /// Unit geometric normal of the surface at the texel centre.
    pub normal: [f32; 3],
    /// World-space surface area that the texel stands for (scene units squared).
    pub area: f32,
    /// Index into the scene's material list.
    pub material: u32,
    /// Atlas chart the texel belongs to (dense ids `0..chart_count`).
    pub chart: u32,
    /// Index into `Scene::objects` of the object the texel lies on. Its depth cube map sees
    /// that object's geometry only (§3.3: each object's CSSM tests self-occlusion; the other
    /// objects are tested with their coherent shadow maps), so it holds wherever the objects
    /// move. In a scene without rigid objects, 0 (the static part) everywhere.
    pub object: u32,
    /// Atlas column of the texel, `0..atlas_resolution`.
    pub x: u16,
    /// Atlas row of the texel, `0..atlas_resolution`.
    pub y: u16,
}

impl Texel {
    /// Position as a glam vector.
    pub fn pos(&self) -> glam::Vec3 {
        glam::Vec3::from(self.position)
    }
    /// Normal as a glam vector.
    pub fn nrm(&self) -> glam::Vec3 {
        glam::Vec3::from(self.normal)
    }
}

/// Order in which the atlas texels are visited, and so the order of the depth-map sequence
/// (§3.2.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Traversal {
    /// Chart by chart; inside a chart, rows of its bounding box alternately left-to-right and
    /// right-to-left; next chart: the one whose first texel is closest in 3D.
    Zigzag,
    /// Chart by chart; inside a chart, walk along the border of the unvisited region keeping it on
    /// the left, stepping back when stuck (outside in).
    Spiral,
    /// Nearest-first walk over texel positions, no use of the atlas layout.
    Greedy,
    /// Chart by chart like Zig-Zag and Spiral; inside a chart, the order of a (generalised)
    /// Hilbert curve over the chart's bounding rectangle (beyond the paper: §3.2.3 rules the
    /// Hilbert pattern of CSMs out for arbitrary chart shapes; restricted to a chart's texels it
    /// still stays local).
    Hilbert,
    /// Chart by chart; inside each chart, the Hilbert or the Spiral order, whichever a pilot bake
    /// of that chart's texels at a coarse cube resolution compresses into fewer runs (beyond the
    /// paper). The bake runs the pilot; without one it is the Hilbert order.
    Piloted,
}

impl Traversal {
    /// The paper's traversals, in the order its Table 2 lists them (§3.2.3).
    pub const PAPER: [Traversal; 3] = [Traversal::Greedy, Traversal::Zigzag, Traversal::Spiral];

    /// Every traversal: the paper's, then the ones beyond it.
    pub const ALL: [Traversal; 5] = [
        Traversal::Greedy,
        Traversal::Zigzag,
        Traversal::Spiral,
        Traversal::Hilbert,
        Traversal::Piloted,
    ];

    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Traversal::Zigzag => "zigzag",
            Traversal::Spiral => "spiral",
            Traversal::Greedy => "greedy",
            Traversal::Hilbert => "hilbert",
            Traversal::Piloted => "piloted",
        }
    }
}

impl std::fmt::Display for Traversal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Traversal {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "zigzag" | "zig-zag" => Ok(Traversal::Zigzag),
            "spiral" => Ok(Traversal::Spiral),
            "greedy" => Ok(Traversal::Greedy),
            "hilbert" => Ok(Traversal::Hilbert),
            "piloted" => Ok(Traversal::Piloted),
            other => Err(format!(
                "unknown traversal '{other}': expected zigzag, spiral, greedy, hilbert or piloted"
            )),
        }
    }
}
