//! What the report stage writes: `report.html` (the page people read),
//! `candidates.csv` (its candidate table, for spreadsheets), `flight.rrd`
//! (the Rerun recording) and, last, its summary `summary.json`: the run in
//! numbers, for batch jobs and dashboards.

use std::collections::BTreeMap;
use std::path::PathBuf;

use polars::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::run_dir::RunDir;

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
pub struct CandidateRow {
    /// Place in the review order, from 1.
    pub rank: u32,
    pub id: String,
    /// Where it is on the structure (`pier 2, east face, 1.4 m above its
    /// base`); `None` before coverage has found the structure's elements.
    pub place: Option<String>,
    pub element: Option<String>,
    /// World frame, metres.
    pub position: [f64; 3],
    pub confidence: f64,
    pub review_priority: f64,
    pub length_m: Option<f64>,
    /// `measured`, `partial`, ... (see `LengthStatus`).
    pub length_status: String,
    pub reshoot: bool,
    /// The best view's broken View rules, `;`-separated.
    pub view_faults: String,
    pub frames: u32,
    pub best_frame: u32,
    pub best_range_m: f64,
    pub best_gsd_mm: f64,
    /// JPEG of the best view, relative to the run directory.
    pub crop: Option<String>,
}

/// Write `candidates.csv`.
pub fn write_candidates(run: &RunDir, rows: &[CandidateRow]) -> Result<(), Error> {
    let mut table = candidates_table(rows).map_err(|cause| Error::Table {
        path: run.file(files::CANDIDATES),
        cause,
    })?;
    let mut out = Vec::new();
    CsvWriter::new(&mut out)
        .finish(&mut table)
        .map_err(|cause| Error::Table {
            path: run.file(files::CANDIDATES),
            cause,
        })?;
    run.write_text(
        files::CANDIDATES,
        &String::from_utf8(out).expect("polars writes UTF-8 CSV"),
    )
}

fn candidates_table(r: &[CandidateRow]) -> PolarsResult<DataFrame> {
    let col = |name: &str, a: usize| {
        Column::new(
            name.into(),
            r.iter().map(|r| r.position[a]).collect::<Vec<f64>>(),
        )
    };
    let columns = vec![
        Column::new("rank".into(), r.iter().map(|r| r.rank).collect::<Vec<_>>()),
        Column::new(
            "id".into(),
            r.iter().map(|r| r.id.as_str()).collect::<Vec<_>>(),
        ),
        Column::new(
            "place".into(),
            r.iter().map(|r| r.place.as_deref()).collect::<Vec<_>>(),
        ),
        Column::new(
            "element".into(),
            r.iter().map(|r| r.element.as_deref()).collect::<Vec<_>>(),
        ),
        col("x", 0),
        col("y", 1),
        col("z", 2),
        Column::new(
            "confidence".into(),
            r.iter().map(|r| r.confidence).collect::<Vec<_>>(),
        ),
        Column::new(
            "review_priority".into(),
            r.iter().map(|r| r.review_priority).collect::<Vec<_>>(),
        ),
        Column::new(
            "length_m".into(),
            r.iter().map(|r| r.length_m).collect::<Vec<_>>(),
        ),
        Column::new(
            "length_status".into(),
            r.iter()
                .map(|r| r.length_status.as_str())
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "reshoot".into(),
            r.iter().map(|r| r.reshoot).collect::<Vec<_>>(),
        ),
        Column::new(
            "view_faults".into(),
            r.iter().map(|r| r.view_faults.as_str()).collect::<Vec<_>>(),
        ),
        Column::new(
            "frames".into(),
            r.iter().map(|r| r.frames).collect::<Vec<_>>(),
        ),
        Column::new(
            "best_frame".into(),
            r.iter().map(|r| r.best_frame).collect::<Vec<_>>(),
        ),
        Column::new(
            "best_range_m".into(),
            r.iter().map(|r| r.best_range_m).collect::<Vec<_>>(),
        ),
        Column::new(
            "best_gsd_mm".into(),
            r.iter().map(|r| r.best_gsd_mm).collect::<Vec<_>>(),
        ),
        Column::new(
            "crop".into(),
            r.iter().map(|r| r.crop.as_deref()).collect::<Vec<_>>(),
        ),
    ];
    DataFrame::new(r.len(), columns)
}
