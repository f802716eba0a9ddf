//! Depth cube-map geometry shared by the bake and every query (§3.2.1, §3.2.2): face and pixel
//! layout, directions, the "don't care" half-space, and 16-bit linear depth quantisation.
//!
//! A cube map of resolution `N` has `6 * N * N` pixels, `pixel = face * N * N + row * N + col`.
//! Face `f` looks along axis `f / 2` (x, y, z), positive for even `f`. Its image axes are the two
//! other world axes in cyclic order (x: y,z; y: z,x; z: x,y) without sign flips, so the direction
//! through the centre of `(col, row)` is `major + u * e_u + v * e_v` with
//! `u = (col + 0.5) / N * 2 - 1` and likewise `v` from `row`. Directions are *not* normalised:
//! their major component is ±1, so the ray parameter `t` of a hit is its linear depth (distance
//! along the face axis), the depth the paper stores (§3.2.1, after Brabec et al.).
//!
//! These functions work in the *cube frame*. A file's [`CubeFrame`] says how it lies in the
//! world: on the world's axes (the paper), or turned so that no world axis runs along a face
//! axis; callers take world vectors into the cube frame with [`CubeFrame::to_cube`].

use glam::{Vec2, Vec3};

/// Largest quantised depth; stands for "nothing within the far plane".
pub const DEPTH_MAX: u16 = u16::MAX;

/// Axis indices (major, u, v) of face `face`.
#[inline]
pub fn face_axes(face: u32) -> (usize, usize, usize) {
    let major = (face / 2) as usize;
    (major, (major + 1) % 3, (major + 2) % 3)
}

/// Sign of the major axis of face `face`: +1 for even faces, -1 for odd ones.
#[inline]
pub fn face_sign(face: u32) -> f32 {
    if face % 2 == 0 { 1.0 } else { -1.0 }
}

/// Unnormalised direction through face coordinates `(u, v)` in `[-1, 1]` of face `face`.
#[inline]
pub fn face_direction(face: u32, u: f32, v: f32) -> Vec3 {
    let (major, ua, va) = face_axes(face);
    let mut d = [0.0f32; 3];
    d[major] = face_sign(face);
    d[ua] = u;
    d[va] = v;
    Vec3::from(d)
}

/// Where a texel's cube-map pixels sit on the faces: the paper's grid, or one shifted by a
/// fraction of a pixel that depends on the texel's atlas cell.
///
/// With one depth per pixel, an occluder's edge is placed by the pixel grid to within half a
/// pixel. Neighbouring texels see a distant edge at nearly the same place on their faces, so
/// on one shared grid the sender filter's 2x2 texels (§3.2.2) all make the same error. Staggered
/// grids (interleaved sampling, after Keller and Heidrich 2001) shift each texel's grid by
/// [`PixelGrid::STAGGER`] of a pixel along both face axes, the sign of each shift set by the
/// parity of the texel's atlas column and row, so the four texels of a filter sample an edge at
/// four places (reports/visibility.md, "Staggered pixel grids").
///
/// ```
/// use cssm_formats::cube::PixelGrid;
/// use glam::Vec2;
/// assert_eq!(PixelGrid::Centred.offset(3, 4), Vec2::ZERO);
/// assert_eq!(PixelGrid::Staggered.offset(3, 4), Vec2::new(0.125, -0.125));
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PixelGrid {
    /// Pixel centres at `(col + 0.5) / N` on every texel's faces (the paper).
    #[default]
    Centred,
    /// Every texel's grid shifted by `±STAGGER` pixels along each face axis: `+` for an odd
    /// atlas column (u) or row (v), `-` for an even one.
    Staggered,
}

impl PixelGrid {
    /// The shift of a staggered grid, in pixels.
    pub const STAGGER: f32 = 0.125;

    /// Every choice, default first.
    pub const ALL: [PixelGrid; 2] = [PixelGrid::Centred, PixelGrid::Staggered];

    /// The shift, in pixels along the faces' (u, v) axes, of the grid of the texel at atlas
    /// cell `(x, y)`.
    #[inline]
    pub fn offset(self, x: u16, y: u16) -> Vec2 {
        match self {
            PixelGrid::Centred => Vec2::ZERO,
            PixelGrid::Staggered => {
                let shift = |k: u16| {
                    if k % 2 == 1 {
                        Self::STAGGER
                    } else {
                        -Self::STAGGER
                    }
                };
                Vec2::new(shift(x), shift(y))
            }
        }
    }

    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            PixelGrid::Centred => "centred",
            PixelGrid::Staggered => "staggered",
        }
    }
}

impl std::fmt::Display for PixelGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for PixelGrid {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "centred" | "centered" => Ok(PixelGrid::Centred),
            "staggered" => Ok(PixelGrid::Staggered),
            other => Err(format!(
                "unknown pixel grid '{other}': expected centred or staggered"
            )),
        }
    }
}

/// How every texel's cube map lies in the world: the faces on the world's axes (the paper), or
/// one fixed rotation of them for every texel.
///
/// Interiors are built of vertical and horizontal edges (columns, frames, mouldings, walls),
/// and on cube faces aligned with the world those edges run along the pixel rows and columns.
/// With one depth per pixel, a 2x2 filter then places such an edge half-way between two pixel
/// centres wherever it truly lies, up to half a pixel off. On a turned cube the edges cross the
/// pixel grid obliquely, the 2x2 neighbourhood samples them at several offsets, and the filtered
/// edge lands nearer its true place (reports/visibility.md, "Turned cube maps").
///
/// [`CubeFrame::Turned`] takes the world's up axis (+y) to the cube's diagonal (1, 1, 1) / sqrt 3,
/// +x to (1, -1, 0) / sqrt 2 and +z to (-1, -1, 2) / sqrt 6, so none of the three world axes is
/// parallel to a face or to a face axis.
///
/// ```
/// use cssm_formats::cube::CubeFrame;
/// use glam::Vec3;
/// let up = CubeFrame::Turned.to_cube(Vec3::Y);
/// assert!((up - Vec3::splat(1.0 / 3f32.sqrt())).length() < 1e-6);
/// assert_eq!(CubeFrame::World.to_cube(Vec3::Y), Vec3::Y);
/// let v = Vec3::new(0.3, -1.2, 2.0);
/// assert!((CubeFrame::Turned.to_world(CubeFrame::Turned.to_cube(v)) - v).length() < 1e-6);
/// ```
///
/// `Default` is [`CubeFrame::World`], what a file without the header flag was baked with; the
/// bake's default is [`CubeFrame::Turned`] (`BakeOptions`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CubeFrame {
    /// Faces on the world's axes (the paper).
    #[default]
    World,
    /// Every cube map turned by [`CubeFrame::TURN`].
    Turned,
}

impl CubeFrame {
    /// The turned frame's rotation, world to cube: the images of the world's x, y and z axes
    /// (the columns of the matrix), as written in WGSL (`runtime/src/visibility/cssm.wgsl`).
    pub const TURN: [[f32; 3]; 3] = [
        [0.707_106_77, -0.707_106_77, 0.0],
        [0.577_350_26, 0.577_350_26, 0.577_350_26],
        [-0.408_248_3, -0.408_248_3, 0.816_496_6],
    ];

    /// Every choice, the bake's default ([`CubeFrame::Turned`]) first.
    pub const ALL: [CubeFrame; 2] = [CubeFrame::Turned, CubeFrame::World];

    /// The rotation, world to cube, as a matrix (the identity for [`CubeFrame::World`]), for
    /// a caller that turns whole meshes (`glam::Affine3A::from_mat3`).
    pub fn rotation(self) -> glam::Mat3 {
        match self {
            CubeFrame::World => glam::Mat3::IDENTITY,
            CubeFrame::Turned => glam::Mat3::from_cols_array_2d(&Self::TURN),
        }
    }

    /// A world vector in the cube frame (the identity for [`CubeFrame::World`]).
    #[inline]
    pub fn to_cube(self, v: Vec3) -> Vec3 {
        match self {
            CubeFrame::World => v,
            CubeFrame::Turned => {
                let [x, y, z] = Self::TURN.map(Vec3::from);
                x * v.x + y * v.y + z * v.z
            }
        }
    }

    /// A cube-frame vector in the world (the inverse of [`CubeFrame::to_cube`]).
    #[inline]
    pub fn to_world(self, v: Vec3) -> Vec3 {
        match self {
            CubeFrame::World => v,
            CubeFrame::Turned => {
                let [x, y, z] = Self::TURN.map(Vec3::from);
                Vec3::new(x.dot(v), y.dot(v), z.dot(v))
            }
        }
    }

    /// Lower-case name as used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            CubeFrame::World => "world",
            CubeFrame::Turned => "turned",
        }
    }
}

impl std::fmt::Display for CubeFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for CubeFrame {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "world" => Ok(CubeFrame::World),
            "turned" => Ok(CubeFrame::Turned),
            other => Err(format!(
                "unknown cube frame '{other}': expected turned or world"
            )),
        }
    }
}

/// Direction through the centre of pixel `pixel` of a cube map of resolution `n`.
#[inline]
pub fn pixel_direction(n: u32, pixel: u32) -> Vec3 {
    pixel_direction_at(n, pixel, Vec2::ZERO)
}

/// [`pixel_direction`] on a grid shifted by `offset` pixels ([`PixelGrid::offset`]); a zero
/// offset gives [`pixel_direction`] bit for bit.
#[inline]
pub fn pixel_direction_at(n: u32, pixel: u32, offset: Vec2) -> Vec3 {
    let (face, row, col) = split_pixel(n, pixel);
    let u = (col as f32 + 0.5 + offset.x) / n as f32 * 2.0 - 1.0;
    let v = (row as f32 + 0.5 + offset.y) / n as f32 * 2.0 - 1.0;
    face_direction(face, u, v)
}

/// The eight pixels around `pixel` (a pixel on a face's border finds its neighbours across the
/// edge, on the adjacent face; next to a cube corner two of them may coincide).
pub fn neighbours(n: u32, pixel: u32) -> [u32; 8] {
    let (face, row, col) = split_pixel(n, pixel);
    let offsets: [(i32, i32); 8] = [
        (-1, -1),
        (0, -1),
        (1, -1),
        (-1, 0),
        (1, 0),
        (-1, 1),
        (0, 1),
        (1, 1),
    ];
    if row > 0 && col > 0 && row + 1 < n && col + 1 < n {
        // Inside the face: plain index arithmetic.
        return offsets.map(|(du, dv)| (pixel as i32 + dv * n as i32 + du) as u32);
    }
    let step = 2.0 / n as f32;
    let u = (col as f32 + 0.5) * step - 1.0;
    let v = (row as f32 + 0.5) * step - 1.0;
    let mut out = [0; 8];
    for (slot, (du, dv)) in out.iter_mut().zip(offsets) {
        let d = face_direction(face, u + du as f32 * step, v + dv as f32 * step);
        let (f, pu, pv, _) = project(d);
        *slot = pixel_index(n, f, pu, pv);
    }
    out
}

/// `(face, row, col)` of a pixel index.
#[inline]
pub fn split_pixel(n: u32, pixel: u32) -> (u32, u32, u32) {
    let face = pixel / (n * n);
    let rest = pixel % (n * n);
    (face, rest / n, rest % n)
}

/// Where a direction from the cube centre lands: `(face, u, v, depth)` with `u, v` in `[-1, 1]`
/// and `depth` the linear depth of the point `centre + d` (its major-axis distance).
/// `d` must not be zero.
#[inline]
pub fn project(d: Vec3) -> (u32, f32, f32, f32) {
    let a = d.abs();
    let major = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let arr = d.to_array();
    let face = major as u32 * 2 + u32::from(arr[major] < 0.0);
    let depth = arr[major].abs();
    let (_, ua, va) = face_axes(face);
    (face, arr[ua] / depth, arr[va] / depth, depth)
}

/// Pixel index for face coordinates, clamped into the face.
#[inline]
pub fn pixel_index(n: u32, face: u32, u: f32, v: f32) -> u32 {
    let col = (((u + 1.0) * 0.5 * n as f32) as i64).clamp(0, n as i64 - 1) as u32;
    let row = (((v + 1.0) * 0.5 * n as f32) as i64).clamp(0, n as i64 - 1) as u32;
    face * n * n + row * n + col
}

/// [`pixel_index`] on a grid shifted by `offset` pixels ([`PixelGrid::offset`]): the pixel
/// whose cell holds `(u, v)`.
#[inline]
pub fn pixel_index_at(n: u32, face: u32, u: f32, v: f32, offset: Vec2) -> u32 {
    let step = 2.0 / n as f32;
    pixel_index(n, face, u - offset.x * step, v - offset.y * step)
}

/// True when the whole pixel lies strictly behind the surface's tangent plane (all four corner
/// directions have a negative dot product with the normal). Such pixels only see the inside of
/// the object: their depth is "don't care" and may take any value after compression (§3.2.1).
/// Pixels that straddle the plane are kept, so coplanar neighbours stay queryable.
#[inline]
pub fn pixel_is_dont_care(n: u32, pixel: u32, normal: Vec3) -> bool {
    pixel_is_dont_care_at(n, pixel, normal, Vec2::ZERO)
}

/// [`pixel_is_dont_care`] on a grid shifted by `offset` pixels.
#[inline]
pub fn pixel_is_dont_care_at(n: u32, pixel: u32, normal: Vec3, offset: Vec2) -> bool {
    // `dot(normal, direction)` is linear in (u, v) over a face, so its largest value over the
    // pixel's corners is the value at the centre plus half a pixel step times |n_u| + |n_v|.
    let (face, _, _) = split_pixel(n, pixel);
    pixel_direction_at(n, pixel, offset).dot(normal) + dont_care_reach(n, face, normal) < 0.0
}

/// The ray the bake casts for `pixel` of a texel with normal `normal`, and the factor that turns
/// its ray parameter into linear depth. Normally the pixel's centre direction (factor 1); for a
/// pixel that straddles the tangent plane with its centre below it, that direction projected onto
/// the plane, so the ray runs along the surface at the near distance and records what blocks the
/// view of coplanar receivers (the factor is then the projected major component).
#[inline]
pub fn cast_direction(n: u32, pixel: u32, normal: Vec3) -> (Vec3, f32) {
    cast_direction_at(n, pixel, normal, Vec2::ZERO)
}

/// [`cast_direction`] on a grid shifted by `offset` pixels.
#[inline]
pub fn cast_direction_at(n: u32, pixel: u32, normal: Vec3, offset: Vec2) -> (Vec3, f32) {
    let dir = pixel_direction_at(n, pixel, offset);
    cast_direction_from(dir, dir.dot(normal), normal, pixel / (n * n))
}

/// [`cast_direction`] from the pixel's centre direction `dir` on face `face` and
/// `below = dir.dot(normal)`, for a renderer that has them already.
#[inline]
pub fn cast_direction_from(dir: Vec3, below: f32, normal: Vec3, face: u32) -> (Vec3, f32) {
    if below >= 0.0 {
        return (dir, 1.0);
    }
    let projected = dir - normal * below;
    let major = (face / 2) as usize;
    (projected, projected.to_array()[major].abs())
}

/// Half a pixel's reach of `dot(normal, direction)` on face `face` at resolution `n`:
/// [`pixel_is_dont_care`] is `pixel_direction(n, pixel).dot(normal) + dont_care_reach(..) < 0`.
#[inline]
pub fn dont_care_reach(n: u32, face: u32, normal: Vec3) -> f32 {
    let (_, ua, va) = face_axes(face);
    let nrm = normal.to_array();
    let half_step = 1.0 / n as f32;
    half_step * (nrm[ua].abs() + nrm[va].abs())
}

/// `x.ceil().clamp(0.0, DEPTH_MAX as f32) as u16` (NaN gives 0), without `ceilf`: on x86-64's
/// baseline (no SSE4.1 `roundss`) that is a libm call per depth, a measurable share of a bake's
/// CPU time (reports/bake.md). Once clamped, truncation is the floor, and the ceiling the floor
/// plus one below `x`.
#[inline]
fn ceil_code(x: f32) -> u16 {
    let clamped = x.clamp(0.0, DEPTH_MAX as f32);
    let floor = clamped as u16;
    floor + u16::from((floor as f32) < clamped)
}

/// Linear-depth quantiser between the near and the far plane (16 bits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthQuantizer {
    near: f32,
    far: f32,
    scale: f32,
}

impl DepthQuantizer {
    /// Quantiser over `[near, far]`.
    pub fn new(near: f32, far: f32) -> Self {
        Self {
            near,
            far,
            scale: DEPTH_MAX as f32 / (far - near),
        }
    }

    /// Continuous position of `depth` on the 16-bit scale (not clamped).
    #[inline]
    pub fn scaled(&self, depth: f32) -> f32 {
        (depth - self.near) * self.scale
    }

    /// Smallest code whose depth is `>= depth`, clamped into the code range.
    #[inline]
    pub fn ceil(&self, depth: f32) -> u16 {
        ceil_code(self.scaled(depth))
    }

    /// Depth a code stands for.
    #[inline]
    pub fn depth(&self, code: u16) -> f32 {
        if code == DEPTH_MAX {
            f32::INFINITY
        } else {
            self.near + code as f32 / self.scale
        }
    }

    /// Far plane.
    pub fn far(&self) -> f32 {
        self.far
    }

    /// Codes `[lo, hi]` whose depths lie in `[first, second)` (dual depth layers, §3.2): any of
    /// them is a correct stand-in for the pixel. `second = INFINITY` when the ray leaves the
    /// scene after the first hit, `first = INFINITY` when it hits nothing. When the layers are
    /// closer than one code apart the range collapses to the code of `first`.
    #[inline]
    pub fn interval(&self, first: f32, second: f32) -> (u16, u16) {
        if !first.is_finite() || first >= self.far {
            return (DEPTH_MAX, DEPTH_MAX);
        }
        let lo = self.ceil(first);
        (lo, self.last_code_before(second).max(lo))
    }

    /// Largest code whose depth lies before `depth` (clamped to 0), [`DEPTH_MAX`] when `depth` is
    /// infinite or beyond the far plane: the top of an interval that `depth` closes.
    #[inline]
    pub fn last_code_before(&self, depth: f32) -> u16 {
        if !depth.is_finite() || depth >= self.far {
            DEPTH_MAX
        } else {
            let scaled = self.scaled(depth);
            if scaled > DEPTH_MAX as f32 {
                DEPTH_MAX
            } else {
                ceil_code(scaled).saturating_sub(1)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_turned_frame_is_a_rotation_with_no_world_axis_on_a_face_axis() {
        let exact = [
            [1.0 / 2f64.sqrt(), -1.0 / 2f64.sqrt(), 0.0],
            [1.0 / 3f64.sqrt(); 3],
            [-1.0 / 6f64.sqrt(), -1.0 / 6f64.sqrt(), 2.0 / 6f64.sqrt()],
        ];
        for (column, exact) in CubeFrame::TURN.iter().zip(exact) {
            for (c, e) in column.iter().zip(exact) {
                assert_eq!(*c, e as f32, "the nearest f32 of the exact entry");
            }
        }
        let axes = [Vec3::X, Vec3::Y, Vec3::Z];
        for a in axes {
            let turned = CubeFrame::Turned.to_cube(a);
            assert!((turned.length() - 1.0).abs() < 1e-6);
            // No world axis along a cube axis.
            assert!(turned.abs().max_element() < 0.82, "{a} -> {turned}");
            for b in axes {
                let dot = turned.dot(CubeFrame::Turned.to_cube(b));
                assert!((dot - f32::from(u8::from(a == b))).abs() < 1e-6);
            }
            assert!((CubeFrame::Turned.to_world(turned) - a).length() < 1e-6);
        }
        assert_eq!("Turned".parse::<CubeFrame>(), Ok(CubeFrame::Turned));
        assert!("tilted".parse::<CubeFrame>().is_err());
    }

    /// On every grid a query finds each pixel where the bake cast it: the pixel's own
    /// direction lands in its own cell (`pixel_index_at`), and no shifted grid's direction is
    /// the centred grid's; a zero offset is the centred grid bit for bit.
    #[test]
    fn shifted_grids_find_their_own_pixels() {
        for n in [8, 16, 32] {
            for x in 0..2u16 {
                for y in 0..2u16 {
                    for grid in PixelGrid::ALL {
                        let offset = grid.offset(x, y);
                        for pixel in 0..6 * n * n {
                            let dir = pixel_direction_at(n, pixel, offset);
                            let (face, u, v, _) = project(dir);
                            assert_eq!(pixel_index_at(n, face, u, v, offset), pixel);
                            let centred = pixel_direction(n, pixel);
                            match grid {
                                PixelGrid::Centred => assert_eq!(dir, centred),
                                PixelGrid::Staggered => assert_ne!(dir, centred),
                            }
                        }
                    }
                }
            }
        }
        // The four offsets of a staggered grid, one per parity of the atlas cell.
        let mut offsets: Vec<[f32; 2]> = (0..4u16)
            .map(|k| PixelGrid::Staggered.offset(k % 2, k / 2).to_array())
            .collect();
        offsets.dedup();
        assert_eq!(offsets.len(), 4);
        assert_eq!(
            PixelGrid::Staggered.offset(7, 9),
            PixelGrid::Staggered.offset(1, 1)
        );
    }

    /// The quantiser's ceilings equal the libm formulas they replace, at and between every
    /// code, out of range, at infinities and NaN.
    #[test]
    fn ceil_code_equals_the_libm_ceiling() {
        let ceil = |x: f32| x.ceil().clamp(0.0, DEPTH_MAX as f32) as u16;
        let before = |x: f32| (x.ceil() - 1.0).clamp(0.0, DEPTH_MAX as f32) as u16;
        let q = DepthQuantizer::new(0.0, DEPTH_MAX as f32);
        let mut xs = vec![
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            0.0,
            1e-30,
            -1e-30,
        ];
        xs.extend([
            -2.5, -1.0, -0.5, 65534.5, 65535.0, 65535.5, 65536.0, 1e9, -1e9,
        ]);
        for code in 0..=u32::from(DEPTH_MAX) + 1 {
            let c = code as f32;
            xs.extend([c, c.next_up(), c.next_down(), c + 0.5]);
        }
        for x in xs {
            assert_eq!(ceil_code(x), ceil(x), "ceil of {x}");
            assert_eq!(q.ceil(x), ceil(x), "quantiser ceil of {x}");
            if x.is_finite() && x < q.far() {
                assert_eq!(q.last_code_before(x), before(x), "last code before {x}");
            }
        }
    }

    #[test]
    fn project_inverts_pixel_direction() {
        for n in [1u32, 4, 8, 33] {
            for pixel in 0..6 * n * n {
                let d = pixel_direction(n, pixel) * 3.7;
                let (face, u, v, depth) = project(d);
                assert_eq!(pixel_index(n, face, u, v), pixel, "n {n} pixel {pixel}");
                assert!((depth - 3.7).abs() < 1e-5);
            }
        }
    }

    #[test]
    fn dont_care_is_all_four_corners_behind_the_plane() {
        let n = 6;
        for normal in [
            Vec3::Y,
            Vec3::new(0.3, -0.8, 0.52).normalize(),
            Vec3::new(-0.9, 0.1, 0.42).normalize(),
        ] {
            for pixel in 0..6 * n * n {
                let (face, row, col) = split_pixel(n, pixel);
                let step = 2.0 / n as f32;
                let (u0, v0) = (col as f32 * step - 1.0, row as f32 * step - 1.0);
                let corners_behind =
                    [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                        .iter()
                        .all(|&(du, dv)| {
                            face_direction(face, u0 + du * step, v0 + dv * step).dot(normal) < -1e-6
                        });
                let corners_front =
                    [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                        .iter()
                        .any(|&(du, dv)| {
                            face_direction(face, u0 + du * step, v0 + dv * step).dot(normal) > 1e-6
                        });
                if corners_behind {
                    assert!(pixel_is_dont_care(n, pixel, normal));
                }
                if corners_front {
                    assert!(!pixel_is_dont_care(n, pixel, normal));
                }
            }
        }
    }

    #[test]
    fn half_of_the_pixels_of_an_axis_aligned_normal_are_dont_care() {
        let n = 8;
        let count = (0..6 * n * n)
            .filter(|&p| pixel_is_dont_care(n, p, Vec3::Y))
            .count() as u32;
        // The -y face and the lower halves of the four side faces, less the row or column of
        // pixels touching the horizon (a corner on the plane keeps a pixel).
        assert_eq!(count, n * n + 4 * n * (n / 2 - 1));
    }

    #[test]
    fn neighbours_are_adjacent_across_faces_too() {
        let n = 8;
        // Inside a face the index arithmetic agrees with stepping the direction and projecting.
        for p in 0..6 * n * n {
            let (face, row, col) = split_pixel(n, p);
            if row == 0 || col == 0 || row == n - 1 || col == n - 1 {
                continue;
            }
            let step = 2.0 / n as f32;
            let (u, v) = (
                (col as f32 + 0.5) * step - 1.0,
                (row as f32 + 0.5) * step - 1.0,
            );
            let mut projected: Vec<u32> = [-1.0f32, 0.0, 1.0]
                .iter()
                .flat_map(|&dv| [-1.0f32, 0.0, 1.0].map(|du| (du, dv)))
                .filter(|&(du, dv)| (du, dv) != (0.0, 0.0))
                .map(|(du, dv)| {
                    let (f, pu, pv, _) =
                        project(face_direction(face, u + du * step, v + dv * step));
                    pixel_index(n, f, pu, pv)
                })
                .collect();
            let mut got = neighbours(n, p).to_vec();
            projected.sort();
            got.sort();
            assert_eq!(got, projected, "pixel {p}");
        }
        // Every pixel's neighbours are distinct from it, lie within a small angle of it, and
        // count it among their own neighbours (the relation is symmetric, edges included).
        for p in 0..6 * n * n {
            let d = pixel_direction(n, p).normalize();
            for q in neighbours(n, p) {
                assert_ne!(q, p);
                let angle = d.angle_between(pixel_direction(n, q).normalize());
                assert!(angle < 0.6, "pixel {p} neighbour {q}: {angle} rad");
                let corner = {
                    let (_, r, c) = split_pixel(n, p);
                    (r == 0 || r == n - 1) && (c == 0 || c == n - 1)
                };
                assert!(corner || neighbours(n, q).contains(&p), "{p} -> {q}");
            }
        }
        // A face-border pixel reaches the adjacent face.
        let edge = pixel_index(n, 0, 0.99, 0.0);
        assert!(
            neighbours(n, edge)
                .iter()
                .any(|&q| split_pixel(n, q).0 != 0)
        );
    }

    #[test]
    fn interval_brackets_the_layers() {
        let q = DepthQuantizer::new(1.0, 101.0);
        let (lo, hi) = q.interval(10.0, 20.0);
        assert!(q.depth(lo) >= 10.0 && q.depth(hi) < 20.0 && lo <= hi);
        assert!(q.depth(lo - 1) < 10.0 && q.depth(hi + 1) >= 20.0 - 1e-3);
        assert_eq!(
            q.interval(f32::INFINITY, f32::INFINITY),
            (DEPTH_MAX, DEPTH_MAX)
        );
        assert_eq!(q.interval(50.0, f32::INFINITY).1, DEPTH_MAX);
        let (lo, hi) = q.interval(10.0, 10.0 + 1e-6);
        assert_eq!(lo, hi);
    }
}
