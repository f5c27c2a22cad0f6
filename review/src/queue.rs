//! The review queue: the run's defect candidates in review order, each with
//! its current decision, the filters an inspector narrows it by, and how far
//! the review has got.

use std::collections::HashMap;

use postflight_core::outputs::localise::DefectRecord;

use crate::store::{Decision, Verdict};

/// Which candidates the queue shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Filter {
    #[default]
    All,
    Pending,
    Accepted,
    Rejected,
    NeedsRepair,
}

impl Filter {
    pub const ALL: [Self; 5] = [
        Self::All,
        Self::Pending,
        Self::Accepted,
        Self::Rejected,
        Self::NeedsRepair,
    ];

    /// The name in addresses (`?filter=pending`).
    pub fn key(self) -> &'static str {
        match self {
            Self::All => "all",
            Self::Pending => "pending",
            Self::Accepted => "accepted",
            Self::Rejected => "rejected",
            Self::NeedsRepair => "needs_repair",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Self::NeedsRepair => "needs repair",
            other => other.key(),
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.key() == s)
    }

    pub fn admits(self, decision: Option<&Decision>) -> bool {
        matches!(
            (self, decision.map(|d| d.verdict)),
            (Self::All, _)
                | (Self::Pending, None)
                | (Self::Accepted, Some(Verdict::Accepted))
                | (Self::Rejected, Some(Verdict::Rejected))
                | (Self::NeedsRepair, Some(Verdict::NeedsRepair))
        )
    }
}

/// One candidate in the queue.
#[derive(Debug, Clone)]
pub struct Entry<'a> {
    /// Place in review order, from 1.
    pub rank: usize,
    pub defect: &'a DefectRecord,
    /// The current decision; `None` while pending.
    pub decision: Option<Decision>,
}

impl Entry<'_> {
    /// The version a new decision on it is made on.
    pub fn version(&self) -> i64 {
        self.decision.as_ref().map_or(0, |d| d.version)
    }
}

/// How far the review has got.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct Progress {
    pub total: usize,
    pub reviewed: usize,
    pub accepted: usize,
    pub rejected: usize,
    pub needs_repair: usize,
}

impl Progress {
    /// How many candidates a filter shows.
    pub fn count(&self, filter: Filter) -> usize {
        match filter {
            Filter::All => self.total,
            Filter::Pending => self.total - self.reviewed,
            Filter::Accepted => self.accepted,
            Filter::Rejected => self.rejected,
            Filter::NeedsRepair => self.needs_repair,
        }
    }
}

/// The queue at one moment.
pub struct Queue<'a> {
    pub entries: Vec<Entry<'a>>,
}

impl<'a> Queue<'a> {
    /// `order`: the candidates in review order; `current`: the current
    /// decisions (of these candidates or of ones localisation no longer has).
    pub fn new(order: &[&'a DefectRecord], current: Vec<Decision>) -> Self {
        let mut by_id: HashMap<String, Decision> = current
            .into_iter()
            .map(|d| (d.candidate.clone(), d))
            .collect();
        let entries = order
            .iter()
            .enumerate()
            .map(|(i, d)| Entry {
                rank: i + 1,
                defect: d,
                decision: by_id.remove(&d.id),
            })
            .collect();
        Self { entries }
    }

    pub fn progress(&self) -> Progress {
        let mut p = Progress {
            total: self.entries.len(),
            ..Progress::default()
        };
        for e in &self.entries {
            let Some(d) = &e.decision else { continue };
            p.reviewed += 1;
            match d.verdict {
                Verdict::Accepted => p.accepted += 1,
                Verdict::Rejected => p.rejected += 1,
                Verdict::NeedsRepair => p.needs_repair += 1,
            }
        }
        p
    }

    pub fn get(&self, id: &str) -> Option<&Entry<'a>> {
        self.entries.iter().find(|e| e.defect.id == id)
    }

    pub fn shown(&self, filter: Filter) -> impl Iterator<Item = &Entry<'a>> {
        self.entries
            .iter()
            .filter(move |e| filter.admits(e.decision.as_ref()))
    }

    /// The next candidate after `id` in review order (or, `forward` false,
    /// the one before) that `filter` shows.
    pub fn neighbour(&self, id: &str, filter: Filter, forward: bool) -> Option<&Entry<'a>> {
        let at = self.entries.iter().position(|e| e.defect.id == id)?;
        let shown = |e: &&Entry<'a>| filter.admits(e.decision.as_ref());
        if forward {
            self.entries[at + 1..].iter().find(shown)
        } else {
            self.entries[..at].iter().rev().find(shown)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::defect;

    fn decision(candidate: &str, verdict: Verdict) -> Decision {
        Decision {
            candidate: candidate.into(),
            version: 1,
            verdict,
            severity: (verdict == Verdict::NeedsRepair).then_some(2),
            condition: None,
            sealed: false,
            note: String::new(),
            reviewer: "ann".into(),
            decided_at: "2026-11-23T00:00:00Z".into(),
        }
    }

    #[test]
    fn filters_progress_and_neighbours_follow_the_decisions() {
        let defects: Vec<DefectRecord> = ["a", "b", "c", "d"].map(|id| defect(id, 0.5)).into();
        let order: Vec<&DefectRecord> = defects.iter().collect();
        let queue = Queue::new(
            &order,
            vec![
                decision("b", Verdict::Rejected),
                decision("c", Verdict::NeedsRepair),
                // A candidate localisation no longer has.
                decision("gone", Verdict::Accepted),
            ],
        );
        let p = queue.progress();
        assert_eq!(
            (p.total, p.reviewed, p.rejected, p.needs_repair),
            (4, 2, 1, 1)
        );
        assert_eq!(p.count(Filter::Pending), 2);
        let ids = |f| {
            queue
                .shown(f)
                .map(|e| e.defect.id.as_str())
                .collect::<Vec<_>>()
        };
        assert_eq!(ids(Filter::Pending), ["a", "d"]);
        assert_eq!(ids(Filter::NeedsRepair), ["c"]);
        assert_eq!(ids(Filter::Accepted), Vec::<&str>::new());
        let next = |id, f, fwd| queue.neighbour(id, f, fwd).map(|e| e.defect.id.as_str());
        assert_eq!(next("a", Filter::Pending, true), Some("d"));
        assert_eq!(next("d", Filter::Pending, true), None);
        assert_eq!(next("d", Filter::All, false), Some("c"));
        assert_eq!(next("c", Filter::Pending, false), Some("a"));
        assert_eq!(queue.get("c").unwrap().version(), 1);
        assert_eq!(queue.get("a").unwrap().version(), 0);
    }
}
