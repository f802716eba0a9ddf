//! Area-uniform points on the scene surface: the pairs of the accuracy check, of the GPU query
//! tests and of the benchmarks.

use cssm_formats::Scene;
use glam::Vec3;

/// World-space area of a triangle.
pub fn triangle_area([a, b, c]: [Vec3; 3]) -> f32 {
    0.5 * (b - a).cross(c - a).length()
}

/// A point on the scene surface.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    /// Triangle index.
    pub triangle: usize,
    /// Barycentric coordinates.
    pub bary: [f32; 3],
    /// Position.
    pub position: Vec3,
    /// Unit geometric normal.
    pub normal: Vec3,
}

/// Area-uniform sampler of surface points; draw its numbers from [`crate::SplitMix64`] so the
/// same seed gives the same points everywhere.
pub struct SurfaceSampler<'a> {
    scene: &'a Scene,
    cdf: Vec<f64>,
}

impl<'a> SurfaceSampler<'a> {
    /// Sampler over all triangles of `scene`.
    pub fn new(scene: &'a Scene) -> Self {
        let mut acc = 0.0;
        let cdf = (0..scene.triangles.len())
            .map(|t| {
                acc += triangle_area(scene.triangle(t)) as f64;
                acc
            })
            .collect();
        Self { scene, cdf }
    }

    /// The surface point for three uniform numbers in `[0, 1)`.
    pub fn point(&self, r: [f64; 3]) -> SurfacePoint {
        let total = *self.cdf.last().unwrap_or(&0.0);
        let t = self
            .cdf
            .partition_point(|&c| c <= r[0] * total)
            .min(self.cdf.len() - 1);
        let su = r[1].sqrt() as f32;
        let bary = [1.0 - su, su * (1.0 - r[2] as f32), su * r[2] as f32];
        let [a, b, c] = self.scene.triangle(t);
        SurfacePoint {
            triangle: t,
            bary,
            position: a * bary[0] + b * bary[1] + c * bary[2],
            normal: (b - a).cross(c - a).normalize_or_zero(),
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    #[test]
    fn points_follow_area() {
        // Two triangles, the second with three times the area of the first.
        let scene = cssm_formats::Scene::from_triangles(
            vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::new(10.0, 0.0, 0.0),
                Vec3::new(13.0, 0.0, 0.0),
                Vec3::new(10.0, 1.0, 0.0),
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        let sampler = super::SurfaceSampler::new(&scene);
        let mut rng = crate::SplitMix64(3);
        let n = 20_000;
        let mut second = 0;
        for _ in 0..n {
            let p = sampler.point([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
            let [a, b, c] = scene.triangle(p.triangle);
            let back = a * p.bary[0] + b * p.bary[1] + c * p.bary[2];
            assert!((back - p.position).length() < 1e-5);
            assert!((p.normal - Vec3::Z).length() < 1e-6);
            second += usize::from(p.triangle == 1);
        }
        let share = second as f64 / n as f64;
        assert!((share - 0.75).abs() < 0.015, "{share}");
    }
}
