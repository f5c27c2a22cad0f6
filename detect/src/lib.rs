//! Crack detection: runs the inspector's open-vocabulary detector (YOLO-World
//! exported to ONNX, prompt "crack") through ONNX Runtime over every frame of
//! an ingested flight, and owns the detections table it writes into the run
//! directory. It reads frames through `ingest` and knows nothing of maps or
//! coverage: which tiles of each frame are worth running (the best views
//! of each patch of the map) is chosen by the `coverage` crate and given to
//! it as a `BestViews` ([`choose`]). One flight can run as shares on many
//! machines and be merged ([`merge`]).

pub mod boxes;
pub mod choose;
pub mod classes;
mod coco;
pub mod convention;
pub mod decode;
mod detector;
pub mod error;
pub mod letterbox;
pub mod masks;
pub mod merge;
mod metadata;
mod pass;
pub mod prompts;
mod read;
pub mod runtime;
pub mod settings;
pub mod signature;
pub mod stage;
pub mod tiles;
mod views;

pub use choose::TilesToRun;
pub use error::DetectError;
pub use runtime::{Device, Library, Runtime, locate};
pub use settings::{DetectConfig, DetectSettings, MergeGap};
pub use stage::{DetectOptions, Estimate, Told, detect};
