//! What `postflight compare` writes into the later run: `changes.json`
//! (the registration of the two flights' maps and every candidate's change
//! since the earlier flight) and `changes.parquet` (the changes, one row
//! each; positions in this run's frame, metres).

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::outputs::record::{ElementRecord, Unit};
use crate::run_dir::RunDir;
use crate::serde_pose::PoseJson;

/// Files of the comparison, in the later run.
pub mod files {
    pub const SUMMARY: &str = "changes.json";
    pub const TABLE: &str = "changes.parquet";
}

/// `changes.json`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ChangesSummary {
    /// The earlier run, and when its flight started (RFC 3339).
    pub before: PathBuf,
    pub before_flight_start: String,
    /// This run.
    pub after: PathBuf,
    pub registration: RegistrationRecord,
    /// Changes by kind (`new`, `grown`, ...).
    pub counts: BTreeMap<ChangeKind, usize>,
    pub changes: Vec<ChangeRecord>,
    /// Each element's and defect's quantities in the two element records,
    /// where both runs have one (`postflight record`).
    #[serde(default)]
    pub elements: Vec<ElementChange>,
    pub seconds: f64,
}

/// An element's (or a defect's) quantities in condition states 1 to 4 in
/// the earlier record and in this one; none where a record has no such
/// row.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ElementChange {
    /// postflight's name of the element (a defect's: its element's).
    pub element: String,
    /// The AASHTO element or defect number, and on a defect its element's.
    pub number: u16,
    pub parent: Option<u16>,
    /// The manual's name.
    pub name: String,
    pub unit: Unit,
    pub before: Option<[f64; 4]>,
    pub after: Option<[f64; 4]>,
}

/// A state's quantity moved by less than this share of the element's
/// total is not worth a line.
const MOVED_SHARE: f64 = 0.005;

impl ElementChange {
    /// The rows of two records paired by element, number and parent, in
    /// this record's order, then the earlier's rows it lacks.
    pub fn pair(before: &[ElementRecord], after: &[ElementRecord]) -> Vec<Self> {
        let key = |r: &ElementRecord| (r.element.clone(), r.number, r.parent);
        let states = |r: &ElementRecord| [r.cs1, r.cs2, r.cs3, r.cs4];
        let change =
            |r: &ElementRecord, b: Option<&ElementRecord>, a: Option<&ElementRecord>| Self {
                element: r.element.clone(),
                number: r.number,
                parent: r.parent,
                name: r.name.clone(),
                unit: r.unit,
                before: b.map(states),
                after: a.map(states),
            };
        let mut pairs: Vec<Self> = after
            .iter()
            .map(|a| change(a, before.iter().find(|b| key(b) == key(a)), Some(a)))
            .collect();
        pairs.extend(
            before
                .iter()
                .filter(|b| !after.iter().any(|a| key(a) == key(b)))
                .map(|b| change(b, Some(b), None)),
        );
        pairs
    }

    /// What moved between states, in the field's words: "deck, Cracking
    /// (RC and Other): condition state 2 from 12.0 to 18.0 m2".
    pub fn moved(&self) -> Vec<String> {
        let (before, after) = (
            self.before.unwrap_or([0.0; 4]),
            self.after.unwrap_or([0.0; 4]),
        );
        let total = before.iter().sum::<f64>().max(after.iter().sum::<f64>());
        (0..4)
            .filter(|&s| (after[s] - before[s]).abs() > MOVED_SHARE * total.max(1e-9))
            .map(|s| {
                format!(
                    "{}, {}: condition state {} from {:.1} to {:.1} {}",
                    self.element,
                    self.name,
                    s + 1,
                    before[s],
                    after[s],
                    self.unit.as_str()
                )
            })
            .collect()
    }
}

impl ChangesSummary {
    /// The earlier flight's date, `YYYY-MM-DD`: what "changes since" names.
    pub fn before_date(&self) -> &str {
        let start = &self.before_flight_start;
        start.get(..10).unwrap_or(start)
    }

    /// How many changes are of `kind`.
    pub fn count(&self, kind: ChangeKind) -> usize {
        self.counts.get(&kind).copied().unwrap_or(0)
    }
}

/// How the earlier flight's map was put onto this one's.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RegistrationRecord {
    /// `T_after_before`: the earlier frame in this run's.
    pub transform: PoseJson,
    /// Its yaw, pitch and roll, degrees.
    pub yaw_deg: f64,
    pub pitch_deg: f64,
    pub roll_deg: f64,
    /// Point-to-plane residual of the inliers, RMS, metres.
    pub rms_m: f64,
    /// Share of the earlier map's points on this one's, percent.
    pub overlap_pct: f64,
    pub iterations: usize,
}

crate::kind! {
    /// What became of a defect candidate between the flights.
    pub enum ChangeKind("change") {
        /// Seen now, not by the earlier flight, which inspected its place
        /// finely enough to see it.
        New = "new",
        /// Seen now, on surface the earlier flight did not inspect (or, when it
        /// has no coverage, may not have), or saw too coarsely for a crack this
        /// narrow: it may be old, first seen now. The mirror of
        /// `NotReinspected`.
        FirstSeen = "first_seen",
        /// Seen by both; longer now by more than both flights' measurement
        /// spread (and perhaps wider too: see the widening).
        Grown = "grown",
        /// Seen by both, as long as before, but wider by more than both
        /// flights' width uncertainties combined and a fifth of its earlier
        /// width.
        Widened = "widened",
        /// Seen by both, as long and as wide as before within the spread.
        Unchanged = "unchanged",
        /// Seen by both, but neither its length nor its width was measured in
        /// both (every view of it in one flight blurred, too oblique or cut
        /// short): whether it changed is not known; shoot it again.
        NotMeasured = "not_measured",
        /// Seen before; this flight inspected its place and found nothing.
        NotSeenAgain = "not_seen_again",
        /// Seen before; this flight did not inspect its place, so nothing is
        /// known of it now.
        NotReinspected = "not_reinspected",
    }
}

impl ChangeKind {
    /// As people read it: "not seen again".
    pub fn words(self) -> &'static str {
        match self {
            Self::FirstSeen => "first seen",
            Self::NotMeasured => "not measured",
            Self::NotSeenAgain => "not seen again",
            Self::NotReinspected => "not re-inspected",
            other => other.as_str(),
        }
    }

    /// A change an inspector looks at first: a crack not on record before,
    /// or one that grew or opened.
    pub fn stands_out(self) -> bool {
        matches!(
            self,
            Self::New | Self::FirstSeen | Self::Grown | Self::Widened
        )
    }
}

crate::table! {
    /// One candidate's change: a row of `changes.parquet`, and of
    /// `changes.json`'s `changes`.
    #[derive(Serialize, Deserialize)]
    pub struct ChangeRecord {
        change: ChangeKind,
        /// The candidate in this run, and its match in the earlier one.
        after: Option<String>,
        before: Option<String>,
        /// Where it is, this run's frame.
        position: [f64; 3] as [x, y, z],
        /// The structure element there, as this run's coverage names it.
        element: Option<String>,
        length_before_m: Option<f64>,
        length_after_m: Option<f64>,
        /// Growth, and the spread it is judged against, metres: in length
        /// (the spread the sum of each candidate's), or, where that shows it
        /// more, how far its trace now runs on beyond the earlier one (the
        /// spread how far a hairline tip's end differs between views, plus the
        /// link distance the two traces may lie apart).
        growth_m: Option<f64>,
        spread_m: Option<f64>,
        /// Its widest before and now, millimetres (each flight's `max_width_mm`;
        /// none where it was below resolution or not measured).
        #[serde(default)]
        width_before_mm: Option<f64>,
        #[serde(default)]
        width_after_mm: Option<f64>,
        /// How much wider it is now, and the spread that is judged against
        /// (both flights' width uncertainties combined, root of the sum of
        /// squares, at least a fifth of the earlier width), millimetres.
        #[serde(default)]
        widening_mm: Option<f64>,
        #[serde(default)]
        width_spread_mm: Option<f64>,
        /// For a candidate seen now only: whether the earlier flight inspected
        /// its place (`false`: first seen; none: the earlier run has no
        /// coverage there, so first seen too).
        earlier_inspected: Option<bool>,
        /// For a candidate seen now only: the earlier flight's finest view of
        /// its place, millimetres per pixel (the View model's GSD); a crack
        /// narrower than half of it is first seen, not new: that flight could
        /// not have seen it.
        #[serde(default)]
        earlier_mm_per_px: Option<f64>,
    }
}

/// Write `changes.parquet` and, last, `changes.json`.
pub fn write_changes(run: &RunDir, summary: &ChangesSummary) -> Result<(), Error> {
    run.write_rows(files::TABLE, &summary.changes)?;
    run.write_json(files::SUMMARY, summary)
}

/// `changes.json` of a run, `None` when it was not compared with an earlier one.
pub fn read_changes(run: &RunDir) -> Result<Option<ChangesSummary>, Error> {
    if !run.file(files::SUMMARY).is_file() {
        return Ok(None);
    }
    run.read_json(files::SUMMARY).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_are_keyed_by_the_kinds_names() {
        let counts: BTreeMap<ChangeKind, usize> =
            [(ChangeKind::Grown, 2), (ChangeKind::NotSeenAgain, 1)].into();
        let json = serde_json::to_string(&counts).unwrap();
        assert_eq!(json, r#"{"grown":2,"not_seen_again":1}"#);
        let back: BTreeMap<ChangeKind, usize> = serde_json::from_str(&json).unwrap();
        assert_eq!(back, counts);
    }
}
