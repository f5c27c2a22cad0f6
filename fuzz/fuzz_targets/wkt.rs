//! A coordinate reference system as OGC WKT (a LAS file's WKT VLR).
#![no_main]
libfuzzer_sys::fuzz_target!(|text: &str| {
    if let Ok(crs) = postflight_core::crs::Crs::from_wkt(text) {
        let _ = crs.projection();
    }
});
