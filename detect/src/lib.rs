//! Crack detection: runs the inspector's open-vocabulary detector (YOLO-World
//! exported to ONNX, prompt "crack") through ONNX Runtime over every frame of
//! an ingested flight, and owns the detections table it writes into the run
//! directory. It reads frames through `ingest` and knows nothing of maps or
//! coverage.

pub mod error;
pub mod runtime;

pub use error::DetectError;
pub use runtime::{Library, Runtime, locate};
pub mod boxes;
pub mod decode;
pub mod letterbox;
pub mod signature;
