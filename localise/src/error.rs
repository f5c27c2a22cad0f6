//! Errors of the localise stage, each naming the problem and the fix.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum LocaliseError {
    #[error("{0}")]
    Option(String),
    #[error(transparent)]
    Flight(#[from] ingest::IngestError),
    #[error(transparent)]
    Detections(#[from] detect::DetectError),
    #[error(
        "the flight has no SLAM map (no PointCloud2 topic was recorded); pass the map with --map map.ply (PLY or PCD, in the world frame of the poses)"
    )]
    NoMap,
    #[error(
        "the map does not overlap the flight: only {hit} of {cast} rays from the cameras meet it (map spans {map}, camera positions span {cameras}); check that the map is in the poses' world frame and in metres"
    )]
    MapMismatch {
        hit: usize,
        cast: usize,
        map: String,
        cameras: String,
    },
    #[error(
        "none of the {detections} detections is in a frame with a pose, so none can be placed; check the pose source with `postflight ingest` (ingest.json lists frames without pose and why)"
    )]
    NoPoses { detections: u64 },
    #[error("cannot write {}: {why}", path.display())]
    Write { path: PathBuf, why: String },
}
