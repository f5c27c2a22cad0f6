//! `summary.json` from a run's results (its layout is in
//! `postflight_core::outputs::report`).

use std::collections::BTreeMap;

use postflight_core::outputs::report::{CoverageFigures, ReplanFigures, RunSummary, Versions};

use crate::results::RunResults;

/// The summary of a run's results, with the seconds each stage took.
pub fn run_summary(results: &RunResults, timings_s: BTreeMap<String, f64>) -> RunSummary {
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
    RunSummary {
        run: std::path::absolute(results.dir().path())
            .unwrap_or_else(|_| results.dir().path().to_owned()),
        recordings: i.recordings.iter().map(|r| r.path.clone()).collect(),
        flight_start: i.start_time.clone(),
        duration_s: i.duration_s,
        truncated: i.truncated(),
        frames: i.frames,
        frames_with_pose: i.frames_with_pose,
        detections: results.detect.as_ref().map(|d| d.detections),
        defects: results.localise.as_ref().map(|l| l.defects),
        coverage: results.coverage.as_ref().map(|c| CoverageFigures {
            target_voxels: c.figures.target_voxels,
            planned_voxels: c.figures.planned_voxels,
            inspected_voxels: c.figures.inspected_voxels,
            inspected_pct: c.figures.inspected_pct,
            planned_inspected_pct: c.figures.planned_inspected_pct,
            gap_voxels: c.figures.gap_voxels,
            uninspectable_voxels: c.figures.uninspectable_voxels,
            face_area_coverage_pct: c.figures.face_area_coverage_pct,
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
