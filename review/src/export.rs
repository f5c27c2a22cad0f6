//! What the review produces for others: the decisions (CSV, and JSON with
//! their history) and the accepted defects as a report table (CSV and
//! Parquet), one row per crack an inspector confirmed.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use polars::prelude::*;
use postflight_core::outputs::localise::LengthStatus;
use postflight_core::outputs::{csv_text, parsed, required};
use postflight_core::{FaceSide, RunDir};
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

/// A crack an inspector accepted (as is, or as needing repair), with what
/// localisation measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AcceptedDefect {
    pub id: String,
    /// The structure element it is on (`pier 2`); `None` off the structure,
    /// or without targets.
    pub element: Option<String>,
    /// Where it is on the structure; `None` as the element.
    pub place: Option<String>,
    pub verdict: Verdict,
    /// 1 (minor) to 5 (urgent), see [`SEVERITY_SCALE`](crate::store::SEVERITY_SCALE).
    pub severity: Option<u8>,
    pub note: String,
    pub reviewer: String,
    pub decided_at: String,
    /// World frame, metres.
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub face: FaceSide,
    pub length_m: Option<f64>,
    /// Measured, a lower bound (`partial`), or why it is missing.
    #[serde(serialize_with = "length_status")]
    pub length_status: LengthStatus,
    pub confidence: f64,
    pub frames: u32,
    pub best_frame: u32,
    /// The best view's oblique GSD (`gsd_mm` in the files, as in
    /// `defects.json`).
    #[serde(rename = "gsd_mm")]
    pub oblique_gsd_mm: f64,
    pub range_m: f64,
}

/// A length status as its name (the CSV's and Parquet's text).
fn length_status<S: serde::Serializer>(s: &LengthStatus, to: S) -> Result<S::Ok, S::Error> {
    to.serialize_str(s.as_str())
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
            let c = e.defect;
            Some(AcceptedDefect {
                id: c.id.clone(),
                element: c.element.clone(),
                // Runs localised before localise named places: coverage's.
                place: c.place.clone().or_else(|| places.get(&c.id).cloned()),
                verdict: d.verdict,
                severity: d.severity,
                note: d.note.clone(),
                reviewer: d.reviewer.clone(),
                decided_at: d.decided_at.clone(),
                x: c.position[0],
                y: c.position[1],
                z: c.position[2],
                face: c.face,
                length_m: c.length_m,
                length_status: c.evidence.length,
                confidence: c.confidence,
                frames: c.frames,
                best_frame: c.best.frame,
                oblique_gsd_mm: c.best.oblique_gsd_mm,
                range_m: c.best.range_m,
            })
        })
        .collect()
}

fn accepted_table(rows: &[AcceptedDefect]) -> PolarsResult<DataFrame> {
    let text = |f: fn(&AcceptedDefect) -> &str| rows.iter().map(f).collect::<Vec<_>>();
    let float = |f: fn(&AcceptedDefect) -> f64| rows.iter().map(f).collect::<Vec<_>>();
    let columns = vec![
        Column::new("id".into(), text(|r| &r.id)),
        Column::new(
            "element".into(),
            rows.iter()
                .map(|r| r.element.as_deref())
                .collect::<Vec<_>>(),
        ),
        Column::new(
            "place".into(),
            rows.iter().map(|r| r.place.as_deref()).collect::<Vec<_>>(),
        ),
        Column::new("verdict".into(), text(|r| r.verdict.as_str())),
        Column::new(
            "severity".into(),
            rows.iter()
                .map(|r| r.severity.map(i32::from))
                .collect::<Vec<_>>(),
        ),
        severity_meanings(rows.iter().map(|r| r.severity)),
        Column::new("note".into(), text(|r| &r.note)),
        Column::new("reviewer".into(), text(|r| &r.reviewer)),
        Column::new("decided_at".into(), text(|r| &r.decided_at)),
        Column::new("x".into(), float(|r| r.x)),
        Column::new("y".into(), float(|r| r.y)),
        Column::new("z".into(), float(|r| r.z)),
        Column::new("face".into(), text(|r| r.face.name())),
        Column::new(
            "length_m".into(),
            rows.iter().map(|r| r.length_m).collect::<Vec<_>>(),
        ),
        Column::new("length_status".into(), text(|r| r.length_status.as_str())),
        Column::new("confidence".into(), float(|r| r.confidence)),
        Column::new(
            "frames".into(),
            rows.iter().map(|r| r.frames).collect::<Vec<_>>(),
        ),
        Column::new(
            "best_frame".into(),
            rows.iter().map(|r| r.best_frame).collect::<Vec<_>>(),
        ),
        Column::new("gsd_mm".into(), float(|r| r.oblique_gsd_mm)),
        Column::new("range_m".into(), float(|r| r.range_m)),
    ];
    DataFrame::new(rows.len(), columns)
}

/// Read an `accepted-defects.parquet` written into `dir`.
pub fn read_accepted(dir: &RunDir) -> Result<Vec<AcceptedDefect>, ReviewError> {
    Ok(dir.read_table(files::ACCEPTED_TABLE, accepted_from)?)
}

fn accepted_from(df: &DataFrame) -> PolarsResult<Vec<AcceptedDefect>> {
    let text = |name: &str| df.column(name).and_then(|c| c.str());
    let f64s = |name: &str| df.column(name).and_then(|c| c.f64());
    let u32s = |name: &str| df.column(name).and_then(|c| c.u32());
    let (id, verdict, note) = (text("id")?, text("verdict")?, text("note")?);
    let (element, place) = (text("element")?, text("place")?);
    let (reviewer, decided_at, face) = (text("reviewer")?, text("decided_at")?, text("face")?);
    let severity = df.column("severity")?.i32()?;
    let (x, y, z) = (f64s("x")?, f64s("y")?, f64s("z")?);
    let (length, confidence) = (f64s("length_m")?, f64s("confidence")?);
    let length_status = text("length_status")?;
    let (frames, best_frame) = (u32s("frames")?, u32s("best_frame")?);
    let (gsd, range) = (f64s("gsd_mm")?, f64s("range_m")?);
    (0..df.height())
        .map(|i| {
            Ok(AcceptedDefect {
                id: required(id, i)?.to_string(),
                element: element.get(i).map(str::to_string),
                place: place.get(i).map(str::to_string),
                verdict: parsed(verdict, i, Verdict::parse)?,
                severity: severity.get(i).map(|v| v as u8),
                note: required(note, i)?.to_string(),
                reviewer: required(reviewer, i)?.to_string(),
                decided_at: required(decided_at, i)?.to_string(),
                x: required(x, i)?,
                y: required(y, i)?,
                z: required(z, i)?,
                face: parsed(face, i, FaceSide::parse)?,
                length_m: length.get(i),
                length_status: parsed(length_status, i, LengthStatus::parse)?,
                confidence: required(confidence, i)?,
                frames: required(frames, i)?,
                best_frame: required(best_frame, i)?,
                oblique_gsd_mm: required(gsd, i)?,
                range_m: required(range, i)?,
            })
        })
        .collect()
}

/// The current decisions as a table, one row per candidate.
fn decisions_table(decisions: &[Decision]) -> PolarsResult<DataFrame> {
    let text = |f: fn(&Decision) -> &str| decisions.iter().map(f).collect::<Vec<_>>();
    let columns = vec![
        Column::new("candidate".into(), text(|d| &d.candidate)),
        Column::new("verdict".into(), text(|d| d.verdict.as_str())),
        Column::new(
            "severity".into(),
            decisions
                .iter()
                .map(|d| d.severity.map(i32::from))
                .collect::<Vec<_>>(),
        ),
        severity_meanings(decisions.iter().map(|d| d.severity)),
        Column::new("note".into(), text(|d| &d.note)),
        Column::new("reviewer".into(), text(|d| &d.reviewer)),
        Column::new("decided_at".into(), text(|d| &d.decided_at)),
        Column::new(
            "version".into(),
            decisions.iter().map(|d| d.version).collect::<Vec<_>>(),
        ),
    ];
    DataFrame::new(decisions.len(), columns)
}

/// What each severity means (the scale written beside the number, so a
/// spreadsheet needs no key).
fn severity_meanings(severities: impl Iterator<Item = Option<u8>>) -> Column {
    Column::new(
        "severity_meaning".into(),
        severities
            .map(|s| s.and_then(severity_meaning))
            .collect::<Vec<_>>(),
    )
}

/// A table as CSV: a header line, RFC 4180 quoting, missing values empty.
fn csv(table: DataFrame) -> Result<String, ReviewError> {
    Ok(csv_text(table)?)
}

/// The current decisions as CSV.
pub fn decisions_csv(decisions: &[Decision]) -> Result<String, ReviewError> {
    csv(decisions_table(decisions)?)
}

/// The accepted defects as CSV.
pub fn accepted_csv(rows: &[AcceptedDefect]) -> Result<String, ReviewError> {
    csv(accepted_table(rows)?)
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
    dir.write_table(files::ACCEPTED_TABLE, accepted_table(&accepted))?;
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
    use super::*;

    #[test]
    fn the_csv_export_quotes_what_needs_quoting() {
        let decision = Decision {
            candidate: "a".into(),
            version: 1,
            verdict: Verdict::NeedsRepair,
            severity: Some(3),
            note: "crack, \"wide\"\nat joint".into(),
            reviewer: "ann".into(),
            decided_at: "2026-11-23T00:00:00Z".into(),
        };
        let csv = decisions_csv(&[decision]).unwrap();
        assert!(
            csv.starts_with(
                "candidate,verdict,severity,severity_meaning,note,reviewer,decided_at,version\n"
            ),
            "{csv}"
        );
        let row = csv.lines().nth(1).unwrap();
        assert!(
            row.starts_with("a,needs_repair,3,significant: plan a repair,\"crack, \"\"wide\"\""),
            "{csv}"
        );
    }

    #[test]
    fn the_accepted_defects_table_reads_back_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path()).unwrap();
        let row = |id: &str, verdict, severity, length_m| AcceptedDefect {
            id: id.into(),
            element: Some("pier 2".into()),
            place: Some("pier 2, east face, 1.4 m above its base".into()),
            verdict,
            severity,
            note: "at the joint, \"wide\"".into(),
            reviewer: "ann".into(),
            decided_at: "2026-11-23T10:00:00.000000000Z".into(),
            x: 1.5,
            y: -2.25,
            z: 3.0,
            face: FaceSide::PosZ,
            length_m,
            length_status: if length_m.is_some() {
                LengthStatus::Measured
            } else {
                LengthStatus::TooOblique
            },
            confidence: 0.9,
            frames: 4,
            best_frame: 17,
            oblique_gsd_mm: 3.2,
            range_m: 3.9,
        };
        let rows = vec![
            row("1_2_3+z", Verdict::Accepted, None, Some(0.8)),
            row("4_5_6+z", Verdict::NeedsRepair, Some(4), None),
        ];
        run.write_table(files::ACCEPTED_TABLE, accepted_table(&rows))
            .unwrap();
        assert_eq!(read_accepted(&run).unwrap(), rows);
    }
}
