//! Map coordinates to latitude, longitude and altitude and back, checked
//! against PROJ (pyproj, an independent implementation) over a 2 km
//! structure, and the map frame found from a flight's GPS fixes.

use crate::common::*;
use nalgebra::Point3;
use postflight_core::geo::GeoOrigin;

#[test]
fn map_points_over_two_kilometres_land_within_a_centimetre_of_proj() {
    let dir = tempfile::tempdir().unwrap();
    // Points of a 2 km square up to 300 m high, around origins on both
    // hemispheres, one in the Arctic, the map turned every way.
    let origins = [
        "47.397742,8.545594,488.0,23.5",
        "-33.8568,151.2153,20.0,-120.0",
        "69.6492,18.9553,35.0,181.0",
    ];
    for text in origins {
        let origin = GeoOrigin::parse(text).unwrap();
        let mut rows = String::new();
        for (i, j, k) in
            (-10..=10).flat_map(|i| (-10..=10).flat_map(move |j| (0..3).map(move |k| (i, j, k))))
        {
            let local = Point3::new(
                f64::from(i) * 100.0,
                f64::from(j) * 100.0,
                f64::from(k) * 150.0,
            );
            let g = origin.to_geodetic(&local);
            rows += &format!(
                "{},{},{},{},{},{}\n",
                local.x, local.y, local.z, g.latitude_deg, g.longitude_deg, g.altitude_m
            );
            let back = origin.to_local(&g);
            assert!(
                (back - local).norm() < 1e-6,
                "{text}: {local} came back as {back}"
            );
        }
        let csv = dir.path().join("points.csv");
        std::fs::write(&csv, rows).unwrap();
        let mut args = vec!["points".to_string(), csv.display().to_string()];
        args.extend(text.split(',').map(str::to_string));
        let out = std::process::Command::new(python())
            .arg(root().join("tests/fixtures/check_geo.py"))
            .args(&args)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        let errors: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        println!("{text}: largest difference from PROJ, metres: {errors}");
        for way in ["forward_m", "backward_m"] {
            assert!(f(&errors[way]) < 0.01, "{text}: {errors}");
        }
    }
}
