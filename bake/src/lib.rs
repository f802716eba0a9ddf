//! Bake pipeline.
pub mod traverse;
