//! A candidate's past, after `postflight compare` set this run beside an
//! earlier inspection: how it changed, and what the earlier review decided
//! on it (read from the earlier run's decisions database, if it has one).

use std::collections::HashMap;

use postflight_core::outputs::changes::{ChangeKind, ChangeRecord, ChangesSummary};

use crate::store::{DEFAULT_DB, Decision, ReviewError, ReviewStore};

/// What is known of a candidate from the earlier inspection.
#[derive(Debug, Clone, PartialEq)]
pub struct Since {
    /// The earlier flight's date, `YYYY-MM-DD`.
    pub date: String,
    pub change: ChangeRecord,
    /// The earlier review's current decision on the same crack.
    pub decision: Option<Decision>,
}

/// Each candidate of this run's past, by id (empty without a comparison).
pub fn pasts(changes: Option<&ChangesSummary>) -> Result<HashMap<String, Since>, ReviewError> {
    let Some(c) = changes else {
        return Ok(HashMap::new());
    };
    // Only a database that is there: opening creates one.
    let db = c.before.join(DEFAULT_DB);
    let earlier: HashMap<String, Decision> = if db.is_file() {
        ReviewStore::open(&db)?
            .current_decisions()?
            .into_iter()
            .map(|d| (d.candidate.clone(), d))
            .collect()
    } else {
        HashMap::new()
    };
    let date = c.before_date().to_string();
    Ok(c.changes
        .iter()
        .filter_map(|ch| {
            let since = Since {
                date: date.clone(),
                change: ch.clone(),
                decision: ch.before.as_ref().and_then(|b| earlier.get(b).cloned()),
            };
            Some((ch.after.clone()?, since))
        })
        .collect())
}

impl Since {
    /// One line: "grown by 0.21 m since 2025-06-15; then needs repair,
    /// severity 3".
    pub fn text(&self) -> String {
        let c = &self.change;
        let what = match (c.change, c.growth_m, c.widening_mm) {
            (ChangeKind::Grown, Some(g), _) => format!("grown by {g:.2} m since {}", self.date),
            (ChangeKind::Widened, _, Some(w)) => {
                format!("widened by {w:.2} mm since {}", self.date)
            }
            (ChangeKind::FirstSeen, ..) => match (c.earlier_inspected, c.earlier_mm_per_px) {
                (Some(true), Some(px)) => format!(
                    "first seen: the {} inspection saw here at {px:.1} mm/px, too coarse for a crack this narrow",
                    self.date
                ),
                _ => format!("first seen: the {} inspection did not look here", self.date),
            },
            (ChangeKind::NotMeasured, ..) => format!(
                "seen by the {} inspection too; whether it changed is not known: neither its length nor its width was measured both times",
                self.date
            ),
            (kind, ..) => format!("{} since {}", kind.words(), self.date),
        };
        match &self.decision {
            Some(d) => {
                let severity = d
                    .severity
                    .map(|s| format!(", severity {s}"))
                    .unwrap_or_default();
                format!("{what}; then {}{severity}", d.verdict.words())
            }
            None => what,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::{Ruling, Verdict};
    use crate::testing::defect;
    use postflight_core::outputs::changes::{ChangeRecord, RegistrationRecord};
    use postflight_core::serde_pose::PoseJson;

    fn change(kind: ChangeKind, after: Option<&str>, before: Option<&str>) -> ChangeRecord {
        ChangeRecord {
            change: kind,
            after: after.map(str::to_string),
            before: before.map(str::to_string),
            position: [0.0; 3],
            element: None,
            length_before_m: before.map(|_| 0.5),
            length_after_m: after.map(|_| 0.8),
            growth_m: (kind == ChangeKind::Grown).then_some(0.3),
            spread_m: None,
            width_before_mm: None,
            width_after_mm: None,
            widening_mm: (kind == ChangeKind::Widened).then_some(0.4),
            width_spread_mm: None,
            earlier_inspected: None,
            earlier_mm_per_px: None,
        }
    }

    #[test]
    fn a_candidate_shows_its_change_and_the_earlier_reviews_decision_on_the_same_crack() {
        let earlier = tempfile::tempdir().unwrap();
        let mut store = ReviewStore::open(&earlier.path().join(DEFAULT_DB)).unwrap();
        store
            .sync_candidates(&[defect("old-a", 0.9), defect("old-b", 0.8)])
            .unwrap();
        store
            .decide(
                "old-a",
                0,
                &Ruling {
                    severity: Some(3),
                    ..Ruling::new(Verdict::NeedsRepair, "Ana")
                },
            )
            .unwrap();
        let summary = ChangesSummary {
            before: earlier.path().to_owned(),
            before_flight_start: "2025-06-15T12:00:00.000000000Z".into(),
            after: "b".into(),
            registration: RegistrationRecord {
                transform: PoseJson {
                    translation: [0.0; 3],
                    rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
                },
                yaw_deg: 0.0,
                pitch_deg: 0.0,
                roll_deg: 0.0,
                rms_m: 0.01,
                overlap_pct: 99.0,
                iterations: 3,
            },
            counts: Default::default(),
            changes: vec![
                change(ChangeKind::Grown, Some("new-a"), Some("old-a")),
                change(ChangeKind::Unchanged, Some("new-b"), Some("old-b")),
                change(ChangeKind::New, Some("new-c"), None),
                change(ChangeKind::NotReinspected, None, Some("old-d")),
                change(ChangeKind::Widened, Some("new-e"), Some("old-e")),
                change(ChangeKind::FirstSeen, Some("new-f"), None),
                ChangeRecord {
                    earlier_inspected: Some(true),
                    earlier_mm_per_px: Some(1.2),
                    ..change(ChangeKind::FirstSeen, Some("new-g"), None)
                },
                change(ChangeKind::NotMeasured, Some("new-h"), Some("old-h")),
            ],
            elements: Vec::new(),
            seconds: 0.1,
        };
        let known = pasts(Some(&summary)).unwrap();
        assert_eq!(known.len(), 7, "one per candidate of this run");
        assert_eq!(
            known["new-a"].text(),
            "grown by 0.30 m since 2025-06-15; then needs repair, severity 3"
        );
        assert_eq!(known["new-b"].text(), "unchanged since 2025-06-15");
        assert_eq!(known["new-c"].text(), "new since 2025-06-15");
        assert_eq!(known["new-e"].text(), "widened by 0.40 mm since 2025-06-15");
        assert_eq!(
            known["new-f"].text(),
            "first seen: the 2025-06-15 inspection did not look here"
        );
        assert_eq!(
            known["new-g"].text(),
            "first seen: the 2025-06-15 inspection saw here at 1.2 mm/px, too coarse for a crack this narrow"
        );
        assert_eq!(
            known["new-h"].text(),
            "seen by the 2025-06-15 inspection too; whether it changed is not known: neither its length nor its width was measured both times"
        );
        // Without an earlier database, nothing is created there.
        let elsewhere = tempfile::tempdir().unwrap();
        let summary = ChangesSummary {
            before: elsewhere.path().to_owned(),
            ..summary
        };
        assert_eq!(pasts(Some(&summary)).unwrap()["new-a"].decision, None);
        assert!(!elsewhere.path().join(DEFAULT_DB).exists());
    }
}
