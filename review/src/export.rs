//! What the review produces for others: the decisions (CSV, and JSON with
//! their history) and the accepted defects as a report table (CSV and
//! Parquet), one row per crack an inspector confirmed.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use postflight_core::RunDir;
use postflight_core::condition::ConditionState;
use postflight_core::outputs::csv_text;
use postflight_core::outputs::localise::DefectRecord;
use postflight_core::table::Row;
use serde::Serialize;

use crate::queue::Queue;
use crate::store::{Decision, ReviewError, ReviewStore, SEVERITY_SCALE, Verdict, severity_meaning};
use reports::results::RunResults;

/// Files `postflight review export` writes.
pub mod files {
    pub const DECISIONS_CSV: &str = "review-decisions.csv";
    pub const DECISIONS_JSON: &str = "review-decisions.json";
    pub const ACCEPTED_CSV: &str = "accepted-defects.csv";
    pub const ACCEPTED_TABLE: &str = "accepted-defects.parquet";
}

postflight_core::table! {
    /// What an inspector decided on a candidate, as the exports write it.
    pub struct DecisionCells {
        verdict: Verdict,
        /// 1 (minor) to 5 (urgent), see [`SEVERITY_SCALE`](crate::store::SEVERITY_SCALE).
        severity: Option<u8>,
        /// What the severity means (the scale written beside the number, so
        /// a spreadsheet needs no key).
        severity_meaning: Option<String>,
        /// The condition state the reviewer put the crack in, over the
        /// measured `condition_state`; null where the measured one stands.
        inspector_condition_state: Option<ConditionState>,
        /// The inspector marked the crack sealed.
        sealed: bool,
        note: String,
        reviewer: String,
        decided_at: String,
    }
}

impl DecisionCells {
    fn of(d: &Decision) -> Self {
        Self {
            verdict: d.verdict,
            severity: d.severity,
            severity_meaning: d.severity.and_then(severity_meaning).map(str::to_string),
            inspector_condition_state: d.condition,
            sealed: d.sealed,
            note: d.note.clone(),
            reviewer: d.reviewer.clone(),
            decided_at: d.decided_at.clone(),
        }
    }
}

postflight_core::table! {
    /// One row of `review-decisions.csv`: a candidate's current decision.
    pub struct DecisionRow {
        candidate: String,
        decision: DecisionCells,
        /// 1 for the first decision on the candidate, then 2, ...
        version: i64,
    }
}

postflight_core::table! {
    /// One row of `accepted-defects`: a crack an inspector accepted (as is,
    /// or as needing repair), the decision then the candidate as
    /// `defects.parquet` holds it.
    pub struct AcceptedDefect {
        decision: DecisionCells,
        defect: DefectRecord,
    }
}

/// The accepted defects, in review order, with their places by id.
pub fn accepted_defects(queue: &Queue, places: &HashMap<String, String>) -> Vec<AcceptedDefect> {
    queue
        .entries
        .iter()
        .filter_map(|e| {
            let d = e.decision.as_ref()?;
            if d.verdict == Verdict::Rejected {
                return None;
            }
            let mut defect = e.defect.clone();
            // Runs localised before localise named places: coverage's.
            defect.place = defect.place.or_else(|| places.get(&defect.id).cloned());
            Some(AcceptedDefect {
                decision: DecisionCells::of(d),
                defect,
            })
        })
        .collect()
}

/// Read an `accepted-defects.parquet` written into `dir`.
pub fn read_accepted(dir: &RunDir) -> Result<Vec<AcceptedDefect>, ReviewError> {
    Ok(dir.read_rows(files::ACCEPTED_TABLE)?)
}

/// A table as CSV: a header line, RFC 4180 quoting, missing values empty.
fn csv<R: Row>(rows: &[R]) -> Result<String, ReviewError> {
    Ok(csv_text(R::frame(rows)?)?)
}

/// The current decisions as CSV.
pub fn decisions_csv(decisions: &[Decision]) -> Result<String, ReviewError> {
    let rows: Vec<DecisionRow> = decisions
        .iter()
        .map(|d| DecisionRow {
            candidate: d.candidate.clone(),
            decision: DecisionCells::of(d),
            version: d.version,
        })
        .collect();
    csv(&rows)
}

/// The accepted defects as CSV.
pub fn accepted_csv(rows: &[AcceptedDefect]) -> Result<String, ReviewError> {
    csv(rows)
}

/// The decisions as JSON: the current one per candidate, and every decision
/// ever made in the order made (the audit trail).
#[derive(Debug, Serialize)]
pub struct DecisionsExport {
    /// What severities 1 (minor) to 5 (urgent) mean.
    pub severity_scale: Vec<SeverityLevel>,
    pub current: Vec<Decision>,
    pub history: Vec<Decision>,
}

/// One step of the severity scale, as exported.
#[derive(Debug, Serialize)]
pub struct SeverityLevel {
    pub severity: u8,
    pub meaning: &'static str,
}

impl DecisionsExport {
    pub fn read(store: &ReviewStore) -> Result<Self, ReviewError> {
        Ok(Self {
            severity_scale: SEVERITY_SCALE
                .iter()
                .map(|&(severity, meaning)| SeverityLevel { severity, meaning })
                .collect(),
            current: store.current_decisions()?,
            history: store.all_decisions()?,
        })
    }
}

/// Write every export into `dir`; returns the file names written.
pub fn write_all(
    dir: &RunDir,
    store: &ReviewStore,
    queue: &Queue,
    places: &HashMap<String, String>,
) -> Result<[&'static str; 4], ReviewError> {
    let decisions = DecisionsExport::read(store)?;
    dir.write_text(files::DECISIONS_CSV, &decisions_csv(&decisions.current)?)?;
    dir.write_json(files::DECISIONS_JSON, &decisions)?;
    let accepted = accepted_defects(queue, places);
    dir.write_text(files::ACCEPTED_CSV, &accepted_csv(&accepted)?)?;
    dir.write_rows(files::ACCEPTED_TABLE, &accepted)?;
    Ok([
        files::DECISIONS_CSV,
        files::DECISIONS_JSON,
        files::ACCEPTED_CSV,
        files::ACCEPTED_TABLE,
    ])
}

/// `postflight review export`: write every export of the review of `run`
/// (decisions in `db`) into `out`; returns the paths written.
pub fn export_run(run: &Path, db: &Path, out: &Path) -> Result<Vec<PathBuf>, ReviewError> {
    let results = RunResults::read(run)?;
    if results.localise.is_none() {
        return Err(ReviewError::NotLocalised(run.to_owned()));
    }
    if !db.is_file() {
        return Err(ReviewError::NoDatabase {
            db: db.to_owned(),
            run: run.to_owned(),
        });
    }
    let store = ReviewStore::open(db)?;
    let queue = Queue::new(&results.defects_for_review(), store.current_decisions()?);
    let dir = RunDir::create(out)?;
    let written = write_all(&dir, &store, &queue, &results.places())?;
    Ok(written.iter().map(|name| dir.file(name)).collect())
}

#[cfg(test)]
mod tests {
    use postflight_core::FaceSide;
    use postflight_core::condition::StateCall;
    use postflight_core::outputs::localise::{Evidence, LengthStatus, ViewRecord, WidthRecord};
    use postflight_core::trace::Trace;
    use postflight_core::view::Miss;

    use super::*;

    #[test]
    fn the_csv_export_quotes_what_needs_quoting() {
        let decision = Decision {
            candidate: "a".into(),
            version: 1,
            verdict: Verdict::NeedsRepair,
            severity: Some(3),
            condition: Some(ConditionState::Severe),
            sealed: false,
            note: "crack, \"wide\"\nat joint".into(),
            reviewer: "ann".into(),
            decided_at: "2026-11-23T00:00:00Z".into(),
        };
        let csv = decisions_csv(&[decision]).unwrap();
        assert!(
            csv.starts_with(
                "candidate,verdict,severity,severity_meaning,inspector_condition_state,sealed,note,reviewer,decided_at,version\n"
            ),
            "{csv}"
        );
        let row = csv.lines().nth(1).unwrap();
        assert!(
            row.starts_with(
                "a,needs_repair,3,significant: plan a repair,severe,false,\"crack, \"\"wide\"\""
            ),
            "{csv}"
        );
    }

    #[test]
    fn the_accepted_defects_table_reads_back_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path()).unwrap();
        let row = |id: &str, verdict, severity: Option<u8>, length_m| AcceptedDefect {
            decision: DecisionCells {
                verdict,
                severity,
                severity_meaning: severity.and_then(severity_meaning).map(str::to_string),
                inspector_condition_state: severity.map(|_| ConditionState::Severe),
                sealed: false,
                note: "at the joint, \"wide\"".into(),
                reviewer: "ann".into(),
                decided_at: "2026-11-23T10:00:00.000000000Z".into(),
            },
            defect: DefectRecord {
                id: id.into(),
                element: Some("pier 2".into()),
                place: Some("pier 2, east face, 1.4 m above its base".into()),
                position: [1.5, -2.25, 3.0],
                position_uncertainty_m: Some(0.04),
                normal: [0.0, 0.0, 1.0],
                extent_min: [1.4, -2.5, 3.0],
                extent_max: [1.6, -2.0, 3.0],
                voxel: [7, -12, 15],
                face: FaceSide::PosZ,
                length_m,
                length_views: u32::from(length_m.is_some()),
                trace: Trace(
                    length_m
                        .map(|_| vec![vec![[1.4, -2.5, 3.0], [1.6, -2.0, 3.0]]])
                        .unwrap_or_default(),
                ),
                frames: 4,
                confidence: 0.9,
                max_score: 0.7,
                evidence: Evidence {
                    view_faults: vec![Miss::TooFar],
                    view_gsd_mm: 2.9,
                    blur_px: None,
                    length: if length_m.is_some() {
                        LengthStatus::Measured
                    } else {
                        LengthStatus::TooOblique
                    },
                    min_measurable_width_mm: 6.4,
                    reshoot: length_m.is_none(),
                },
                // The columns hold the best view's frame, geometry and box.
                best: ViewRecord {
                    frame: 17,
                    range_m: 3.9,
                    incidence_deg: 21.0,
                    oblique_gsd_mm: 3.2,
                    bbox: [10.0, 20.0, 110.5, 60.0],
                    time_ns: 0,
                    score: 0.0,
                    length_m: None,
                    clipped: false,
                },
                width: length_m.map(|_| WidthRecord {
                    max_mm: Some(1.2),
                    median_mm: Some(0.7),
                    uncertainty_mm: Some(0.2),
                    narrower_than_mm: None,
                    mm_per_px: 0.9,
                    ..WidthRecord::default()
                }),
                condition: length_m.map(|_| StateCall {
                    state: ConditionState::Fair,
                    probability: 1.0,
                    other: None,
                    other_probability: None,
                }),
                crop: Some(format!("defects/{id}.jpg")),
                views: Vec::new(),
            },
        };
        let rows = vec![
            row("1_2_3+z", Verdict::Accepted, None, Some(0.8)),
            row("4_5_6+z", Verdict::NeedsRepair, Some(4), None),
        ];
        run.write_rows(files::ACCEPTED_TABLE, &rows).unwrap();
        assert_eq!(read_accepted(&run).unwrap(), rows);
    }
}
