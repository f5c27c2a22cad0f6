//! Fleets of flights: many flights processed by one command, on this
//! machine or a cluster, and their results read as one.
//!
//! - [`manifest`]: the batch manifest (TOML or CSV, one row per flight) and
//!   each flight's run directory, `FLEET_DIR/<structure>/<date or name>/`;
//! - [`task`]: each flight's task record, `batch.json` in its run directory;
//! - [`status`]: where every flight of a manifest stands, from the records
//!   and the engine's queue;
//! - [`slurm`] and [`kubernetes`]: the engines that run the tasks on a
//!   cluster (a Slurm job array; a Kubernetes Indexed Job manifest);
//! - [`tables`] and [`index`]: the fleet's tables (`fleet/*.parquet`,
//!   Hive-partitioned by structure) and its page linking every report.
//!
//! Running one flight is `postflight run`'s work; the binary's `batch`
//! commands drive these pieces.

pub mod error;
pub mod index;
pub mod kubernetes;
pub mod manifest;
pub mod slurm;
pub mod status;
pub mod tables;
pub mod task;

pub use error::Error;
pub use manifest::{FlightEntry, Manifest};
pub use task::{TaskRecord, TaskState, Worker};

/// A JSON file read into `T`; `None` when there is no such file. An
/// unreadable one is an error saying what to do (`fix`).
fn read_json_if_present<T: serde::de::DeserializeOwned>(
    path: &std::path::Path,
    fix: &str,
) -> Result<Option<T>, Error> {
    let text = match std::fs::read_to_string(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        text => text.map_err(|cause| postflight_core::Error::Open {
            path: path.to_owned(),
            cause,
        })?,
    };
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| Error::Fleet {
            path: path.to_owned(),
            why: format!("unreadable ({e}); {fix}"),
        })
}
