//! What the report stage writes: `report.html` (the page people read),
//! `candidates.csv` (its candidate table, for spreadsheets), `flight.rrd`
//! (the Rerun recording) and, last, its summary `summary.json`: the run in
//! numbers, for batch jobs and dashboards.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::localise::DefectRecord;
use crate::error::Error;
use crate::run_dir::RunDir;
use crate::table::Row;

/// Files of the report stage.
pub mod files {
    pub const REPORT: &str = "report.html";
    pub const CANDIDATES: &str = "candidates.csv";
    pub const RECORDING: &str = "flight.rrd";
    pub const SUMMARY: &str = "summary.json";
}

/// Where `postflight review serve` listens unless told otherwise (the
/// report links to it).
pub const DEFAULT_REVIEW_ADDR: &str = "127.0.0.1:8765";

/// `summary.json`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RunSummary {
    pub run: PathBuf,
    /// The flight's recordings (one, or one per sortie or drone).
    pub recordings: Vec<PathBuf>,
    pub flight_start: String,
    /// Time flown, the recordings' spans added up.
    pub duration_s: f64,
    /// A recording was cut short and salvaged.
    pub truncated: bool,
    pub frames: u64,
    pub frames_with_pose: u64,
    /// `None` until the stage has run.
    pub detections: Option<u64>,
    pub defects: Option<u64>,
    pub coverage: Option<CoverageFigures>,
    pub replan: Option<ReplanFigures>,
    /// Seconds per stage, of the run that produced the current results.
    pub timings_s: BTreeMap<String, f64>,
    pub versions: Versions,
    /// Warnings of every stage, prefixed with the stage.
    pub warnings: Vec<String>,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct CoverageFigures {
    pub target_voxels: usize,
    pub planned_voxels: Option<usize>,
    pub inspected_voxels: usize,
    pub inspected_pct: f64,
    pub planned_inspected_pct: Option<f64>,
    pub gap_voxels: usize,
    pub uninspectable_voxels: usize,
    pub face_area_coverage_pct: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ReplanFigures {
    pub gap_voxels: usize,
    pub planned_gap_voxels: usize,
    pub unplannable_gap_voxels: usize,
    pub waypoints: usize,
    pub sorties: usize,
    pub length_m: f64,
    pub time_s: f64,
}

#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Versions {
    pub postflight: String,
    pub model: Option<PathBuf>,
    /// SHA-256 of the model file.
    pub model_sha256: Option<String>,
    pub onnxruntime: Option<String>,
}

crate::table! {
    /// One row of `candidates.csv`: a defect candidate as the report lists
    /// it, in review order.
    pub struct CandidateRow {
        /// Place in the review order, from 1.
        rank: u32,
        review_priority: f64,
        defect: DefectRecord,
    }
}

/// Write `candidates.csv`.
pub fn write_candidates(run: &RunDir, rows: &[CandidateRow]) -> Result<(), Error> {
    run.write_csv(files::CANDIDATES, CandidateRow::frame(rows))
}
