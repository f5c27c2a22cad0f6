//! Inspection coverage and replanning: recomputes, voxel by voxel, what the
//! flight actually inspected under the View model (viewing cone, distance
//! band, incidence, occlusion, image quality) against the plan, and plans a
//! follow-up flight for the gaps as a Generalized TSP with its own solver. It
//! owns the coverage tables and the follow-up plan; it reads only the flight
//! model from `ingest`.

pub mod cover;
pub mod error;
pub mod face;
pub mod gtsp;
pub mod motion;
pub mod reach;
pub mod records;
pub mod replan;
pub mod settings;
pub mod stage;
pub mod targets;
pub mod view;

pub use cover::{FaceCover, Shot, cover, cover_naive};
pub use error::CoverageError;
pub use face::{Face, exposed_faces};
pub use replan::{ReplanOptions, ReplanSummary, Unplannable, replan};
pub use settings::{CoverageSettings, ViewSettings};
pub use stage::{CoverageOptions, CoverageSummary, Targets, coverage};
pub use view::{Miss, Sight};
