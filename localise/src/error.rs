//! Errors of the localise stage, each naming the problem and the fix.

#[derive(Debug, thiserror::Error)]
pub enum LocaliseError {
    #[error(transparent)]
    Run(#[from] postflight_core::Error),
    #[error(transparent)]
    Setting(#[from] postflight_core::InvalidSetting),
    #[error(transparent)]
    Flight(#[from] ingest::IngestError),
    #[error(transparent)]
    Structure(#[from] targets::StructureError),
    #[error(
        "detections.parquet names frame {frame} which the ingest has no record of; rerun `postflight detect` after `postflight ingest`"
    )]
    UnknownFrame { frame: u32 },
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
}
