//! The camera of a scene that names none (a directory of OBJ files): from the open side of an
//! open scene, from inside an enclosed one (issue 22: the original Cornell box, open at -z, was
//! seen from behind its back wall).
//!
//! The rule: from the bounding box's centre, rays go to a grid of points on each of the box's
//! four sides (±x, ±z) and its top; a side is open when at least half of its rays leave the box
//! without hitting a triangle that faces the centre (a triangle seen from behind is the skin of
//! a solid object around the centre, not a room's wall). The camera looks from the most open side (ties in the order +z,
//! -z, +x, -x, top: an object open all round, like the bunny, is seen from +z, its usual front),
//! far enough out to frame the whole box. When no side is open, the scene is
//! an enclosed room: the camera stands inside, near the middle of the wall across the room's
//! longer horizontal axis, and looks along that axis with a wider field of view.

use glam::Vec3;

use super::{Camera, DEFAULT_CUTOFF_DEG, DEFAULT_FOV_Y_DEG, DEFAULT_RESOLUTION, SpotLight};

/// Rays per side of the box: a grid of `GRID` x `GRID` points.
const GRID: usize = 5;
/// The fraction of a side's rays that must leave the box for the side to be open.
const OPEN_FRACTION: f32 = 0.5;
/// How much less open than the most open side a side earlier in the order may be and still
/// be chosen.
const NEARLY_AS_OPEN: f32 = 0.1;
/// Field of view inside an enclosed room.
const INSIDE_FOV_Y_DEG: f32 = 60.0;
/// A scene lower than this fraction of its diameter is flat (a floor with a few objects on it,
/// a terrain): seen from the side at its centre's height, it would be a line.
const FLAT_FRACTION: f32 = 0.1;
/// How far above a flat scene's horizon the camera looks down on it from its open side.
const FLAT_ELEVATION_DEG: f32 = 35.0;

/// A side of the bounding box the camera may look from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Side {
    NegZ,
    PosZ,
    NegX,
    PosX,
    Top,
}

impl Side {
    const ALL: [Side; 5] = [Side::PosZ, Side::NegZ, Side::PosX, Side::NegX, Side::Top];

    /// The side's outward direction.
    fn normal(self) -> Vec3 {
        match self {
            Side::NegZ => Vec3::NEG_Z,
            Side::PosZ => Vec3::Z,
            Side::NegX => Vec3::NEG_X,
            Side::PosX => Vec3::X,
            Side::Top => Vec3::Y,
        }
    }

    /// The side in words.
    pub(super) fn describe(self) -> &'static str {
        match self {
            Side::NegZ => "-z",
            Side::PosZ => "+z",
            Side::NegX => "-x",
            Side::PosX => "+x",
            Side::Top => "top (+y)",
        }
    }
}

/// Where the default camera stands, for the warning that reports it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Placement {
    /// Outside the box, on its most open side, with the fraction of that side's rays that left.
    Outside(Side, f32),
    /// Inside an enclosed room.
    Inside,
}

/// The default camera of the scene of `positions` and `triangles`, whose bounds are `lo`, `hi`,
/// and where it stands (see the module docs for the rule).
pub(super) fn default_camera(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    lo: Vec3,
    hi: Vec3,
) -> (Camera, Placement) {
    let centre = 0.5 * (lo + hi);
    let radius = 0.5 * (hi - lo).length();
    let open = Side::ALL.map(|side| (side, openness(positions, triangles, lo, hi, side)));
    let most = open.iter().map(|&(_, o)| o).fold(0.0, f32::max);
    // The first side in order that is open and nearly as open as the most open one: a few
    // rays more or less (an inconsistently wound patch, a handle) do not turn the view.
    let best = open
        .into_iter()
        .find(|&(_, o)| o >= OPEN_FRACTION && o >= most - NEARLY_AS_OPEN);
    match best {
        Some((side, open)) => {
            let half = (0.5 * DEFAULT_FOV_Y_DEG).to_radians();
            let distance = radius / half.sin();
            let up = if side == Side::Top {
                Vec3::NEG_Z
            } else {
                Vec3::Y
            };
            // A flat scene is looked down on from its side, not seen edge on.
            let extent = hi - lo;
            let toward = if side != Side::Top && extent.y < FLAT_FRACTION * extent.length() {
                let elevation = FLAT_ELEVATION_DEG.to_radians();
                side.normal() * elevation.cos() + Vec3::Y * elevation.sin()
            } else {
                side.normal()
            };
            let camera = Camera {
                position: centre + toward * distance,
                target: centre,
                up,
                fov_y_deg: DEFAULT_FOV_Y_DEG,
                resolution: DEFAULT_RESOLUTION,
            };
            (camera, Placement::Outside(side, open))
        }
        None => {
            // Across the longer horizontal axis, from just inside one wall.
            let extent = hi - lo;
            let axis = if extent.x > extent.z {
                Vec3::X
            } else {
                Vec3::Z
            };
            let position = centre - axis * (0.45 * axis.dot(extent));
            let camera = Camera {
                position,
                target: position + axis,
                up: Vec3::Y,
                fov_y_deg: INSIDE_FOV_Y_DEG,
                resolution: DEFAULT_RESOLUTION,
            };
            (camera, Placement::Inside)
        }
    }
}

/// The default light of the scene (see the module docs), and where it is, in words.
pub(super) fn default_light(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    lo: Vec3,
    hi: Vec3,
    camera: &Camera,
) -> (SpotLight, &'static str) {
    let centre = 0.5 * (lo + hi);
    let diameter = (hi - lo).length();
    let height = hi.y - lo.y;
    // diameter^2 W/sr at about half a diameter: the irradiance the ceiling light gives.
    let intensity_at = |distance: f32| diameter * diameter * (distance / (0.5 * diameter)).powi(2);
    let flat = height < FLAT_FRACTION * diameter;
    if !flat && openness(positions, triangles, lo, hi, Side::Top) < OPEN_FRACTION {
        let light = SpotLight {
            position: Vec3::new(centre.x, hi.y - 0.02 * height, centre.z),
            direction: Vec3::NEG_Y,
            cutoff_deg: DEFAULT_CUTOFF_DEG,
            intensity: [diameter * diameter; 3],
        };
        return (light, "under the scene's top, pointing down");
    }
    let direction = (camera.target - camera.position).normalize_or(Vec3::NEG_Y);
    let distance = (camera.target - camera.position).length();
    // The cone holds the whole view (its diagonal half-angle, with a margin).
    let aspect = camera.resolution[0] as f32 / camera.resolution[1].max(1) as f32;
    let tan_half_y = (0.5 * camera.fov_y_deg).to_radians().tan();
    let diagonal = (tan_half_y * (1.0 + aspect * aspect).sqrt())
        .atan()
        .to_degrees();
    let light = SpotLight {
        position: camera.position,
        direction,
        // Within the widest cone the GPU methods render: a wide camera's corners go unlit
        // rather than the scene not rendering at all.
        cutoff_deg: (diagonal + 5.0).min(super::MAX_SPOT_CUTOFF_DEG),
        intensity: [intensity_at(distance); 3],
    };
    (light, "at the camera, the scene being open above")
}

/// The fraction of the rays from the box's centre to a grid of points on `side` that lead out
/// ([`leads_out`]).
fn openness(positions: &[Vec3], triangles: &[[u32; 3]], lo: Vec3, hi: Vec3, side: Side) -> f32 {
    let centre = 0.5 * (lo + hi);
    let n = side.normal();
    // The side's plane point and two axes spanning it.
    let (u_axis, v_axis) = match side {
        Side::NegZ | Side::PosZ => (Vec3::X, Vec3::Y),
        Side::NegX | Side::PosX => (Vec3::Z, Vec3::Y),
        Side::Top => (Vec3::X, Vec3::Z),
    };
    let half = 0.5 * (hi - lo);
    let mut open = 0;
    for i in 0..GRID {
        for j in 0..GRID {
            // Cell centres of the grid, slightly inside the side's edges.
            let s = (i as f32 + 0.5) / GRID as f32 * 2.0 - 1.0;
            let t = (j as f32 + 0.5) / GRID as f32 * 2.0 - 1.0;
            let on_side = centre
                + n * n.abs().dot(half)
                + u_axis * (s * u_axis.dot(half))
                + v_axis * (t * v_axis.dot(half));
            if leads_out(positions, triangles, centre, on_side) {
                open += 1;
            }
        }
    }
    open as f32 / (GRID * GRID) as f32
}

/// Whether the segment from `a` to `b` leads out: it meets no triangle, or the first it meets
/// faces away from `a` (the centre is inside a solid object, the bunny, whose skin it sees from
/// within, not a room's wall). Brute force, Möller-Trumbore: a few hundred segments once per
/// scene without a camera.
fn leads_out(positions: &[Vec3], triangles: &[[u32; 3]], a: Vec3, b: Vec3) -> bool {
    let d = b - a;
    let (t_min, t_max) = (1e-4, 1.0 + 1e-4);
    let mut nearest: Option<(f32, bool)> = None;
    for tri in triangles {
        let [p0, p1, p2] = tri.map(|i| positions[i as usize]);
        let (e1, e2) = (p1 - p0, p2 - p0);
        let p = d.cross(e2);
        // det = -d . (e1 x e2): positive where the triangle's front (counter-clockwise) side
        // faces the ray's origin.
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            continue;
        }
        let inv = 1.0 / det;
        let s = a - p0;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            continue;
        }
        let q = s.cross(e1);
        let v = d.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            continue;
        }
        let t = e2.dot(q) * inv;
        if t > t_min && t < t_max && nearest.is_none_or(|(n, _)| t < n) {
            nearest = Some((t, det > 0.0));
        }
    }
    nearest.is_none_or(|(_, front)| !front)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An axis-aligned box of walls from 0 to `size`, without the walls in `open`, each facing
    /// in (a room) or out (a solid box).
    fn walls(size: Vec3, open: &[Side], facing_in: bool) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let centre = 0.5 * size;
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        let mut quad = |mut corners: [Vec3; 4]| {
            let normal = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
            if (normal.dot(centre - corners[0]) > 0.0) != facing_in {
                corners.reverse();
            }
            let base = positions.len() as u32;
            positions.extend(corners);
            triangles.push([base, base + 1, base + 2]);
            triangles.push([base, base + 2, base + 3]);
        };
        let (x, y, z) = (size.x, size.y, size.z);
        let v = Vec3::new;
        // Floor, always.
        quad([v(0., 0., 0.), v(x, 0., 0.), v(x, 0., z), v(0., 0., z)]);
        let walls = [
            (
                Side::Top,
                [v(0., y, 0.), v(0., y, z), v(x, y, z), v(x, y, 0.)],
            ),
            (
                Side::NegZ,
                [v(0., 0., 0.), v(0., y, 0.), v(x, y, 0.), v(x, 0., 0.)],
            ),
            (
                Side::PosZ,
                [v(0., 0., z), v(x, 0., z), v(x, y, z), v(0., y, z)],
            ),
            (
                Side::NegX,
                [v(0., 0., 0.), v(0., 0., z), v(0., y, z), v(0., y, 0.)],
            ),
            (
                Side::PosX,
                [v(x, 0., 0.), v(x, y, 0.), v(x, y, z), v(x, 0., z)],
            ),
        ];
        for (side, corners) in walls {
            if !open.contains(&side) {
                quad(corners);
            }
        }
        (positions, triangles)
    }

    fn room(size: Vec3, open: &[Side]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        walls(size, open, true)
    }

    fn framed(positions: &[Vec3], triangles: &[[u32; 3]]) -> (Camera, Placement) {
        let lo = positions.iter().fold(Vec3::INFINITY, |a, p| a.min(*p));
        let hi = positions.iter().fold(Vec3::NEG_INFINITY, |a, p| a.max(*p));
        default_camera(positions, triangles, lo, hi)
    }

    fn camera_of(size: Vec3, open: &[Side]) -> (Camera, Placement) {
        let (positions, triangles) = room(size, open);
        framed(&positions, &triangles)
    }

    /// A solid object (its faces outward, the centre inside it) is seen from outside, from +z,
    /// not taken for a closed room.
    #[test]
    fn a_solid_object_is_seen_from_outside() {
        let (positions, triangles) = walls(Vec3::new(4.0, 3.0, 5.0), &[], false);
        let (camera, placement) = framed(&positions, &triangles);
        assert!(
            matches!(placement, Placement::Outside(Side::PosZ, open) if open == 1.0),
            "{placement:?}"
        );
        assert!(camera.position.z > 5.0);
    }

    /// A box open on one side is seen through that side, from outside, looking at its centre.
    #[test]
    fn an_open_room_is_seen_through_its_open_side() {
        let size = Vec3::new(4.0, 3.0, 5.0);
        for side in [Side::NegZ, Side::PosZ, Side::NegX, Side::PosX, Side::Top] {
            let (camera, placement) = camera_of(size, &[side]);
            assert!(
                matches!(placement, Placement::Outside(s, open) if s == side && open == 1.0),
                "{side:?}: {placement:?}"
            );
            let centre = 0.5 * size;
            let out = camera.position - centre;
            assert!(
                out.normalize().dot(side.normal()) > 0.999,
                "{side:?}: {camera:?}"
            );
            // Outside the box, and looking at its centre.
            assert!(out.dot(side.normal()) > side.normal().abs().dot(0.5 * size));
            assert_eq!(camera.target, centre);
            assert!(camera.up.cross(out).length() > 0.5, "up not along the view");
        }
    }

    /// A room (closed above) gets its light under the top, pointing down; a solid object (open
    /// above: the top-centre light would sit inside it) gets it at the camera, covering the
    /// whole view.
    #[test]
    fn the_light_hangs_under_a_ceiling_or_comes_from_the_camera() {
        let size = Vec3::new(4.0, 3.0, 5.0);
        for (facing_in, open) in [(true, &[Side::NegZ][..]), (false, &[][..])] {
            let (positions, triangles) = walls(size, open, facing_in);
            let (camera, _) = framed(&positions, &triangles);
            let (light, _) = default_light(&positions, &triangles, Vec3::ZERO, size, &camera);
            if facing_in {
                assert_eq!(light.direction, Vec3::NEG_Y);
                assert!(light.position.y < size.y && light.position.y > 0.9 * size.y);
            } else {
                assert_eq!(light.position, camera.position);
                let view = (camera.target - camera.position).normalize();
                assert!(light.direction.dot(view) > 0.999);
                assert!(light.cutoff_deg > 0.5 * camera.fov_y_deg && light.cutoff_deg < 90.0);
            }
            assert!(light.intensity[0] > 0.0 && light.intensity[0].is_finite());
        }
        // A camera wider than the widest cone the GPU methods render (a glTF's, say) gets a
        // light they render, not one they refuse (issue 53, class 8).
        let (positions, triangles) = walls(size, &[], false);
        let (mut camera, _) = framed(&positions, &triangles);
        camera.fov_y_deg = 150.0;
        let (light, _) = default_light(&positions, &triangles, Vec3::ZERO, size, &camera);
        assert_eq!(light.cutoff_deg, crate::scene::MAX_SPOT_CUTOFF_DEG);
    }

    /// A flat scene (a 20x10 floor with a 1 m cube on it) is looked down on from its open side,
    /// not seen edge on from its centre's height; the light at the camera lights it.
    #[test]
    fn a_flat_scene_is_looked_down_on() {
        let (mut positions, mut triangles) = walls(Vec3::new(1.0, 1.0, 1.0), &[], false);
        let base = positions.len() as u32;
        let v = Vec3::new;
        positions.extend([
            v(-10., 0., -5.),
            v(10., 0., -5.),
            v(10., 0., 5.),
            v(-10., 0., 5.),
        ]);
        triangles.extend([[base, base + 2, base + 1], [base, base + 3, base + 2]]);
        let (camera, placement) = framed(&positions, &triangles);
        assert!(
            matches!(placement, Placement::Outside(Side::PosZ, _)),
            "{placement:?}"
        );
        let view = (camera.target - camera.position).normalize();
        let down = (-view.y).asin().to_degrees();
        assert!((down - FLAT_ELEVATION_DEG).abs() < 0.01, "{down}");
        let (lo, hi) = (v(-10., 0., -5.), v(10., 1., 5.));
        let (light, _) = default_light(&positions, &triangles, lo, hi, &camera);
        assert_eq!(light.position, camera.position);
        assert!(light.direction.dot(view) > 0.999);
    }

    /// A closed box is seen from inside, across its longer horizontal axis.
    #[test]
    fn an_enclosed_room_is_seen_from_inside() {
        for size in [Vec3::new(8.0, 3.0, 5.0), Vec3::new(4.0, 3.0, 9.0)] {
            let (camera, placement) = camera_of(size, &[]);
            assert_eq!(placement, Placement::Inside);
            let p = camera.position;
            assert!(
                p.cmpgt(Vec3::ZERO).all() && p.cmplt(size).all(),
                "{camera:?}"
            );
            let view = (camera.target - p).normalize();
            let longer = if size.x > size.z { Vec3::X } else { Vec3::Z };
            assert_eq!(view, longer, "{size}");
        }
    }

    /// Sides equally open go in the order +z, -z, +x, -x, top: a box open at -z and +x is seen
    /// from -z, one open all round from +z.
    #[test]
    fn ties_go_to_the_first_side_in_order() {
        let size = Vec3::new(4.0, 3.0, 5.0);
        let (camera, placement) = camera_of(size, &[Side::NegZ, Side::PosX]);
        assert!(
            matches!(placement, Placement::Outside(Side::NegZ, _)),
            "{placement:?}"
        );
        assert!(camera.position.z < 0.0);
        let all = [Side::NegZ, Side::PosZ, Side::NegX, Side::PosX, Side::Top];
        let (camera, placement) = camera_of(size, &all);
        assert!(
            matches!(placement, Placement::Outside(Side::PosZ, _)),
            "{placement:?}"
        );
        assert!(camera.position.z > size.z);
    }
}
