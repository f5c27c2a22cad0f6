//! The human review queue: inspectors accept or reject each proposed crack.
//! `store` keeps the decisions (SQLite, one transaction per decision, an
//! audit trail of who decided what, when, and what it replaced).

pub mod store;

pub use store::{Decision, ReviewError, ReviewStore, Verdict};
