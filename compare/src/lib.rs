//! Repeat inspections of one structure: what changed since the last flight.
//!
//! The earlier flight's map is put onto the later one's (their SLAM frames
//! differ) by `postflight_core::map::register`: a coarse yaw search, then
//! point-to-plane ICP, with the transform, the residual and the overlap,
//! refusing maps that do not overlap enough to trust. [`changes`] moves the earlier defect candidates
//! into the later frame, matches them with the later ones and classifies
//! each; where a crack now runs on, [`sight`] says whether the earlier
//! flight's frames had that surface in view. [`stage`] reads both run
//! directories and writes `changes.json` and `changes.parquet` into the
//! later one (laid out in `postflight_core::outputs::changes`).

pub mod changes;
pub mod error;
pub mod settings;
pub mod sight;
pub mod stage;

pub use error::CompareError;
pub use postflight_core::map::register::{RegisterOptions, Registration, register};
pub use settings::{CompareConfig, CompareSettings};
pub use stage::{CompareOptions, compare};
