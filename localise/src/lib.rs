//! Defect localisation: places each detection on the SLAM map by casting
//! camera rays through the crack it found (its centre line traced in the
//! image, or its box) into the voxel map and refining the hit against the
//! map points, measures the crack on that surface (its length along the
//! centre line, its width across it), and fuses observations of the same
//! crack across frames into defect candidates (position, extent, length,
//! width, supporting views, best view). It writes the observations and
//! defects tables (laid out in `postflight_core::outputs::localise`); it
//! reads the flight and the detections from the run directory, and frames'
//! images from the recording through `ingest`.

pub mod blur;
pub mod centre_line;
pub mod contrast;
pub mod crop;
pub mod crossing;
pub mod error;
pub mod evidence;
mod flight_widths;
pub mod fused_line;
pub mod fusion;
pub mod joint;
pub mod observation;
pub mod records;
pub mod settings;
mod slot;
pub mod stage;
pub mod stats;
pub mod surface;
pub mod trace;
pub mod union_find;
pub mod view_width;
pub mod width;

pub use error::LocaliseError;
pub use fusion::DefectCandidate;
pub use observation::Observation;
pub use settings::{LocaliseConfig, LocaliseSettings};
pub use stage::{LocaliseOptions, localise};
