//! Defect localisation: places each detection on the SLAM map by casting
//! camera rays through the crack it found (its centre line traced in the
//! image, or its box) into the voxel map and refining the hit against the
//! map points, measures the crack on that surface, and fuses observations of
//! the same crack across frames into defect candidates (position, extent,
//! length, supporting views, best view). It owns the observations and
//! defects tables; it reads the flight model from `ingest` and detections
//! from `detect`.

pub mod crop;
pub mod error;
pub mod fusion;
pub mod observation;
pub mod records;
pub mod stage;
pub mod surface;
pub mod trace;

pub use error::LocaliseError;
pub use fusion::{DefectCandidate, FusionOptions};
pub use observation::{Observation, Outcome};
pub use records::{DefectRecord, ViewRecord};
pub use stage::{LocaliseOptions, LocaliseSummary, localise};
