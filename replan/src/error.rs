//! Errors of the replan stage, each naming the problem and the fix.

use std::path::PathBuf;

use postflight_core::InvalidSetting;
use postflight_core::region::RegionError;

use crate::settings::keys;

#[derive(Debug, thiserror::Error)]
pub enum ReplanError {
    #[error(transparent)]
    Run(#[from] postflight_core::Error),
    #[error(transparent)]
    Flight(#[from] ingest::IngestError),
    #[error(transparent)]
    Setting(#[from] InvalidSetting),
    #[error(
        "the flight has no poses to take off from; give the take-off point with {}",
        keys::home
    )]
    NoTakeOff,
    #[error(
        "the flight's camera has no intrinsics; rerun `postflight ingest` with {}",
        ingest::settings::keys::camera_info_file
    )]
    NoIntrinsics,
    #[error(transparent)]
    Region(#[from] RegionError),
    #[error(
        "cannot read keep-out zones from {}: {why}; give a GeoJSON FeatureCollection of Polygon features (RFC 7946)",
        path.display()
    )]
    KeepOutFile { path: PathBuf, why: String },
    #[error(
        "{} places keep-out zones on the Earth, but the map frame's place on it is unknown; give {}",
        path.display(), keys::geo_origin
    )]
    KeepOutWithoutGeoOrigin { path: PathBuf },
    #[error(
        "the take-off point ({:.1}, {:.1}, {:.1}) is inside keep-out zone '{zone}'; give a take-off point outside it with {}",
        home[0], home[1], home[2], keys::home
    )]
    HomeInKeepOut { home: [f64; 3], zone: String },
    #[error(
        "home ({:.1}, {:.1}, {:.1}) and the 20 m above it are within {clearance_m} m of the map; give a clear take-off point with {} or a smaller {}",
        home[0], home[1], home[2], keys::home, keys::clearance_m
    )]
    HomeBlocked { home: [f64; 3], clearance_m: f64 },
    #[error(
        "the viewpoint at ({:.1}, {:.1}, {:.1}) is a {round_trip_m:.0} m, {:.1} min round trip from home, more than one battery allows ({} {max_m} m, {} {battery_minutes} min); raise them or move {} closer",
        point[0], point[1], point[2], round_trip_s / 60.0, keys::max_sortie_length_m, keys::battery_minutes, keys::home
    )]
    SortieTooLong {
        point: [f64; 3],
        round_trip_m: f64,
        round_trip_s: f64,
        max_m: f64,
        battery_minutes: f64,
    },
    #[error(transparent)]
    SpaceTooLarge(#[from] crate::free_space::TooLarge),
}
