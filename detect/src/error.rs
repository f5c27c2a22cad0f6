//! Errors of the detect stage, each naming the problem and the fix.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    #[error("{0}")]
    Runtime(String),
    #[error("model {}: {why}", path.display())]
    Model { path: PathBuf, why: String },
}
