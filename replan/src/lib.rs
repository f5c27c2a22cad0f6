//! The replan stage: a follow-up flight for the coverage gaps.
//!
//! From the gaps the coverage stage found (target voxels not inspected that
//! some free standpoint could inspect), [`viewpoints`] draws candidate
//! viewpoints around each gap face and asks the View model (`coverage`'s
//! rules, the same code that judged the flight) which gap voxels each
//! inspects; clusters are per gap voxel and view it needs. [`free_space`] inflates the map by
//! the clearance once, so a check in open air costs one look-up, keeps out
//! of the [`airspace`]'s keep-out zones and below its ceiling, and finds
//! paths (A* over the clear voxel lattice, shortened by line of sight).
//! [`tour`] solves the GTSP from home with the `gtsp` crate and, as GATSBI
//! does, re-solves with lazy collision checks while a flown leg is much
//! longer than its cost; [`route`] is these for one drone's camera and
//! home. [`stage`] ties these together: the [`gaps`] to go back for, the
//! route, its [`sorties`] for the battery (for a team, first a stretch per
//! drone, re-planned as the drone's own route when its camera or home
//! differ: [`team`]), the plan's [`summary`], and its [`outputs`]:
//! `replan.json` (also an inspection plan `postflight coverage
//! --viewpoints` can check) and `replan.csv` (GATSBI's `X,Y,Z,Yaw` path);
//! with a geo origin, [`ground_station`] also writes a
//! QGroundControl mission per sortie (its geofence holding the keep-out
//! columns), KML and GeoJSON, and [`wpml`] a DJI waypoint mission (KMZ).

pub mod airspace;
pub mod error;
pub mod free_space;
mod gaps;
pub mod ground_station;
mod outputs;
pub mod route;
pub mod settings;
mod sorties;
pub mod stage;
mod summary;
pub mod team;
pub mod tour;
pub mod viewpoints;
pub mod wpml;

pub use error::ReplanError;
pub use postflight_core::outputs::replan::GapChoice;
pub use settings::{ReplanConfig, ReplanSettings};
pub use stage::{ReplanOptions, replan};
