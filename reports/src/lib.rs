//! Reports: turns a run directory into what people read and use: the run in
//! numbers (`summary.json`), the self-contained HTML report (`report.html`:
//! coverage pictures, defect candidates in review order, the follow-up
//! flight) and the Rerun recording (`flight.rrd`), and the human review
//! queue of proposed cracks (`review`: a small web application over a SQLite store of decisions). It
//! reads the outputs of every stage and writes nothing that another stage
//! reads back.

pub mod error;
pub mod html;
pub mod recording;
pub mod results;
pub mod review;
pub mod stage;
pub mod summary;
pub mod svg;
pub mod views;

pub use error::ReportError;
pub use results::{RunResults, TargetVoxel, VoxelStatus, review_priority};
pub use stage::{ReportOptions, report};
pub use summary::RunSummary;
