//! `cargo +nightly fuzz run obj_mtl`: see `fuzz/README.md` and [`cssm_fuzz::obj_mtl`].
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let _ = cssm_fuzz::obj_mtl(data);
});
