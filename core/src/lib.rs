//! The model every postflight stage shares, and the run directory they
//! share it through.
//!
//! - The flight: [`Flight`] (what ingest found, loaded from a run
//!   directory), its [`Frame`]s, [`Camera`]s and body [`Trajectory`], and
//!   rigid [`pose`]s.
//! - The map: point clouds (PLY, PCD), voxel occupancy, the KD-tree of map
//!   points and ray casting through voxels ([`map`]), with one
//!   [`FaceSide`] for a voxel's sides.
//! - The plan that was flown and the View model it was made for ([`plan`]),
//!   and a frame's motion blur, which the View model judges ([`motion`]).
//! - Condition states from crack width, by the material's limits, and the
//!   `[condition]` settings that choose them ([`condition`]).
//! - Where detection matters: the parts of each frame that show a patch it
//!   is among the best views of ([`best_views`]).
//! - Detections: boxes with their scores and kinds ([`detection`],
//!   [`defect_kind`]: a crack or an area defect), and the pixels of those
//!   a segmentation model gives ([`mask`]); a crack's
//!   centre line on the structure ([`trace`]).
//! - The run directory ([`RunDir`]: atomic writes), the run log of
//!   `postflight run` ([`RunLog`]), and the file contract ([`outputs`]):
//!   for every stage its files, its summary and one typed writer and reader
//!   per table.
//! - Regions of the map frame, as keep-out zones and focus regions are
//!   given ([`region`]).
//! - The structure as inspectors name it: elements and places on them
//!   ([`structure`]).
//! - Settings named by their key in `postflight.toml` ([`setting`]), and
//!   lists of numbers as flags and tools write them ([`runs`]).
//!
//! Nothing heavy: no ONNX Runtime, Rerun, web server or recording format;
//! those belong to the stages that need them.

pub mod best_views;
pub mod camera;
pub mod condition;
pub mod crs;
pub mod defect_kind;
pub mod detection;
pub mod error;
pub mod flight;
pub mod frame;
pub mod geo;
pub mod kind;
pub mod map;
pub mod mask;
pub mod motion;
pub mod outputs;
pub mod plan;
pub mod pose;
pub mod region;
pub mod run_dir;
pub mod run_log;
pub mod runs;
pub mod serde_pose;
pub mod setting;
pub mod shown;
pub mod similarity;
pub mod structure;
pub mod table;
pub mod time;
pub mod trace;
pub mod trajectory;
pub mod user_file;
pub mod view;

pub use camera::{Camera, Distortion, Intrinsics};
pub use error::Error;
pub use flight::Flight;
pub use frame::{Frame, ImageEncoding, ImageLocation, ImageStatus, MessageLocation, PoseStatus};
pub use map::FaceSide;
pub use outputs::Stage;
pub use plan::{FlownPlan, InspectionPlan, PathPoint, PlanFile, Viewpoint, YawUnit};
pub use run_dir::RunDir;
pub use run_log::{InputFile, RunLog, StageRecord};
pub use setting::{InvalidSetting, Key};
pub use trajectory::{PoseAt, Trajectory};
pub use view::{ViewModel, ViewSettings};
