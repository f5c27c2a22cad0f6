//! Errors of fleets and batch runs, each naming the problem and what to do.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("manifest {}: {why}", path.display())]
    Manifest { path: PathBuf, why: String },

    #[error("fleet directory {}: {why}", path.display())]
    Fleet { path: PathBuf, why: String },

    #[error(
        "{} holds {entry}, which `postflight fleet` did not write there; move it away (the fleet's tables go in {})",
        dir.display(), dir.display()
    )]
    NotOurs { dir: PathBuf, entry: String },

    #[error("{0}")]
    Slurm(String),

    #[error(transparent)]
    Core(#[from] postflight_core::Error),
}
