//! Flight ingest: reading a flight recording (MCAP with ROS 2 or ROS 1
//! messages, or a ROS 1 bag) into the flight model of `postflight_core`.
//!
//! The ingest stage ([`ingest`]) makes one pass over each recording of a
//! flight (one, or one per sortie: [`recording`], [`bag`]), salvaging what a
//! truncated or damaged file still holds,
//! decodes the ROS messages it needs ([`ros`]), builds the body trajectory
//! from a pose topic or `/tf` ([`tf`]), matches cameras with their
//! calibration ([`calibration`]) and places every frame; it writes
//! `frames.parquet`, `trajectory.parquet`, `cameras.json` and `ingest.json`
//! into a run directory. Later stages load that with
//! `postflight_core::Flight::load` and read images and the recorded maps
//! back from the recordings on demand ([`Recordings`], [`load_map`]).

pub mod bag;
pub mod calibration;
mod cameras;
mod combine;
mod earth;
pub mod error;
pub mod image;
mod ingested;
mod photo_frame;
pub mod photos;
mod placement;
pub mod reconstruction;
pub mod recording;
pub mod reopen;
mod reuse;
pub mod ros;
mod scan;
pub mod settings;
mod slam_frames;
pub mod source;
pub mod stage;
pub mod tf;
mod topics;

pub use error::IngestError;
pub use photos::PhotoFolder;
pub use recording::Recording;
pub use reopen::{Recordings, load_map, map_cloud};
pub use settings::{IngestConfig, IngestSettings};
pub use source::{Source, sources_in};
pub use stage::{IngestOptions, Progress, ingest};
