//! Each texel's list of the leaves a pixel on it gathers as its near field (`gather=atlas`),
//! built once at load instead of walked per pixel from the hierarchy's root.
//!
//! A pixel at `p` on texel `t` (the texel under its atlas coordinates) gathers every leaf within
//! the near radius `R` of `p`. When `p` lies within [`NearLists::margin`] of `t`'s centre, every
//! such leaf lies within `R + margin` of that centre, so `t`'s list holds them all. Left out of
//! the list are the leaves in `t`'s own plane (normal and plane within [`COPLANAR`] of `t`'s):
//! a pixel in that plane too sends nothing to them or gets nothing from them (the footprint's
//! transfer is zero in the sender's plane, `transfer::irradiance_from_footprint`), and they are
//! most of the leaves around a pixel in the middle of a wall, whose list is empty. A pixel
//! farther from its texel's centre or off its plane (a texel across a crease, whose centre and
//! normal are its coverage's means) walks the hierarchy instead, so no leaf is lost either way.
//! `final_gather.wgsl::near_field` and its twin `cpu.rs::near_field` read the same lists.

use cssm_formats::{hierarchy::Hierarchy, texel::Texel};

use crate::gpu_types::GpuNode;
use glam::Vec3;
use rayon::prelude::*;

/// How close to coplanar a leaf must be to a texel to be left out of its list: the sine of
/// the angle between their normals, and the leaf centre's distance from the texel's plane and
/// a pixel's, in the scene's mean texel sizes.
pub const COPLANAR: f32 = 1e-4;

/// The reach of a list beyond the near radius, in mean texel sizes: a pixel within it of its
/// texel's centre reads the list (the centre of a texel's coverage lies within about 0.7 of its
/// size from any point of it where the chart is not stretched).
pub const MARGIN_SIZES: f32 = 2.0;

/// The stackless walk of `final_gather.wgsl::near_field` (Fig. 10's skip pointers): `visit`
/// hears every node it reaches in order (node index, and whether it is a leaf whose bounding
/// sphere reaches within `reach` of `p`); it descends only into nodes reaching within `reach`.
pub fn walk_within(nodes: &[GpuNode], p: Vec3, reach: f32, mut visit: impl FnMut(usize, bool)) {
    let mut s = 0usize;
    while s < nodes.len() {
        let node = &nodes[s];
        let within = (Vec3::from(node.center) - p).length() - node.radius < reach;
        visit(s, within && node.count <= 1);
        s = if within && node.count > 1 {
            s + 1
        } else {
            node.skip as usize
        };
    }
}

/// The near lists of every texel: see the module docs.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NearLists {
    /// Per texel (texel order) the start of its list in `leaves`, and one past the last texel.
    pub offsets: Vec<u32>,
    /// The lists' leaves, as node indices of the hierarchy.
    pub leaves: Vec<u32>,
    /// How far from its texel's centre a pixel may lie and read its texel's list (world units).
    pub margin: f32,
    /// The plane test's tolerance (world units): [`COPLANAR`] texel sizes.
    pub plane: f32,
}

impl NearLists {
    /// The lists of `texels` (where they stand) over `hierarchy`, for the near radius `radius`
    /// (world units, [`super::near_radius`]) of a scene whose mean texel size is `size`.
    pub fn new(hierarchy: &Hierarchy, texels: &[Texel], radius: f32, size: f32) -> Self {
        let margin = MARGIN_SIZES * size;
        let plane = COPLANAR * size;
        let reach = radius + margin;
        let nodes = &hierarchy.nodes;
        let lists: Vec<Vec<u32>> = texels
            .par_iter()
            .map(|t| {
                let mut list = Vec::new();
                let (c, n) = (t.pos(), t.nrm());
                walk_within(nodes, c, reach, |s, is_leaf| {
                    if !is_leaf {
                        return;
                    }
                    let y = &texels[hierarchy.leaf_texels[nodes[s].first as usize] as usize];
                    let coplanar = y.nrm().cross(n).length() < COPLANAR
                        && y.nrm().dot(n) > 0.0
                        && (y.pos() - c).dot(n).abs() < plane;
                    if (y.pos() - c).length() < reach && !coplanar {
                        list.push(s as u32);
                    }
                });
                list
            })
            .collect();
        let mut offsets = Vec::with_capacity(texels.len() + 1);
        let mut leaves = Vec::new();
        for list in lists {
            offsets.push(leaves.len() as u32);
            leaves.extend(list);
        }
        offsets.push(leaves.len() as u32);
        Self {
            offsets,
            leaves,
            margin,
            plane,
        }
    }

    /// The list of texel `t` when a pixel at `p` on it may read it (within the margin of the
    /// texel's centre `c`, in its plane of normal `n`), else `None` (walk the hierarchy).
    pub fn list(&self, t: u32, p: Vec3, c: Vec3, n: Vec3) -> Option<&[u32]> {
        let t = t as usize;
        if t + 1 >= self.offsets.len()
            || (p - c).length() > self.margin
            || (p - c).dot(n).abs() > self.plane
        {
            return None;
        }
        Some(&self.leaves[self.offsets[t] as usize..self.offsets[t + 1] as usize])
    }

    /// The lists as the GPU reads them (`final_gather.wgsl`'s `near_lists`): the offsets,
    /// moved past themselves, then the leaves, in one array.
    pub fn packed(&self) -> Vec<u32> {
        let base = self.offsets.len() as u32;
        self.offsets
            .iter()
            .map(|&o| o + base)
            .chain(self.leaves.iter().copied())
            .collect()
    }

    /// Bytes on the GPU: the offsets and the leaves, `u32` each.
    pub fn bytes(&self) -> u64 {
        4 * (self.offsets.len() + self.leaves.len()) as u64
    }
}
