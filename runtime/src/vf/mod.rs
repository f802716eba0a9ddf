//! Visibility filtering over point proxies (Chen et al. 2014, "Visibility Filtering for
//! Producing Indirect Illumination"). Built so far: the point proxies and their voxel grid
//! (§3.1, [`proxies`]): discs spread over the triangles in proportion to their area, hashed
//! into voxels by Eq. 1 and sorted by voxel on the GPU (`common::sort`), each voxel's range of
//! proxies. The VPL light, the spherical harmonics per voxel, the sparse shadow rays, the
//! visibility filter and the gathering follow; the method is not yet in the method table.

pub mod proxies;
