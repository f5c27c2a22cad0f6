//! Errors of the replan stage, each naming the problem and the fix.

use postflight_core::InvalidSetting;

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
}
