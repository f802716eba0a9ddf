#define_import_path cssm::lowres

// Reduced-resolution sampling (§4.5, Bang 2011): a technique computes its indirect light at
// `factor` times fewer pixels per side, low-res pixel (x, y) standing for the full-res pixel
// at the centre of its factor x factor block, clamped to the image. The technique's sampling
// pass and the edge-aware filters (common/filters.wgsl) read the G-buffer at that pixel.
// Rust twin: common/filters/mod.rs::representative.

fn lowres_representative(low: vec2u, factor: u32, full: vec2u) -> vec2u {
    return min(low * factor + vec2u(factor / 2u), full - vec2u(1u));
}
