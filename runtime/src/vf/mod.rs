//! Visibility filtering over point proxies (Chen et al. 2014, "Visibility Filtering for
//! Producing Indirect Illumination"). Built so far (§3.1): the point proxies and their voxel
//! grid ([`proxies`]: discs spread over the triangles in proportion to their area, hashed into
//! voxels by Eq. 1 and sorted by voxel on the GPU with `common::sort`, each voxel's range of
//! proxies), and their light ([`light`]: the proxies lit through the shadow maps as VPLs, each
//! voxel's order-0/1 spherical harmonics of them, Eq. 2, 3), and the sparse shadow rays from a
//! reduced G-buffer through the voxels ([`march`]: each ray's first voxel with a disc it hits,
//! the pixel's visible-voxel list). The visibility filter (Eq. 4), the gathering (Eq. 5-7) and
//! the up-sampling follow; the method is not yet in the method table.

pub mod light;
pub mod march;
pub mod proxies;
