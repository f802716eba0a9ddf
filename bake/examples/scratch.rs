use cssm_bake::{check::*, raycast::SceneBvh};
use cssm_formats::{visibility::*, Scene};
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let file = cssm_formats::cssm::read(std::path::Path::new(&path)).unwrap();
    let scene = Scene::load(std::path::Path::new("scenes/cornell-box")).unwrap();
    let s = SurfaceSampler::new(&scene);
    let bvh = SceneBvh::new(&scene);
    let q = VisibilityQuery::new(&file, QueryOptions::default());
    let mut rng = SplitMix64(1);
    let eps = 1e-4 * scene.diameter();
    let mut by_tri = vec![[0u32; 4]; scene.triangles.len()];
    let mut snapped = [0u32; 4];
    for _ in 0..100000 {
        let mut r = || [rng.next_f64(), rng.next_f64(), rng.next_f64()];
        let a = s.point(r());
        let b = s.point(r());
        let Some(t) = q.texel_at(a.triangle, a.bary) else { continue };
        let truth = exact_visible(&bvh, &a, &b, eps);
        let v = q.visible(t, b.position);
        by_tri[a.triangle][truth as usize * 2 + v as usize] += 1;
        // sender snapped to texel centre
        let tx = &file.texels[t as usize];
        let a2 = SurfacePoint { triangle: a.triangle, bary: a.bary, position: tx.pos(), normal: tx.nrm() };
        let truth2 = exact_visible(&bvh, &a2, &b, eps);
        snapped[truth2 as usize * 2 + v as usize] += 1;
    }
    println!("rows: tri; cols: occ->occ, occ->vis(false visible), vis->occ (false occluded), vis->vis");
    for (t, c) in by_tri.iter().enumerate() { println!("tri {t:2} {:?}", c); }
    println!("snapped sender: {:?} agreement {}", snapped, (snapped[0]+snapped[3]) as f64 / snapped.iter().sum::<u32>() as f64);
}
