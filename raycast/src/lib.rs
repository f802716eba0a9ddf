//! The exact CPU reference that the bake and the runtime share, in a crate of its own so the
//! runtime never depends on the bake (and an app that embeds the runtime never compiles xatlas):
//!
//! - [`SceneBvh`] ([`bvh`]): ray casting against a scene with obvhs: segment tests (the ground
//!   truth of every visibility answer), closest hits (the path tracer, the CPU direct light),
//!   first and second hits (the bake's depth cube maps, §3.2.1).
//! - [`SurfaceSampler`] ([`sample`]): area-uniform points on the surface.
//! - [`SplitMix64`] ([`rng`]): the fixed seeded generator every sample set is drawn from.
//!
//! ```
//! use cssm_raycast::{SceneBvh, SplitMix64, SurfaceSampler};
//! let scene = cssm_formats::Scene::load(
//!     &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell-box"),
//! )?;
//! let (bvh, sampler, mut rng) = (SceneBvh::new(&scene), SurfaceSampler::new(&scene), SplitMix64(1));
//! let mut draw = || sampler.point([rng.next_f64(), rng.next_f64(), rng.next_f64()]);
//! let (a, b) = (draw(), draw());
//! let clear = bvh.segment_clear(a.position + 1e-3 * a.normal, b.position + 1e-3 * b.normal);
//! println!("the two points see each other: {clear}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod bvh;
pub mod rng;
pub mod sample;

pub use bvh::{
    DualHit, FrontHit, HitReducer, SceneBvh, SharedAxisRays, WatertightRay, reduce_hits,
    scene_triangles,
};
pub use rng::SplitMix64;
pub use sample::{SurfacePoint, SurfaceSampler, triangle_area};
