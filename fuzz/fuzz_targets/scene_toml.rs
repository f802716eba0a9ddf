//! `cargo +nightly fuzz run scene_toml`: see `fuzz/README.md` and [`cssm_fuzz::scene_toml`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = cssm_fuzz::scene_toml(data);
});
