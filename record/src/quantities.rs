//! An element's quantities in condition states: each cell in the worst
//! state of the cracks over it (and of the patterns they run in), the
//! defect's quantity the cells its cracks are in, the element's the worst
//! of its defects at each cell and state 1 elsewhere; then the part not
//! inspected, as `[record] not_inspected` says.

use std::collections::{BTreeMap, BTreeSet};

use postflight_core::condition::ConditionState;
use postflight_core::outputs::record::NotInspectedRule;

use crate::cells::CellKey;
use crate::cracks::{CountedCrack, sealed_state};
use crate::elements::RecordedElement;
use crate::pattern::{Line, patterns, sample};

/// Quantities of one row: an element, or its cracking defect.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Tally {
    pub inspected: f64,
    pub not_inspected: f64,
    /// States 1 to 4.
    pub states: [f64; 4],
    /// The cracks behind its states 2 to 4 (ids).
    pub candidates: BTreeSet<String>,
    /// Of those, the ones no reviewer has decided.
    pub pending: BTreeSet<String>,
}

impl Tally {
    pub fn total(&self) -> f64 {
        self.states.iter().sum()
    }

    fn add(&mut self, state: ConditionState, quantity: f64) {
        self.states[usize::from(state.number() - 1)] += quantity;
    }
}

/// An element's tallies: its own, and its cracking defect's where it has
/// cracks.
#[derive(Debug, Clone, PartialEq)]
pub struct ElementTally {
    pub element: Tally,
    pub defect: Option<Tally>,
}

/// The state a crack's cells take: its own or its pattern's, the worse,
/// then sealed as the manual counts a sealed crack.
fn crack_state(crack: &CountedCrack, pattern: Option<ConditionState>) -> ConditionState {
    let state = pattern.map_or(crack.state, |p| p.max(crack.state));
    if crack.sealed {
        sealed_state(state)
    } else {
        state
    }
}

/// The worst state over each cell, and the cracks (their places in
/// `cracks`) that put it there.
pub fn cell_states(
    element: &RecordedElement,
    cracks: &[&CountedCrack],
) -> BTreeMap<CellKey, (ConditionState, BTreeSet<usize>)> {
    let cells = &element.cells;
    let step = cells.cell_m / 4.0;
    let lines: Vec<Line> = cracks
        .iter()
        .enumerate()
        .flat_map(|(i, c)| c.lines.iter().map(move |l| sample(i, l, step)))
        .collect();
    let in_pattern = patterns(cracks.len(), &lines);
    let mut states: BTreeMap<CellKey, (ConditionState, BTreeSet<usize>)> = BTreeMap::new();
    let mut mark = |key: CellKey, state: ConditionState, crack: usize| {
        let entry = states.entry(key).or_insert((state, BTreeSet::new()));
        if state > entry.0 {
            *entry = (state, BTreeSet::new());
        }
        if state == entry.0 {
            entry.1.insert(crack);
        }
    };
    for line in &lines {
        let state = crack_state(cracks[line.crack], in_pattern[line.crack].state);
        for key in cells.cells_of_line(&line.points) {
            mark(key, state, line.crack);
        }
    }
    for (i, p) in in_pattern.iter().enumerate() {
        let Some(pattern) = p.state else { continue };
        let state = crack_state(cracks[i], Some(pattern));
        for (a, b) in &p.spans {
            for key in cells.cells_of_line(&[*a, *b]) {
                mark(key, state, i);
            }
        }
    }
    states
}

/// The element's and its defect's quantities in the part the flight
/// inspected (a cell with a counted crack in it was seen, whatever the
/// View model says of its voxels); the rest is `not_inspected`, in no
/// state yet.
pub fn tally(element: &RecordedElement, cracks: &[&CountedCrack]) -> ElementTally {
    let states = cell_states(element, cracks);
    let scale = element.scale();
    let mut own = Tally::default();
    let mut defect = Tally::default();
    for (key, cell) in &element.cells.cells {
        let q = cell.quantity * scale;
        let cracked = states.get(key);
        if !(cell.inspected || cracked.is_some()) {
            own.not_inspected += q;
            continue;
        }
        own.inspected += q;
        let Some((state, by)) = cracked else {
            own.add(ConditionState::Good, q);
            continue;
        };
        own.add(*state, q);
        defect.add(*state, q);
        if *state > ConditionState::Good {
            for &i in by {
                for t in [&mut own, &mut defect] {
                    t.candidates.insert(cracks[i].id.clone());
                    if cracks[i].pending {
                        t.pending.insert(cracks[i].id.clone());
                    }
                }
            }
        }
    }
    defect.inspected = defect.total();
    ElementTally {
        element: own,
        defect: (defect.total() > 0.0).then_some(defect),
    }
}

/// An earlier record's shares of one element's total in each state: its
/// own row's, and its defect's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EarlierShares {
    pub element: [f64; 4],
    pub defect: [f64; 4],
}

/// Put the part not inspected into states as `rule` says: `earlier` is the
/// previous record's shares for this element (with `previous`).
pub fn fill_not_inspected(
    t: &mut ElementTally,
    rule: NotInspectedRule,
    earlier: Option<EarlierShares>,
) {
    let unseen = t.element.not_inspected;
    if unseen <= 0.0 {
        return;
    }
    let inspected = t.element.inspected;
    let seen_shares = |states: &[f64; 4]| -> [f64; 4] {
        if inspected > 0.0 {
            states.map(|q| q / inspected)
        } else {
            [1.0, 0.0, 0.0, 0.0]
        }
    };
    let (element_shares, defect_shares) = match (rule, earlier) {
        (NotInspectedRule::Cs1, _) => ([1.0, 0.0, 0.0, 0.0], [0.0; 4]),
        (NotInspectedRule::Previous, Some(e)) => (e.element, e.defect),
        // Without an earlier record of the element (the stage refuses this
        // before it gets here), nothing better than what was seen.
        (NotInspectedRule::Refuse | NotInspectedRule::Previous, _) => (
            seen_shares(&t.element.states),
            t.defect
                .as_ref()
                .map_or([0.0; 4], |d| seen_shares(&d.states)),
        ),
    };
    for (q, share) in t.element.states.iter_mut().zip(element_shares) {
        *q += unseen * share;
    }
    if defect_shares.iter().any(|s| *s > 0.0) {
        let defect = t.defect.get_or_insert_with(Tally::default);
        for (q, share) in defect.states.iter_mut().zip(defect_shares) {
            *q += unseen * share;
        }
        defect.not_inspected = defect.total() - defect.inspected;
    }
}
