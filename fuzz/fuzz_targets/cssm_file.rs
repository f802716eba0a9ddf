//! `cargo +nightly fuzz run cssm_file`: see `fuzz/README.md` and [`cssm_fuzz::cssm_file`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = cssm_fuzz::cssm_file(data);
});
