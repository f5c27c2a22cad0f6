//! An OctoMap map: binary `.bt` where the input's first byte is even,
//! full `.ot` where it is odd.
#![no_main]
libfuzzer_sys::fuzz_target!(|input: &[u8]| {
    let Some((first, bytes)) = input.split_first() else {
        return;
    };
    let extension = if first % 2 == 0 { "bt" } else { "ot" };
    let _ = postflight_core::map::PointCloud::parse(bytes, extension);
});
