//! The cracks the record counts, each in the condition state the manual
//! gives it on its element: by its width (its widest stretch, against the
//! limits of the element's material), over that the state a reviewer set,
//! and a sealed moderate crack in state 1. Rejected candidates never
//! count; pending ones as `[record] pending` says; one whose width no view
//! measured counts once a reviewer gives its state.

use std::collections::BTreeMap;

use postflight_core::condition::{ConditionConfig, ConditionState, CrackLimits};
use postflight_core::outputs::localise::DefectRecord;
use postflight_core::outputs::record::{CandidateCounts, PendingRule};

use crate::catalogue::Cracking;

/// What a reviewer decided about a candidate, as the record needs it (the
/// review queue's decision, read by whoever runs the record).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ReviewerCall {
    /// Not a crack: never counted.
    pub rejected: bool,
    /// The state the reviewer put it in, over the one its width gives.
    pub condition: Option<ConditionState>,
    /// The crack has been sealed.
    pub sealed: bool,
}

/// The reviewers' decisions by candidate id; a candidate without one is
/// pending.
pub type Decisions = BTreeMap<String, ReviewerCall>;

/// A crack as the record counts it.
#[derive(Debug, Clone, PartialEq)]
pub struct CountedCrack {
    pub id: String,
    /// postflight's element it is on.
    pub element: String,
    /// Its centre lines (its trace's, else its position alone), world
    /// frame, metres.
    pub lines: Vec<Vec<[f64; 3]>>,
    /// The state its width (or its reviewer) gives it, before any pattern.
    pub state: ConditionState,
    pub sealed: bool,
    /// No reviewer has decided it.
    pub pending: bool,
}

/// The state a crack's width puts it in on an element whose cracks are
/// `cracking` (`[condition]`'s limits apply to its own material); `None`
/// where no view measured it (or its bound straddles a limit).
pub fn width_state(
    defect: &DefectRecord,
    cracking: Cracking,
    condition: &ConditionConfig,
) -> Option<ConditionState> {
    match cracking {
        Cracking::Steel => Some(ConditionState::Poor),
        Cracking::Concrete(material) => {
            let limits: CrackLimits = if material == condition.material {
                condition.limits()
            } else {
                material.limits()
            };
            defect
                .width
                .as_ref()
                .and_then(|w| limits.state_of(w))
                .map(|call| call.state)
        }
    }
}

/// The state a sealed crack counts in: a moderate crack (state 2) sealed
/// is state 1; a wide one stays as it is.
pub fn sealed_state(state: ConditionState) -> ConditionState {
    match state {
        ConditionState::Fair => ConditionState::Good,
        other => other,
    }
}

/// The candidates the record counts, on the elements `cracking_of` knows
/// (postflight's element name to its cracking), and how many of each
/// decision there were.
pub fn counted_cracks(
    defects: &[DefectRecord],
    decisions: &Decisions,
    pending_rule: PendingRule,
    condition: &ConditionConfig,
    cracking_of: &dyn Fn(&str) -> Option<Cracking>,
) -> (Vec<CountedCrack>, CandidateCounts) {
    let mut counts = CandidateCounts::default();
    let mut counted = Vec::new();
    for d in defects {
        let call = decisions.get(&d.id);
        match call {
            Some(c) if c.rejected => {
                counts.rejected += 1;
                continue;
            }
            Some(_) => counts.accepted += 1,
            None => counts.pending += 1,
        }
        if call.is_none() && pending_rule == PendingRule::Skip {
            continue;
        }
        let Some((element, cracking)) = d
            .element
            .as_deref()
            .and_then(|e| cracking_of(e).map(|c| (e, c)))
        else {
            counts.off_elements += 1;
            continue;
        };
        let sealed = call.is_some_and(|c| c.sealed);
        let state = call
            .and_then(|c| c.condition)
            .or_else(|| width_state(d, cracking, condition));
        // No state: a crack is there, but which state is for a reviewer (or
        // a gauge on site) to say.
        let Some(state) = state else {
            counts.unmeasured.push(d.id.clone());
            continue;
        };
        let lines = if d.trace.is_empty() {
            vec![vec![d.position]]
        } else {
            d.trace.0.clone()
        };
        counted.push(CountedCrack {
            id: d.id.clone(),
            element: element.to_string(),
            lines,
            state,
            sealed,
            pending: call.is_none(),
        });
    }
    (counted, counts)
}
