//! Errors of the coverage stage, each naming the problem and the fix.

#[derive(Debug, thiserror::Error)]
pub enum CoverageError {
    #[error(transparent)]
    Run(#[from] postflight_core::Error),
    #[error(transparent)]
    Setting(#[from] postflight_core::InvalidSetting),
    #[error(transparent)]
    Region(#[from] postflight_core::region::RegionError),
    #[error(transparent)]
    Flight(#[from] ingest::IngestError),
    #[error(transparent)]
    Structure(#[from] targets::StructureError),
    #[error(
        "the flight has no camera (no image topic was ingested); check `postflight ingest`'s image topics"
    )]
    NoCamera,
    #[error(
        "a camera of the flight has no intrinsics; rerun `postflight ingest` with {}",
        ingest::settings::keys::camera_info_file
    )]
    NoIntrinsics,
    #[error(
        "no frame of the flight has a pose, so nothing can be judged; check the pose source with `postflight ingest`"
    )]
    NoPoses,
    #[error(
        "no camera came within {max_distance_m} m of any target voxel (cameras span {cameras}, targets span {targets}); check that the poses and the targets are in the same world frame"
    )]
    CamerasTooFar {
        max_distance_m: f64,
        cameras: String,
        targets: String,
    },
    #[error(
        "views near defects need the defect candidates of `postflight localise` ({}); run it first",
        postflight_core::outputs::localise::files::DEFECTS_JSON
    )]
    NoDefects,
}
