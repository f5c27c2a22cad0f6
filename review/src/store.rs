//! Review decisions in SQLite. Candidates are keyed by their stable ids
//! (surface voxel and face), so a decision stays with its crack when
//! localisation is re-run on the same flight. Every decision is a new row
//! (nothing is overwritten): the latest is the current one, the rest are its
//! history. A decision names the version it was made on; if someone decided
//! in between, it is refused as a conflict instead of silently replacing
//! theirs.

use std::path::Path;

use rusqlite::{Connection, OptionalExtension, TransactionBehavior, params};
use serde::{Deserialize, Serialize};

use postflight_core::condition::ConditionState;
use postflight_core::outputs::localise::DefectRecord;
use postflight_core::table::Named;

postflight_core::kind! {
    /// What a reviewer decided about a candidate.
    pub enum Verdict("verdict") {
        /// A crack.
        Accepted = "accepted",
        /// Not a crack (a false detection).
        Rejected = "rejected",
        /// A crack that needs repair, with a severity from 1 to 5.
        NeedsRepair = "needs_repair",
    }
}

impl Verdict {
    /// As people read it: "needs repair".
    pub fn words(self) -> &'static str {
        match self {
            Self::NeedsRepair => "needs repair",
            other => other.as_str(),
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        <Self as Named>::named(s)
    }
}

/// The severity scale of a crack that needs repair: 1 is the least urgent,
/// 5 the most. Shown on the pages and written into the exports.
pub const SEVERITY_SCALE: [(u8, &str); 5] = [
    (
        1,
        "minor: record it, recheck at the next routine inspection",
    ),
    (2, "moderate: monitor it, recheck sooner"),
    (3, "significant: plan a repair"),
    (4, "serious: repair soon"),
    (5, "urgent: act now, restrict use until repaired"),
];

/// What a severity means, from [`SEVERITY_SCALE`].
pub fn severity_meaning(severity: u8) -> Option<&'static str> {
    SEVERITY_SCALE
        .iter()
        .find(|(s, _)| *s == severity)
        .map(|(_, m)| *m)
}

/// What a reviewer rules on a candidate, before it is recorded.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ruling<'a> {
    pub verdict: Verdict,
    /// 1 to 5, for a crack that needs repair.
    pub severity: Option<u8>,
    /// The condition state the reviewer puts the crack in, over the one its
    /// width gave; `None` leaves that one. A rejected candidate is no crack
    /// and is recorded without one.
    pub condition: Option<ConditionState>,
    /// The crack has been sealed (the element record counts a sealed
    /// moderate crack in state 1). A rejected candidate is recorded
    /// without it.
    pub sealed: bool,
    pub note: &'a str,
    pub reviewer: &'a str,
}

impl<'a> Ruling<'a> {
    /// `verdict` by `reviewer`, with no severity, state or note.
    pub fn new(verdict: Verdict, reviewer: &'a str) -> Self {
        Self {
            verdict,
            severity: None,
            condition: None,
            sealed: false,
            note: "",
            reviewer,
        }
    }
}

/// One decision, as recorded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Decision {
    pub candidate: String,
    /// 1 for the first decision on a candidate, then 2, ...
    pub version: i64,
    pub verdict: Verdict,
    pub severity: Option<u8>,
    /// See [`Ruling::condition`].
    #[serde(default)]
    pub condition: Option<ConditionState>,
    /// See [`Ruling::sealed`].
    #[serde(default)]
    pub sealed: bool,
    pub note: String,
    pub reviewer: String,
    /// RFC 3339, UTC.
    pub decided_at: String,
}

impl Decision {
    /// The decision as the element record weighs it.
    pub fn reviewer_call(&self) -> record::ReviewerCall {
        record::ReviewerCall {
            rejected: self.verdict == Verdict::Rejected,
            condition: self.condition,
            sealed: self.sealed,
        }
    }
}

/// The current decisions in the review database at `db`, as the element
/// record weighs them; none where there is no database yet (nothing is
/// created).
pub fn record_decisions(db: &Path) -> Result<record::Decisions, ReviewError> {
    if !db.is_file() {
        return Ok(record::Decisions::new());
    }
    let store = ReviewStore::open(db)?;
    Ok(store
        .current_decisions()?
        .iter()
        .map(|d| (d.candidate.clone(), d.reviewer_call()))
        .collect())
}

/// Why a decision as submitted cannot be recorded (the reviewer can fix it
/// and submit again).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InvalidDecision {
    #[error("version {0:?} is not a number; reload the page")]
    Version(String),
    #[error("unknown decision {0:?}; use accepted, rejected or needs_repair")]
    Verdict(String),
    #[error("severity {0:?} is not a number from 1 to 5")]
    SeverityNotANumber(String),
    #[error("unknown condition state {0:?}; use good, fair, poor or severe")]
    Condition(String),
    #[error("needs repair takes a severity from 1 to 5")]
    SeverityMissing,
    #[error("only a needs-repair decision has a severity")]
    SeverityWithoutRepair,
    #[error("say who you are: a decision needs a reviewer name")]
    NoReviewer,
    #[error("a reviewer name has at most {MAX_REVIEWER_CHARS} characters")]
    ReviewerTooLong,
    #[error(
        "a reviewer name cannot hold control or invisible formatting characters ({0}); type the name as plain text"
    )]
    ReviewerInvisible(String),
    #[error(
        "a note cannot hold control characters ({0}) other than tabs and line breaks; type it as plain text"
    )]
    NoteControl(String),
    #[error(
        "a note has at most {MAX_NOTE_CHARS} characters; put longer text in the inspection report"
    )]
    NoteTooLong,
}

#[derive(Debug, thiserror::Error)]
pub enum ReviewError {
    #[error("review database: {0}")]
    Database(#[from] rusqlite::Error),
    #[error("cannot open the review database {}: {cause}; check the --db path", path.display())]
    Open {
        path: std::path::PathBuf,
        cause: rusqlite::Error,
    },
    #[error("no defect candidate {0:?} in this review; reload the queue")]
    UnknownCandidate(String),
    #[error(
        "candidate {candidate} was decided by someone else since you loaded it (now version {current}); reload it and decide again"
    )]
    Conflict { candidate: String, current: i64 },
    #[error(transparent)]
    Decision(#[from] InvalidDecision),
    #[error(
        "an access token needs at least 16 characters of letters, digits, '-' or '_'; or leave --token out to have one generated"
    )]
    WeakToken,
    #[error(
        "no review database at {}: review the run first with `postflight review serve --run {}`, or name the database with --db",
        db.display(),
        run.display()
    )]
    NoDatabase {
        db: std::path::PathBuf,
        run: std::path::PathBuf,
    },
    #[error(transparent)]
    Files(#[from] postflight_core::Error),
    #[error(transparent)]
    Run(#[from] reports::ReportError),
    #[error(transparent)]
    Flight(#[from] ingest::IngestError),
    #[error("cannot build the export table: {0}")]
    Table(#[from] polars::prelude::PolarsError),
    #[error(
        "this run has no defect candidates to review yet: run `postflight localise --run {0}` (or `postflight run`) first"
    )]
    NotLocalised(std::path::PathBuf),
    #[error(
        "cannot listen on {addr}: {cause}; choose another address with --addr (port 0 picks a free port)"
    )]
    Bind {
        addr: std::net::SocketAddr,
        cause: std::io::Error,
    },
    #[error("review server: {0}")]
    Server(std::io::Error),
}

const SCHEMA: &str = "
CREATE TABLE IF NOT EXISTS candidates (
    id TEXT PRIMARY KEY,
    priority REAL NOT NULL,
    confidence REAL NOT NULL,
    length_m REAL,
    -- 0 when the latest localisation no longer has it (its decisions stay).
    present INTEGER NOT NULL DEFAULT 1,
    version INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS decisions (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    candidate TEXT NOT NULL REFERENCES candidates(id),
    version INTEGER NOT NULL,
    verdict TEXT NOT NULL CHECK (verdict IN ('accepted', 'rejected', 'needs_repair')),
    severity INTEGER CHECK (severity BETWEEN 1 AND 5),
    note TEXT NOT NULL,
    reviewer TEXT NOT NULL,
    decided_at TEXT NOT NULL,
    UNIQUE (candidate, version)
);
";

/// Columns added since the first schema, each with the statement that adds
/// it: a database made before them (or new) gains them when opened; older
/// decisions hold null there.
fn added_columns() -> [(&'static str, String); 2] {
    let states: Vec<String> = ConditionState::ALL
        .iter()
        .map(|s| format!("'{}'", s.name()))
        .collect();
    [
        (
            "condition_state",
            format!(
                "ALTER TABLE decisions ADD COLUMN condition_state TEXT CHECK (condition_state IN ({}))",
                states.join(", ")
            ),
        ),
        (
            "sealed",
            "ALTER TABLE decisions ADD COLUMN sealed INTEGER NOT NULL DEFAULT 0 CHECK (sealed IN (0, 1))"
                .to_string(),
        ),
    ]
}

/// The decisions' columns, in [`decision_row`]'s order.
const DECISION_COLUMNS: &str =
    "candidate, version, verdict, severity, note, reviewer, decided_at, condition_state, sealed";

/// The review database's file name in a run directory, by default.
pub const DEFAULT_DB: &str = "review.sqlite";

/// Longest reviewer name accepted.
pub const MAX_REVIEWER_CHARS: usize = 80;
/// Longest note accepted.
pub const MAX_NOTE_CHARS: usize = 4000;

/// The review database of a run.
pub struct ReviewStore {
    conn: Connection,
}

impl ReviewStore {
    /// Open (or create) the database at `path`: WAL, and every commit synced
    /// to disk before it returns, so an acknowledged decision survives a
    /// killed server.
    pub fn open(path: &Path) -> Result<Self, ReviewError> {
        let setup = || -> rusqlite::Result<Connection> {
            let conn = Connection::open(path)?;
            conn.pragma_update(None, "journal_mode", "WAL")?;
            conn.pragma_update(None, "synchronous", "FULL")?;
            conn.pragma_update(None, "foreign_keys", "ON")?;
            conn.busy_timeout(std::time::Duration::from_secs(5))?;
            conn.execute_batch(SCHEMA)?;
            add_columns(&conn)?;
            Ok(conn)
        };
        let conn = setup().map_err(|cause| ReviewError::Open {
            path: path.to_owned(),
            cause,
        })?;
        Ok(Self { conn })
    }

    /// Bring the candidates up to date with localisation's: new ones are
    /// added, known ones keep their decisions (their priority is refreshed),
    /// and ones no longer found are kept, marked absent. Returns how many
    /// are new.
    pub fn sync_candidates(&mut self, defects: &[DefectRecord]) -> Result<usize, ReviewError> {
        let tx = self.conn.transaction()?;
        tx.execute("UPDATE candidates SET present = 0", [])?;
        let mut added = 0;
        for d in defects {
            let priority = reports::results::review_priority(d);
            let changed = tx.execute(
                "UPDATE candidates SET present = 1, priority = ?2, confidence = ?3, length_m = ?4 WHERE id = ?1",
                params![d.id, priority, d.confidence, d.length_m],
            )?;
            if changed == 0 {
                tx.execute(
                    "INSERT INTO candidates (id, priority, confidence, length_m) VALUES (?1, ?2, ?3, ?4)",
                    params![d.id, priority, d.confidence, d.length_m],
                )?;
                added += 1;
            }
        }
        tx.commit()?;
        Ok(added)
    }

    /// Record `ruling` on `candidate`, made on `seen_version` (the version
    /// the reviewer was shown; 0 before any decision). One transaction.
    pub fn decide(
        &mut self,
        candidate: &str,
        seen_version: i64,
        ruling: &Ruling,
    ) -> Result<Decision, ReviewError> {
        check_decision(ruling)?;
        let reviewer = ruling.reviewer.trim();
        let tx = self
            .conn
            .transaction_with_behavior(TransactionBehavior::Immediate)?;
        let current: Option<i64> = tx
            .query_row(
                "SELECT version FROM candidates WHERE id = ?1",
                [candidate],
                |r| r.get(0),
            )
            .optional()?;
        let current = current.ok_or_else(|| ReviewError::UnknownCandidate(candidate.into()))?;
        if current != seen_version {
            return Err(ReviewError::Conflict {
                candidate: candidate.into(),
                current,
            });
        }
        let decision = Decision {
            candidate: candidate.into(),
            version: current + 1,
            verdict: ruling.verdict,
            severity: ruling.severity,
            condition: ruling
                .condition
                .filter(|_| ruling.verdict != Verdict::Rejected),
            sealed: ruling.sealed && ruling.verdict != Verdict::Rejected,
            note: ruling.note.into(),
            reviewer: reviewer.into(),
            decided_at: postflight_core::time::now_rfc3339(),
        };
        tx.execute(
            &format!(
                "INSERT INTO decisions ({DECISION_COLUMNS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)"
            ),
            params![
                decision.candidate,
                decision.version,
                decision.verdict.as_str(),
                decision.severity,
                decision.note,
                decision.reviewer,
                decision.decided_at,
                decision.condition.map(ConditionState::name),
                decision.sealed,
            ],
        )?;
        tx.execute(
            "UPDATE candidates SET version = ?2 WHERE id = ?1",
            params![candidate, decision.version],
        )?;
        tx.commit()?;
        Ok(decision)
    }

    /// Every decision on `candidate`, oldest first (the last is current).
    pub fn history(&self, candidate: &str) -> Result<Vec<Decision>, ReviewError> {
        let mut q = self.conn.prepare(&format!(
            "SELECT {DECISION_COLUMNS} FROM decisions WHERE candidate = ?1 ORDER BY version"
        ))?;
        let rows = q.query_map([candidate], decision_row)?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// The current decision of every decided candidate, by candidate id.
    pub fn current_decisions(&self) -> Result<Vec<Decision>, ReviewError> {
        let mut q = self.conn.prepare(&format!(
            "SELECT {DECISION_COLUMNS} FROM decisions
             WHERE (candidate, version) IN (SELECT id, version FROM candidates)
             ORDER BY candidate"
        ))?;
        let rows = q.query_map([], decision_row)?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Every decision ever made, in the order they were made.
    pub fn all_decisions(&self) -> Result<Vec<Decision>, ReviewError> {
        let mut q = self.conn.prepare(&format!(
            "SELECT {DECISION_COLUMNS} FROM decisions ORDER BY seq"
        ))?;
        let rows = q.query_map([], decision_row)?;
        Ok(rows.collect::<Result<_, _>>()?)
    }
}

/// Add the [`added_columns`] a database lacks.
fn add_columns(conn: &Connection) -> rusqlite::Result<()> {
    let mut q = conn.prepare("SELECT name FROM pragma_table_info('decisions')")?;
    let have: Vec<String> = q.query_map([], |r| r.get(0))?.collect::<Result<_, _>>()?;
    for (column, add) in added_columns() {
        if !have.iter().any(|c| c == column) {
            conn.execute_batch(&add)?;
        }
    }
    Ok(())
}

fn decision_row(r: &rusqlite::Row) -> rusqlite::Result<Decision> {
    // A name the database holds that is not one of the kind's.
    let named = |i: usize, what: &str, text: &str| {
        rusqlite::Error::FromSqlConversionFailure(
            i,
            rusqlite::types::Type::Text,
            format!("unknown {what} {text:?}").into(),
        )
    };
    let verdict: String = r.get(2)?;
    let condition: Option<String> = r.get(7)?;
    Ok(Decision {
        candidate: r.get(0)?,
        version: r.get(1)?,
        verdict: Verdict::parse(&verdict).ok_or_else(|| named(2, "verdict", &verdict))?,
        severity: r.get(3)?,
        condition: condition
            .map(|c| ConditionState::named(&c).ok_or_else(|| named(7, "condition state", &c)))
            .transpose()?,
        sealed: r.get(8)?,
        note: r.get(4)?,
        reviewer: r.get(5)?,
        decided_at: r.get(6)?,
    })
}

/// The rules a decision must meet before it is recorded.
fn check_decision(ruling: &Ruling) -> Result<(), InvalidDecision> {
    let Ruling {
        verdict,
        severity,
        note,
        reviewer,
        ..
    } = *ruling;
    match (verdict, severity) {
        (Verdict::NeedsRepair, Some(1..=5)) | (Verdict::Accepted | Verdict::Rejected, None) => {}
        (Verdict::NeedsRepair, _) => return Err(InvalidDecision::SeverityMissing),
        _ => return Err(InvalidDecision::SeverityWithoutRepair),
    }
    let reviewer = reviewer.trim();
    if reviewer.is_empty() {
        return Err(InvalidDecision::NoReviewer);
    }
    if reviewer.chars().count() > MAX_REVIEWER_CHARS {
        return Err(InvalidDecision::ReviewerTooLong);
    }
    if let Some(c) = reviewer.chars().find(|&c| is_control_or_format(c)) {
        return Err(InvalidDecision::ReviewerInvisible(code_point(c)));
    }
    if !reviewer.chars().any(char::is_alphanumeric) {
        return Err(InvalidDecision::NoReviewer);
    }
    if note.chars().count() > MAX_NOTE_CHARS {
        return Err(InvalidDecision::NoteTooLong);
    }
    if let Some(c) = note
        .chars()
        .find(|&c| c.is_control() && !matches!(c, '\t' | '\n' | '\r'))
    {
        return Err(InvalidDecision::NoteControl(code_point(c)));
    }
    Ok(())
}

/// A control character (NUL, escape) or an invisible format character (a
/// bidirectional override, a zero-width space): they hide or reorder what
/// a name shows.
fn is_control_or_format(c: char) -> bool {
    use unicode_properties::{GeneralCategory, UnicodeGeneralCategory};
    matches!(
        c.general_category(),
        GeneralCategory::Control | GeneralCategory::Format
    )
}

/// `U+202E`.
fn code_point(c: char) -> String {
    format!("U+{:04X}", u32::from(c))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::defect;

    fn store(dir: &tempfile::TempDir) -> ReviewStore {
        ReviewStore::open(&dir.path().join("review.sqlite")).unwrap()
    }

    #[test]
    fn a_decision_made_on_an_old_version_is_a_conflict_not_an_overwrite() {
        let dir = tempfile::tempdir().unwrap();
        let mut s = store(&dir);
        s.sync_candidates(&[defect("a", 0.9)]).unwrap();
        let first = s
            .decide("a", 0, &Ruling::new(Verdict::Accepted, "ann"))
            .unwrap();
        assert_eq!(first.version, 1);
        // Bob loaded the candidate before Ann decided.
        match s.decide("a", 0, &Ruling::new(Verdict::Rejected, "bob")) {
            Err(ReviewError::Conflict { current: 1, .. }) => {}
            other => panic!("{other:?}"),
        }
        let second = s
            .decide(
                "a",
                1,
                &Ruling {
                    severity: Some(4),
                    note: "wide, near bearing",
                    ..Ruling::new(Verdict::NeedsRepair, "bob")
                },
            )
            .unwrap();
        let history = s.history("a").unwrap();
        assert_eq!(history, vec![first, second.clone()]);
        assert_eq!(s.current_decisions().unwrap(), vec![second]);
    }

    #[test]
    fn decisions_stay_with_their_candidates_when_localisation_reruns() {
        let dir = tempfile::tempdir().unwrap();
        let mut s = store(&dir);
        assert_eq!(
            s.sync_candidates(&[defect("a", 0.9), defect("b", 0.8)])
                .unwrap(),
            2
        );
        s.decide(
            "a",
            0,
            &Ruling {
                note: "stain",
                ..Ruling::new(Verdict::Rejected, "ann")
            },
        )
        .unwrap();
        drop(s);
        // Reopened, with a new localisation: a kept, b gone, c new.
        let mut s = store(&dir);
        assert_eq!(
            s.sync_candidates(&[defect("a", 0.7), defect("c", 0.6)])
                .unwrap(),
            1
        );
        let current = s.current_decisions().unwrap();
        assert_eq!(current.len(), 1);
        assert_eq!(
            (current[0].candidate.as_str(), current[0].verdict),
            ("a", Verdict::Rejected)
        );
        assert_eq!(
            s.decide("c", 0, &Ruling::new(Verdict::Accepted, "ann"))
                .unwrap()
                .version,
            1
        );
    }

    #[test]
    fn bad_decisions_are_refused_with_the_reason() {
        let dir = tempfile::tempdir().unwrap();
        let mut s = store(&dir);
        s.sync_candidates(&[defect("a", 0.9)]).unwrap();
        let mut refused = |ruling: Ruling| s.decide("a", 0, &ruling).unwrap_err().to_string();
        let severity = |verdict, severity| Ruling {
            severity,
            ..Ruling::new(verdict, "ann")
        };
        assert!(refused(severity(Verdict::NeedsRepair, None)).contains("severity"));
        assert!(refused(severity(Verdict::NeedsRepair, Some(6))).contains("1 to 5"));
        assert!(refused(severity(Verdict::Accepted, Some(2))).contains("severity"));
        assert!(refused(Ruling::new(Verdict::Accepted, "  ")).contains("reviewer"));
        let unknown = s.decide("zz", 0, &Ruling::new(Verdict::Accepted, "ann"));
        assert!(unknown.unwrap_err().to_string().contains("zz"));
        assert!(s.history("a").unwrap().is_empty());
    }

    /// Accepted by `reviewer`, who puts the crack in `state`.
    fn accepted_in(state: ConditionState, reviewer: &str) -> Ruling<'_> {
        Ruling {
            condition: Some(state),
            ..Ruling::new(Verdict::Accepted, reviewer)
        }
    }

    #[test]
    fn a_reviewer_corrects_the_condition_state_and_a_rejection_has_none() {
        let dir = tempfile::tempdir().unwrap();
        let mut s = store(&dir);
        s.sync_candidates(&[defect("a", 0.9), defect("b", 0.8)])
            .unwrap();
        let severe = accepted_in(ConditionState::Severe, "ann");
        assert_eq!(
            s.decide("a", 0, &severe).unwrap().condition,
            Some(ConditionState::Severe)
        );
        let rejected = Ruling {
            verdict: Verdict::Rejected,
            ..severe
        };
        assert_eq!(s.decide("a", 1, &rejected).unwrap().condition, None);
        // Sealed is kept with a crack, never with a rejection.
        let sealed = Ruling {
            sealed: true,
            ..severe
        };
        assert!(s.decide("b", 0, &sealed).unwrap().sealed);
        let refused = Ruling {
            verdict: Verdict::Rejected,
            ..sealed
        };
        assert!(!s.decide("b", 1, &refused).unwrap().sealed);
        assert!(s.history("b").unwrap()[0].sealed);
        let history = s.history("a").unwrap();
        assert_eq!(
            history.iter().map(|d| d.condition).collect::<Vec<_>>(),
            [Some(ConditionState::Severe), None]
        );
    }

    #[test]
    fn a_database_made_before_condition_states_gains_the_column() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("review.sqlite");
        // The first schema, as databases were made before condition states.
        let conn = Connection::open(&path).unwrap();
        conn.execute_batch(SCHEMA).unwrap();
        conn.execute_batch(
            "INSERT INTO candidates (id, priority, confidence, version) VALUES ('a', 1, 0.9, 1);
             INSERT INTO decisions (candidate, version, verdict, note, reviewer, decided_at)
             VALUES ('a', 1, 'accepted', '', 'ann', '2026-11-25T10:00:00Z');",
        )
        .unwrap();
        drop(conn);
        let mut s = ReviewStore::open(&path).unwrap();
        assert_eq!(s.current_decisions().unwrap()[0].condition, None);
        assert!(!s.current_decisions().unwrap()[0].sealed);
        let poor = accepted_in(ConditionState::Poor, "bob");
        assert_eq!(
            s.decide("a", 1, &poor).unwrap().condition,
            Some(ConditionState::Poor)
        );
    }
}
