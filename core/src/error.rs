//! Errors of reading and writing a run directory and the shared inputs
//! (maps, plans), worded for the person running postflight: each names the
//! problem and what to do about it.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("cannot open {}: {cause}; check the path", path.display())]
    Open {
        path: PathBuf,
        cause: std::io::Error,
    },

    #[error("cannot write {}: {cause}", path.display())]
    Write {
        path: PathBuf,
        cause: std::io::Error,
    },

    #[error("table {}: {cause}; rerun the stage that wrote it", path.display())]
    Table {
        path: PathBuf,
        cause: polars::error::PolarsError,
    },

    #[error("run directory {}: {why}", path.display())]
    RunDir { path: PathBuf, why: String },

    #[error("map {}: {why}", path.display())]
    Map { path: PathBuf, why: String },

    #[error("plan {}: {why}", path.display())]
    Plan { path: PathBuf, why: String },

    #[error(
        "{} holds {entry}, which `postflight {stage}` did not write there; move it away or choose another run directory (the stage writes its own files into that folder)",
        dir.display()
    )]
    NotOurs {
        dir: PathBuf,
        entry: String,
        stage: crate::outputs::Stage,
    },

    #[error(
        "{} is in the way: postflight writes a file of that name there, and this is not a file; move it away or choose another run directory",
        path.display()
    )]
    InTheWay { path: PathBuf },

    #[error(transparent)]
    Setting(#[from] crate::setting::InvalidSetting),
}
