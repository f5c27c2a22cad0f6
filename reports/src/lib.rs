//! Reports: turns a run directory into what people read: the run in numbers
//! (`summary.json`), the self-contained HTML report (`report.html`: coverage
//! pictures, defect candidates in review order, the follow-up flight) and
//! the Rerun recording (`flight.rrd`). [`results`] reads a run directory
//! once (every stage's summary and tables; a stage that has not run is
//! absent) and everything else draws from it; [`views`] draws the target
//! voxels from a side, which the review queue (the `review` crate) shows
//! too. It writes nothing that another stage reads back.

pub mod error;
pub mod html;
pub mod recording;
pub mod results;
pub mod stage;
pub mod summary;
pub mod svg;
pub mod views;

pub use error::ReportError;
pub use results::{RunResults, TargetVoxel, VoxelStatus, review_priority};
pub use stage::{ReportOptions, report};
