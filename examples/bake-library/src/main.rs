//! Bakes a scene with the `cssm-bake` library from a program of your own, and writes the
//! `.cssm` file that `embed-runtime` (or `cssm render --cssm`) renders with.
//!
//! ```sh
//! cargo run --release --manifest-path examples/bake-library/Cargo.toml -- \
//!     scenes/cornell-box cornell-box.cssm
//! ```

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene_dir = PathBuf::from(args.next().unwrap_or_else(|| "scenes/cornell-box".into()));
    let out = PathBuf::from(args.next().unwrap_or_else(|| "cornell-box.cssm".into()));

    let scene = cssm_formats::Scene::load(&scene_dir)?;
    let options = cssm_bake::BakeOptions {
        atlas_resolution: 64,
        cube_resolution: 32,
        ..Default::default()
    };
    let baked = cssm_bake::bake(&scene, &options, &mut |_progress| {})?;
    // Written under a temporary name and renamed: an interrupted run leaves no partial file.
    cssm_formats::cssm::write_atomic(&out, &baked.file)?;
    println!(
        "{}: {} depth maps, compression {:.1} : 1 -> {}",
        scene.name,
        baked.file.texels.len(),
        baked.stats.ratio_gpu(),
        out.display()
    );
    Ok(())
}
