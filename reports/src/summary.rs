//! `summary.json`: the run in numbers, for batch jobs and dashboards.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::results::RunResults;

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

impl RunSummary {
    pub fn new(results: &RunResults, timings_s: BTreeMap<String, f64>) -> Self {
        let i = &results.flight.summary;
        let mut warnings: Vec<String> = Vec::new();
        let mut warn = |stage: &str, list: &[String]| {
            warnings.extend(list.iter().map(|w| format!("{stage}: {w}")));
        };
        warn("ingest", &i.warnings);
        if let Some(d) = &results.detect {
            warn("detect", &d.warnings);
        }
        if let Some(l) = &results.localise {
            warn("localise", &l.warnings);
        }
        if let Some(c) = &results.coverage {
            warn("coverage", &c.warnings);
        }
        if let Some(r) = &results.replan {
            warn("replan", &r.warnings);
        }
        Self {
            run: std::path::absolute(results.dir().path())
                .unwrap_or_else(|_| results.dir().path().to_owned()),
            flight: i.flight.path.clone(),
            flight_start: i.start_time.clone(),
            duration_s: i.duration_s,
            truncated: i.truncated,
            frames: i.frames,
            frames_with_pose: i.frames_with_pose,
            detections: results.detect.as_ref().map(|d| d.detections),
            defects: results.localise.as_ref().map(|l| l.defects),
            coverage: results.coverage.as_ref().map(|c| CoverageFigures {
                target_voxels: c.target_voxels,
                planned_voxels: c.planned_voxels,
                inspected_voxels: c.inspected_voxels,
                inspected_pct: c.inspected_pct,
                planned_inspected_pct: c.planned_inspected_pct,
                gap_voxels: c.gap_voxels,
                uninspectable_voxels: c.uninspectable_voxels,
                face_area_coverage_pct: c.face_area_coverage_pct,
            }),
            replan: results.replan.as_ref().map(|r| ReplanFigures {
                gap_voxels: r.gap_voxels,
                planned_gap_voxels: r.planned_gap_voxels,
                unplannable_gap_voxels: r.uninspectable_gaps.len(),
                waypoints: r.waypoints,
                sorties: r.sorties.len(),
                length_m: r.length_m,
                time_s: r.time_s,
            }),
            timings_s,
            versions: Versions {
                postflight: env!("CARGO_PKG_VERSION").to_string(),
                model: results.detect.as_ref().map(|d| d.model.clone()),
                model_sha256: results
                    .detect
                    .as_ref()
                    .map(|d| d.model_sha256.clone())
                    .filter(|h| !h.is_empty()),
                onnxruntime: results
                    .detect
                    .as_ref()
                    .map(|d| d.onnxruntime_version.clone())
                    .filter(|v| !v.is_empty()),
            },
            warnings,
        }
    }
}
