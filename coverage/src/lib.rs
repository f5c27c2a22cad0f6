//! Inspection coverage: recomputes, voxel by voxel, what the flight
//! actually inspected under the View model (viewing cone, distance band,
//! incidence, occlusion, image quality) against the plan.
//!
//! The same rules choose where detect runs the model: each exposed face of
//! the map's voxels and its best views, by the View model's measure
//! ([`best`]).
//!
//! Coverage is counted on the exposed faces of the target voxels ([`face`]).
//! [`cover`] puts the [`shots`] (flight frames with a pose, or a plan's
//! viewpoints) in a KD-tree of camera centres; each face, in parallel,
//! takes the shots within the band's outer distance and runs the [`view`]
//! rules in order, keeping the view count, the finest-GSD view and, when it
//! is not inspected, the furthest rule any shot got to. Occlusion walks the
//! voxel map by DDA and searches only occupied voxels for map points near
//! the line of sight, so a ray that passes beside a surface inside a voxel
//! is not stopped by the voxel. `postflight_core::motion` judges blur
//! from the fitted camera velocity; [`reach`] tries standpoints across the band and the
//! incidence limit for faces nobody inspected, to tell gaps from the
//! uninspectable; the `targets` crate says which voxels are the structure
//! and its elements. The
//! stage ([`stage`]) writes `coverage.parquet` and `coverage.json` (laid
//! out in `postflight_core::outputs::coverage`; its counts, `summary`). The follow-up flight for
//! the gaps is the `replan` crate's; it asks these same rules which gaps a
//! viewpoint inspects.

pub mod best;
pub mod cover;
pub mod error;
pub mod face;
pub mod focus;
pub mod reach;
pub mod records;
pub mod settings;
pub mod shots;
pub mod stage;
mod summary;
pub mod view;

pub use best::{Choosing, best_views};
pub use cover::{FaceCover, Shot, cover, cover_naive};
pub use error::CoverageError;
pub use face::{Face, exposed_faces};
pub use postflight_core::ViewSettings;
pub use settings::{CoverageConfig, CoverageSettings};
pub use shots::{FlightShots, flight_shots, lenses};
pub use stage::{CoverageOptions, coverage};
pub use targets::Targets;
pub use view::{Miss, Sight};
