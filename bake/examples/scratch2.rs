use cssm_bake::{check::*, raycast::SceneBvh};
use cssm_formats::{visibility::*, Scene, cube::*};
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let file = cssm_formats::cssm::read(std::path::Path::new(&path)).unwrap();
    let scene = Scene::load(std::path::Path::new("scenes/cornell-box")).unwrap();
    let bvh = SceneBvh::new(&scene);
    let q = VisibilityQuery::new(&file, QueryOptions { bias_near: 1.0, bias_relative: 0.0, pcf: false });
    let n = file.params.cube_resolution;
    let quant = DepthQuantizer::new(file.params.near, file.params.far);
    let s = SurfaceSampler::new(&scene);
    let mut rng = SplitMix64(5);
    let mut shown = 0;
    for _ in 0..20000 {
        let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
        let a = s.point(r()); let b = s.point(r());
        let Some(t) = q.texel_at(a.triangle, a.bary) else { continue };
        let c = q.cube_centre(t);
        let side = if (c - b.position).dot(b.normal) >= 0.0 { 1.0 } else { -1.0 };
        let truth = bvh.segment_clear(c, b.position + b.normal * side * 0.1);
        let v = q.visible(t, b.position);
        if !truth && v && shown < 12 {
            shown += 1;
            let d = b.position - c;
            let (face, u, vv, depth) = project(d);
            let pixel = pixel_index(n, face, u, vv);
            let pd = pixel_direction(n, pixel);
            let exact = bvh.dual_hit(c, d / depth, 0.01);
            let centre_ray = bvh.dual_hit(c, pd, 0.01);
            let code = q.depth_code(t, pixel);
            println!("tex {t} n {:?} c {c:.1} -> p_i {:.1} (tri {}) depth {depth:.1}; exact ray {:.1}/{:.1}; pixel ray {:.1}/{:.1}; stored {:.1} dontcare {}",
              file.texels[t as usize].normal, b.position, b.triangle, exact.first, exact.second, centre_ray.first, centre_ray.second, quant.depth(code), pixel_is_dont_care(n, pixel, file.texels[t as usize].nrm()));
        }
    }
}
