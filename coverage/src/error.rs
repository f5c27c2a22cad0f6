//! Errors of the coverage stage, each naming the problem and the fix.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum CoverageError {
    #[error("{0}")]
    Option(String),
    #[error(transparent)]
    Flight(#[from] ingest::IngestError),
    #[error("cannot read targets {}: {why}", path.display())]
    Targets { path: PathBuf, why: String },
    #[error(
        "the flight has no SLAM map (no PointCloud2 topic was recorded); pass the map with --map map.ply (PLY or PCD, in the world frame of the poses)"
    )]
    NoMap,
    #[error("cannot write {}: {why}", path.display())]
    Write { path: PathBuf, why: String },
}
