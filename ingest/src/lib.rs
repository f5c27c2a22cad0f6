//! Flight ingest, and the flight model every postflight stage shares.
//!
//! This crate owns reading a ROS 2 flight recording (MCAP, CDR) into typed
//! data: camera [`Frame`]s with their poses, [`Camera`] intrinsics and
//! extrinsics, the body [`Trajectory`], the SLAM map ([`map`]: point cloud,
//! voxel occupancy, KD-tree) and the [`InspectionPlan`]. The ingest stage
//! ([`ingest`]) makes one pass over a recording, salvaging what a truncated or
//! damaged file still holds, and writes `frames.parquet`,
//! `trajectory.parquet`, `cameras.json` and `ingest.json` into a run
//! directory; later stages open that with [`Flight::load`] and decode images
//! lazily from the recording.

pub mod camera;
pub mod error;
pub mod flight;
pub mod frame;
pub mod image;
pub mod map;
pub mod plan;
pub mod pose;
pub mod recording;
pub mod ros;
pub mod run_dir;
pub mod run_log;
pub mod serde_pose;
pub mod stage;
pub mod tables;
pub mod tf;
pub mod trajectory;

pub use camera::{Camera, Distortion, Intrinsics};
pub use error::IngestError;
pub use flight::Flight;
pub use frame::{Frame, ImageStatus, PoseStatus};
pub use plan::{InspectionPlan, ViewModel, Viewpoint};
pub use run_dir::RunDir;
pub use run_log::{InputFile, RunLog, StageRecord};
pub use stage::{IngestOptions, IngestSummary, Progress, ingest};
pub use trajectory::{PoseAt, Trajectory};
