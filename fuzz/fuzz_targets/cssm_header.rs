//! `cargo +nightly fuzz run cssm_header`: see `fuzz/README.md` and [`cssm_fuzz::cssm_header`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = cssm_fuzz::cssm_header(data);
});
