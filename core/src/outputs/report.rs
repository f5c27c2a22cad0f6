//! What the report stage writes: `report.html` (the page people read),
//! `candidates.csv` (its candidate table, for spreadsheets), `flight.rrd`
//! (the Rerun recording) and, last, its summary `summary.json`: the run in
//! numbers, for batch jobs and dashboards.

use std::collections::BTreeMap;
use std::path::PathBuf;

use polars::prelude::*;
use serde::{Deserialize, Serialize};

use super::localise::{DefectRecord, ViewFault};
use crate::error::Error;
use crate::run_dir::RunDir;
use crate::structure::Place;

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
    pub flight: PathBuf,
    pub flight_start: String,
    pub duration_s: f64,
    /// The recording was cut short and salvaged.
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

/// One row of `candidates.csv`: a defect candidate as the report lists it.
#[derive(Debug, Clone, PartialEq)]
pub struct CandidateRow<'a> {
    /// Place in the review order, from 1.
    pub rank: u32,
    pub defect: &'a DefectRecord,
    /// Where it is on the structure; `None` before coverage has found the
    /// structure's elements, or off them.
    pub place: Option<Place>,
    pub review_priority: f64,
}

/// Write `candidates.csv`.
pub fn write_candidates(run: &RunDir, rows: &[CandidateRow]) -> Result<(), Error> {
    run.write_csv(files::CANDIDATES, candidates_table(rows))
}

fn candidates_table(r: &[CandidateRow]) -> PolarsResult<DataFrame> {
    let f = |name: &str, value: &dyn Fn(&DefectRecord) -> f64| {
        Column::new(
            name.into(),
            r.iter().map(|r| value(r.defect)).collect::<Vec<f64>>(),
        )
    };
    let u = |name: &str, value: &dyn Fn(&DefectRecord) -> u32| {
        Column::new(
            name.into(),
            r.iter().map(|r| value(r.defect)).collect::<Vec<u32>>(),
        )
    };
    let columns = vec![
        Column::new("rank".into(), r.iter().map(|r| r.rank).collect::<Vec<_>>()),
        Column::new(
            "id".into(),
            r.iter().map(|r| r.defect.id.as_str()).collect::<Vec<_>>(),
        ),
        Column::new(
            "place".into(),
            r.iter()
                .map(|r| r.place.as_ref().map(Place::to_string))
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "element".into(),
            r.iter()
                .map(|r| r.place.as_ref().map(|p| p.element.as_str()))
                .collect::<Vec<_>>(),
        ),
        f("x", &|d| d.position[0]),
        f("y", &|d| d.position[1]),
        f("z", &|d| d.position[2]),
        f("confidence", &|d| d.confidence),
        Column::new(
            "review_priority".into(),
            r.iter().map(|r| r.review_priority).collect::<Vec<_>>(),
        ),
        Column::new(
            "length_m".into(),
            r.iter().map(|r| r.defect.length_m).collect::<Vec<_>>(),
        ),
        Column::new(
            "length_status".into(),
            r.iter()
                .map(|r| r.defect.evidence.length.as_str())
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "reshoot".into(),
            r.iter()
                .map(|r| r.defect.evidence.reshoot)
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "view_faults".into(),
            r.iter()
                .map(|r| ViewFault::list(&r.defect.evidence.view_faults))
                .collect::<Vec<_>>(),
        ),
        u("frames", &|d| d.frames),
        u("best_frame", &|d| d.best.frame),
        f("best_range_m", &|d| d.best.range_m),
        f("best_gsd_mm", &|d| d.best.oblique_gsd_mm),
        Column::new(
            "crop".into(),
            r.iter()
                .map(|r| r.defect.crop.as_deref())
                .collect::<Vec<_>>(),
        ),
    ];
    DataFrame::new(r.len(), columns)
}
