//! Structs shared by Rust and WGSL, each defined once in Rust (`#[repr(C)]`) and once in
//! `types.wgsl`; the test `wgsl_layouts_match_rust` holds the two together with naga.

use bytemuck::{Pod, Zeroable};

/// WGSL declarations of every struct below.
pub const TYPES_WGSL: &str = include_str!("types.wgsl");

/// One mesh vertex: triangles are unrolled (three vertices each) so that every vertex carries
/// its triangle's geometric normal and material (flat shading, as the bake sees the surface).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuVertex {
    /// World position.
    pub position: [f32; 3],
    /// Unit geometric normal of the triangle (its winding's side).
    pub normal: [f32; 3],
    /// Texture coordinates (zero when the mesh has none).
    pub uv: [f32; 2],
    /// Atlas coordinates in texels (zero when no `.cssm` is loaded).
    pub atlas_uv: [f32; 2],
    /// Material index.
    pub material: u32,
    /// Scene triangle index.
    pub triangle: u32,
    /// Index of the triangle's object in `Scene::objects` (its row of the object motion).
    pub object: u32,
    /// The triangle's flat tangent frame for its normal map ([`crate::normal_map::tangent_frame`]):
    /// xyz the unit tangent (+u), w the handedness (+1, or -1 for mirrored UVs; the bitangent is
    /// `w * normal x tangent`); all zero where the UVs are degenerate: no perturbation.
    pub tangent: [f32; 4],
}

/// A material (conventions in `docs/architecture.md`).
///
/// `Default` is a black, non-emissive material with no textures: every texture layer is -1.
/// It is written by hand because a derived one would put 0 there, which means layer 0 of the
/// texture array, not "none". The all-zero bytes of `Zeroable` stay a valid material (then
/// sampling layer 0), for code that wants exactly that.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    /// Lambertian albedo, linear RGB.
    pub kd: [f32; 3],
    /// Phong exponent.
    pub ns: f32,
    /// Specular albedo of the normalised Phong lobe.
    pub ks: [f32; 3],
    /// Layer of the albedo texture array, or -1 for none.
    pub texture: i32,
    /// Emitted radiance, linear RGB, from the front side only (the side the triangle's winding
    /// normal faces; `docs/scene-format.md`); zero for a surface that only reflects.
    pub emission: [f32; 3],
    /// Layer of the emission texture in the same texture array as the albedo textures (it
    /// multiplies `emission`), or -1 for none.
    pub emission_texture: i32,
    /// `emission` times the mean of its texture (`emission` without one): what an atlas texel
    /// of the material emits, the atlas sampling no textures (§4.7: the radiosity's source).
    pub emission_mean: [f32; 3],
    /// Layer of the tangent-space normal map in the same texture array (a height map turned
    /// into one on load, [`crate::normal_map`]), or -1 for none: it tilts the shading normal.
    pub normal_texture: i32,
    /// `kd` times the mean of its albedo texture (`kd` without one): what an atlas texel of the
    /// material reflects in the bounces, the atlas sampling no textures
    /// ([`crate::direct::cpu::bounce_albedo`]).
    pub kd_mean: [f32; 3],
    /// Padding to 80 bytes.
    pub padding: u32,
}

impl Default for GpuMaterial {
    fn default() -> Self {
        Self {
            texture: -1,
            emission_texture: -1,
            normal_texture: -1,
            ..Zeroable::zeroed()
        }
    }
}

/// A spot light with its shadow-map transform.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuSpotLight {
    /// Position.
    pub position: [f32; 3],
    /// Cosine of the cone half-angle.
    pub cos_cutoff: f32,
    /// Unit cone axis.
    pub direction: [f32; 3],
    /// World-space offset along the normal before the shadow-map lookup, per unit of distance
    /// to the light (normal-offset bias, a multiple of the shadow-map texel footprint).
    pub normal_offset: f32,
    /// Radiant intensity, W/sr, linear RGB.
    pub intensity: [f32; 3],
    /// Shadow-map resolution in texels.
    pub shadow_resolution: f32,
    /// World to shadow-map clip space.
    pub view_proj: [[f32; 4]; 4],
    /// Solid angle of the shadow-map texel on the cone's axis, steradians; a texel at angle
    /// `a` off the axis spans `texel_solid_angle cos³ a` (the reflective shadow map's flux,
    /// `common::shadow_map::Rsm`).
    pub texel_solid_angle: f32,
    /// Unused.
    pub _pad: [f32; 3],
}

/// Per-frame view constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuView {
    /// World to clip space.
    pub view_proj: [[f32; 4]; 4],
    /// Eye position.
    pub eye: [f32; 3],
    /// Number of lights.
    pub light_count: u32,
    /// Image width and height.
    pub size: [u32; 2],
    /// Exposure multiplier applied before tone mapping.
    pub exposure: f32,
    /// Unused.
    pub _pad: u32,
}

/// One atlas texel as the GPU sees it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTexel {
    /// World position of the texel centre.
    pub position: [f32; 3],
    /// Surface area it stands for.
    pub area: f32,
    /// Unit normal.
    pub normal: [f32; 3],
    /// Atlas chart.
    pub chart: u32,
    /// Index of its depth map in the sequence.
    pub map: u32,
    /// Material index.
    pub material: u32,
    /// Atlas column.
    pub x: u32,
    /// Atlas row.
    pub y: u32,
    /// Index into `Scene::objects` of the object it lies on (§3.3: which placement moves it,
    /// whose maps its cube map holds).
    pub object: u32,
    /// Unused.
    pub _pad: [u32; 3],
}

/// Constants of a loaded CSSM and of its query.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuCssmParams {
    /// Atlas width and height.
    pub atlas_resolution: u32,
    /// Cube-map face resolution N.
    pub cube_resolution: u32,
    /// Number of depth maps (= defined texels).
    pub map_count: u32,
    /// Pixels per cube map, 6 N².
    pub pixel_count: u32,
    /// Near distance of the bake.
    pub near: f32,
    /// Far plane of the bake.
    pub far: f32,
    /// Depth codes per scene unit (65535 / (far - near)).
    pub depth_scale: f32,
    /// Constant bias, in near distances.
    pub bias_near: f32,
    /// Bias proportional to the query depth.
    pub bias_relative: f32,
    /// Bit 0: PCF over 2x2 pixels; bit 1: filter over the 2x2 sender texels; bit 2: both ends;
    /// bit 3: the file's cube maps sample staggered pixel grids; bit 4: they are turned against
    /// the world (`cube::CubeFrame::Turned`).
    pub flags: u32,
    /// Number of scene triangles with atlas coordinates.
    pub triangle_count: u32,
    /// Runs each storage binding of the run data holds (all of them where one binding holds
    /// the file's runs): run `i` is element `i % runs_per_binding` of binding
    /// `i / runs_per_binding` ([`crate::load::CssmGpu::run_bindings`]).
    pub runs_per_binding: u32,
}

/// One node of the texel hierarchy (§4.2.1): the file's own node (64 bytes, `#[repr(C)]`,
/// `Pod`), uploaded with its spread as a [`GpuHierarchyNode`] (WGSL `Node` in `types.wgsl`).
pub use cssm_formats::hierarchy::HierarchyNode as GpuNode;

/// What a cluster's transfer needs beyond its [`GpuNode`], computed at load from the texels
/// where they stand ([`crate::radiosity::transfer::node_spreads`]; not in the file): the second
/// moment of its texels' normals, `sum area n n^T`, which with the mean normal gives the area
/// the cluster shows in any direction, and the texel whose normal is the most opposite to the
/// representative's, whose visibility stands for the cluster's where the representative faces
/// away from a receiver. On the GPU it follows its node ([`GpuHierarchyNode`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuNodeSpread {
    /// The moment's xx, yy, zz and xy entries.
    pub moment_a: [f32; 4],
    /// Its xz and yz entries.
    pub moment_b: [f32; 2],
    /// The texel of the node whose normal is the most opposite to its representative's.
    pub other: u32,
    /// [`NODE_EMITTER`] and [`NODE_ALL_EMITTERS`] (32 bytes in all).
    pub flags: u32,
}

/// [`GpuNodeSpread::flags`]: the node holds a texel whose material emits.
pub const NODE_EMITTER: u32 = 1;
/// [`GpuNodeSpread::flags`]: every texel of the node emits.
pub const NODE_ALL_EMITTERS: u32 = 2;

/// A node as the GPU holds it: the file's node, then its spread (96 bytes, `Pod`); its WGSL twin
/// is `Node` in `types.wgsl`, whose fields are both parts' in this order (one storage binding:
/// the radiosity gather is at the 12 a device must allow).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuHierarchyNode {
    /// The file's node.
    pub node: GpuNode,
    /// Its spread.
    pub spread: GpuNodeSpread,
}

/// Constants of one hierarchy traversal pass (radiosity gather or final gather).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuTraversalParams {
    /// Receivers of the pass (texels, or pixels).
    pub receiver_count: u32,
    /// Nodes in the hierarchy.
    pub node_count: u32,
    /// Refine a sender while its tone-mapped upper bound exceeds this (§4.3).
    pub threshold: f32,
    /// Exposure of the tone mapper the oracle uses.
    pub exposure: f32,
    /// Seed of the sender jitter (§4.5, final gather only); only used when `jitter` is 1.
    pub seed: u32,
    /// 1: each sender is a random point of a random texel of its node (§4.5); 0: the node's
    /// representative.
    pub jitter: u32,
    /// 1: gather (a bounce); 0: write the direct light only (the start of the iteration); 2:
    /// gather the far field only, every leaf sender weighted by `1 - near_split_weight` and
    /// every node within `near_radius` refined (`lightcuts`' texture-space final gather).
    pub gather: u32,
    /// Frames accumulated so far (final gather's progressive average).
    pub frame: u32,
    /// The reach of the near field `lightcuts` gathers per pixel (world units; 0: none), see
    /// `transfer::near_split_weight`.
    pub near_radius: f32,
    /// How far from its texel's centre a pixel reads the texel's near list (world units; 0:
    /// no lists, the near field walks the hierarchy), `lightcuts::near::NearLists::margin`.
    pub near_margin: f32,
    /// How far off its texel's plane a pixel reads the list, `NearLists::plane`.
    pub near_plane: f32,
    /// 1: the emitters' light is kept out of the far field (`gather` 2) and every pixel of the
    /// texture-space final gather gathers it itself ([`NODE_EMITTER`]); 0: the far field holds
    /// it.
    pub emitters: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default material samples no texture: layer 0 is a real texture, -1 none.
    #[test]
    fn the_default_material_has_no_textures() {
        let m = GpuMaterial::default();
        assert_eq!(
            (m.texture, m.emission_texture, m.normal_texture),
            (-1, -1, -1)
        );
        // Everything else is zero, as the derived default was.
        let zeroed_textures = GpuMaterial {
            texture: 0,
            emission_texture: 0,
            normal_texture: 0,
            ..m
        };
        assert_eq!(zeroed_textures, Zeroable::zeroed());
    }

    /// Every struct above has the size and member offsets naga computes for its WGSL twin.
    #[test]
    fn wgsl_layouts_match_rust() {
        // The structs alone, without the line naga_oil reads.
        let source: String = TYPES_WGSL
            .lines()
            .filter(|l| !l.starts_with("#define_import_path"))
            .map(|l| format!("{l}\n"))
            .collect();
        let module = naga::front::wgsl::parse_str(&source).expect("types.wgsl parses");
        let check = |name: &str, size: usize, offsets: &[(&str, usize)]| {
            crate::shaders::tests::check_struct(&module, name, size, offsets)
        };
        use std::mem::{offset_of, size_of};
        check(
            "Material",
            size_of::<GpuMaterial>(),
            &[
                ("kd", offset_of!(GpuMaterial, kd)),
                ("ns", offset_of!(GpuMaterial, ns)),
                ("ks", offset_of!(GpuMaterial, ks)),
                ("texture", offset_of!(GpuMaterial, texture)),
                ("emission", offset_of!(GpuMaterial, emission)),
                (
                    "emission_texture",
                    offset_of!(GpuMaterial, emission_texture),
                ),
                ("emission_mean", offset_of!(GpuMaterial, emission_mean)),
                ("kd_mean", offset_of!(GpuMaterial, kd_mean)),
                ("normal_texture", offset_of!(GpuMaterial, normal_texture)),
            ],
        );
        check(
            "SpotLight",
            size_of::<GpuSpotLight>(),
            &[
                ("position", offset_of!(GpuSpotLight, position)),
                ("cos_cutoff", offset_of!(GpuSpotLight, cos_cutoff)),
                ("direction", offset_of!(GpuSpotLight, direction)),
                ("normal_offset", offset_of!(GpuSpotLight, normal_offset)),
                ("intensity", offset_of!(GpuSpotLight, intensity)),
                (
                    "shadow_resolution",
                    offset_of!(GpuSpotLight, shadow_resolution),
                ),
                ("view_proj", offset_of!(GpuSpotLight, view_proj)),
                (
                    "texel_solid_angle",
                    offset_of!(GpuSpotLight, texel_solid_angle),
                ),
            ],
        );
        check(
            "View",
            size_of::<GpuView>(),
            &[
                ("view_proj", offset_of!(GpuView, view_proj)),
                ("eye", offset_of!(GpuView, eye)),
                ("light_count", offset_of!(GpuView, light_count)),
                ("size", offset_of!(GpuView, size)),
                ("exposure", offset_of!(GpuView, exposure)),
            ],
        );
        check(
            "Texel",
            size_of::<GpuTexel>(),
            &[
                ("position", offset_of!(GpuTexel, position)),
                ("area", offset_of!(GpuTexel, area)),
                ("normal", offset_of!(GpuTexel, normal)),
                ("chart", offset_of!(GpuTexel, chart)),
                ("map", offset_of!(GpuTexel, map)),
                ("material", offset_of!(GpuTexel, material)),
                ("x", offset_of!(GpuTexel, x)),
                ("y", offset_of!(GpuTexel, y)),
                ("object", offset_of!(GpuTexel, object)),
            ],
        );
        let spread = offset_of!(GpuHierarchyNode, spread);
        check(
            "Node",
            size_of::<GpuHierarchyNode>(),
            &[
                ("center", offset_of!(GpuNode, center)),
                ("radius", offset_of!(GpuNode, radius)),
                ("normal", offset_of!(GpuNode, normal)),
                ("cone_cos", offset_of!(GpuNode, cone_cos)),
                ("area", offset_of!(GpuNode, area)),
                ("skip", offset_of!(GpuNode, skip)),
                ("first", offset_of!(GpuNode, first)),
                ("count", offset_of!(GpuNode, count)),
                ("representative", offset_of!(GpuNode, representative)),
                ("moment_a", spread + offset_of!(GpuNodeSpread, moment_a)),
                ("moment_b", spread + offset_of!(GpuNodeSpread, moment_b)),
                ("other", spread + offset_of!(GpuNodeSpread, other)),
                ("flags", spread + offset_of!(GpuNodeSpread, flags)),
            ],
        );
        check(
            "TraversalParams",
            size_of::<GpuTraversalParams>(),
            &[
                (
                    "receiver_count",
                    offset_of!(GpuTraversalParams, receiver_count),
                ),
                ("node_count", offset_of!(GpuTraversalParams, node_count)),
                ("threshold", offset_of!(GpuTraversalParams, threshold)),
                ("exposure", offset_of!(GpuTraversalParams, exposure)),
                ("seed", offset_of!(GpuTraversalParams, seed)),
                ("jitter", offset_of!(GpuTraversalParams, jitter)),
                ("gather", offset_of!(GpuTraversalParams, gather)),
                ("frame", offset_of!(GpuTraversalParams, frame)),
                ("near_radius", offset_of!(GpuTraversalParams, near_radius)),
                ("near_margin", offset_of!(GpuTraversalParams, near_margin)),
                ("near_plane", offset_of!(GpuTraversalParams, near_plane)),
                ("emitters", offset_of!(GpuTraversalParams, emitters)),
            ],
        );
        check(
            "CssmParams",
            size_of::<GpuCssmParams>(),
            &[
                (
                    "atlas_resolution",
                    offset_of!(GpuCssmParams, atlas_resolution),
                ),
                (
                    "cube_resolution",
                    offset_of!(GpuCssmParams, cube_resolution),
                ),
                ("map_count", offset_of!(GpuCssmParams, map_count)),
                ("pixel_count", offset_of!(GpuCssmParams, pixel_count)),
                ("near", offset_of!(GpuCssmParams, near)),
                ("far", offset_of!(GpuCssmParams, far)),
                ("depth_scale", offset_of!(GpuCssmParams, depth_scale)),
                ("bias_near", offset_of!(GpuCssmParams, bias_near)),
                ("bias_relative", offset_of!(GpuCssmParams, bias_relative)),
                ("flags", offset_of!(GpuCssmParams, flags)),
                ("triangle_count", offset_of!(GpuCssmParams, triangle_count)),
                (
                    "runs_per_binding",
                    offset_of!(GpuCssmParams, runs_per_binding),
                ),
            ],
        );
    }

    /// The vertex buffer layout the raster passes declare packs the attributes at the offsets of
    /// [`GpuVertex`]'s fields.
    #[test]
    fn vertex_layout_matches_rust() {
        use std::mem::{offset_of, size_of};
        let layout = crate::load::SceneGpu::VERTEX_LAYOUT;
        assert_eq!(layout.array_stride as usize, size_of::<GpuVertex>());
        let offsets: Vec<u64> = layout.attributes.iter().map(|a| a.offset).collect();
        let fields = [
            offset_of!(GpuVertex, position),
            offset_of!(GpuVertex, normal),
            offset_of!(GpuVertex, uv),
            offset_of!(GpuVertex, atlas_uv),
            offset_of!(GpuVertex, material),
            offset_of!(GpuVertex, triangle),
            offset_of!(GpuVertex, object),
            offset_of!(GpuVertex, tangent),
        ];
        assert_eq!(offsets, fields.map(|f| f as u64));
    }
}
