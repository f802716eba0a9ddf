//! Voxel cone tracing over a sparse voxel octree (Crassin et al. 2011), built in slices: so far
//! the octree's structure from the shared voxeliser's fragments ([`octree`]). Bricks, light
//! injection, MIP-mapping and the cone tracing follow, and then the method's entry in the table.

pub mod octree;
