//! A survey's LAS or LAZ file: header, VLRs (its CRS) and points.
#![no_main]
libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    let _ = postflight_core::map::las::parse(bytes);
});
