//! Keep-out zones as a GeoJSON file, placed at a geo origin.
#![no_main]
use nalgebra::Point3;
use postflight_core::geo::{GeoOrigin, Geodetic};

libfuzzer_sys::fuzz_target!(|json: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zones.geojson");
    std::fs::write(&path, json).unwrap();
    let origin = GeoOrigin {
        position: Geodetic {
            latitude_deg: 47.3977,
            longitude_deg: 8.5456,
            altitude_m: 488.0,
        },
        yaw_deg: 0.0,
    };
    let _ = replan::airspace::read_zones(&path, &origin, &Point3::origin());
});
