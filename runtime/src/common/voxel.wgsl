#define_import_path cssm::voxel

// A voxel a triangle touches, as the voxeliser writes it (`voxelize::VoxelFragment`; a test
// holds the layouts together).
struct VoxelFragment {
    // x | y << 10 | z << 20
    coord: u32,
    // pack4x8unorm(albedo, 1)
    albedo: u32,
    // pack4x8snorm(normal, 0)
    normal: u32,
    triangle: u32,
}

fn fragment_cell(f: VoxelFragment) -> vec3u {
    return vec3u(f.coord & 1023u, (f.coord >> 10u) & 1023u, f.coord >> 20u);
}
