//! `cargo +nightly fuzz run gltf`: see `fuzz/README.md` and [`cssm_fuzz::gltf`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = cssm_fuzz::gltf(data);
});
