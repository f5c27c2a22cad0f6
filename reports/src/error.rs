//! What can go wrong while reporting.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Run(#[from] postflight_core::Error),
    #[error(transparent)]
    Flight(#[from] ingest::IngestError),
    #[error("cannot write the Rerun recording {}: {why}", path.display())]
    Recording { path: PathBuf, why: String },
}
