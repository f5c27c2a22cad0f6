//! Errors of the coverage stage, each naming the problem and the fix.

use std::path::PathBuf;

use postflight_core::setting::inputs;

#[derive(Debug, thiserror::Error)]
pub enum CoverageError {
    #[error(transparent)]
    Run(#[from] postflight_core::Error),
    #[error(transparent)]
    Setting(#[from] postflight_core::InvalidSetting),
    #[error(transparent)]
    Flight(#[from] ingest::IngestError),
    #[error("cannot read targets {}: {why}", path.display())]
    Targets { path: PathBuf, why: String },
    #[error(
        "no target voxels: pass the plan with {}, or the structure with {}, {} or {}",
        inputs::PLAN,
        inputs::TARGET_BOXES,
        inputs::TARGET_CLOUD,
        inputs::TARGET_MAP
    )]
    NoTargets,
    #[error(
        "the plan is a waypoint path, which names no targets; pass the structure with {}, {} or {}",
        inputs::TARGET_BOXES,
        inputs::TARGET_CLOUD,
        inputs::TARGET_MAP
    )]
    PathWithoutTargets,
    #[error(
        "the targets ({targets}) hold no voxel of the map; check that they are in the map's world frame and metres"
    )]
    TargetsOffMap { targets: String },
    #[error(
        "the targets ({targets}) do not overlap the map: {mapped} of {total} target voxels hold map points (targets span {targets_span}, map spans {map_span}); check that both are in the same world frame and in metres"
    )]
    TargetsMissMap {
        targets: String,
        mapped: usize,
        total: usize,
        targets_span: String,
        map_span: String,
    },
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
