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

// A 1D pass over more items than one dispatch dimension holds (65,535 workgroups): its
// workgroups as a 2D dispatch, each dimension at most 32,768 (`voxelize::split_groups`).
fn split_groups(groups: u32) -> vec3u {
    if groups == 0u {
        return vec3u(0u, 1u, 1u);
    }
    let x = min(groups, 32768u);
    return vec3u(x, (groups + x - 1u) / x, 1u);
}

// The item of an invocation of a split dispatch.
fn split_item(group: vec3u, count: vec3u, local: u32, workgroup: u32) -> u32 {
    return (group.y * count.x + group.x) * workgroup + local;
}
