//! A OBJ map, as `--map` reads it.
#![no_main]
libfuzzer_sys::fuzz_target!(|bytes: &[u8]| {
    let _ = postflight_core::map::PointCloud::parse(bytes, "obj");
});
