//! What can go wrong while reporting.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error(transparent)]
    Run(#[from] ingest::IngestError),
    #[error("{}: {why}", path.display())]
    Table { path: PathBuf, why: String },
    #[error("cannot write the Rerun recording {}: {why}", path.display())]
    Recording { path: PathBuf, why: String },
}
