//! Errors of the detect stage, each naming the problem and the fix.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum DetectError {
    #[error(transparent)]
    Setting(#[from] postflight_core::InvalidSetting),
    #[error(transparent)]
    Run(#[from] postflight_core::Error),
    /// Finding or starting ONNX Runtime.
    #[error("{0}")]
    Runtime(String),
    #[error("model {}: {why}", path.display())]
    Model { path: PathBuf, why: String },
    #[error("embeddings {}: {why}", path.display())]
    Embeddings { path: PathBuf, why: String },
    #[error(transparent)]
    Flight(#[from] ingest::IngestError),
    #[error(
        "none of the {frames} frames could be decoded (frame {first}: {why}); check the recording's images with `postflight ingest`"
    )]
    NoFrames {
        frames: u64,
        first: u32,
        why: String,
    },
    #[error("cannot merge the shares of {}: {why}", run.display())]
    Shards { run: PathBuf, why: String },
    #[error("inference failed on frame {frame}: {why}")]
    Inference { frame: u32, why: String },
}
