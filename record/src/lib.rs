//! The element record a bridge owner submits, from a flight: each of the
//! structure's elements as the AASHTO *Manual for Bridge Element
//! Inspection* numbers it, its total quantity, how much of it the flight
//! inspected, and its quantities in condition states 1 to 4, with its
//! cracking defect's beneath it.
//!
//! [`catalogue`] declares the manual's elements and defects postflight
//! records; [`elements`] maps postflight's elements onto them and lays each
//! out in [`cells`]; [`cracks`] says which candidates count (the reviewers'
//! decisions) and in which state; [`pattern`] finds cracks that run in a
//! pattern by their spacing; [`quantities`] puts each cell in the worst
//! state over it and fills what the flight did not see as `[record]
//! not_inspected` says; [`submission`] writes the FHWA's and the SNBI's
//! files; [`stage`] reads the run directory (coverage, localise) and writes
//! the files laid out in `postflight_core::outputs::record`.

pub mod catalogue;
pub mod cells;
pub mod cracks;
pub mod elements;
pub mod error;
pub mod pattern;
pub mod quantities;
pub mod settings;
pub mod stage;
pub mod submission;

pub use cracks::{Decisions, ReviewerCall};
pub use error::RecordError;
pub use settings::{ElementChoice, RecordConfig, RecordSettings};
pub use stage::{RecordOptions, record};
