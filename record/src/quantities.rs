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

#[cfg(test)]
mod tests {
    use nalgebra::{Point3, Vector2};
    use postflight_core::map::{VoxelGrid, VoxelIndex};
    use postflight_core::outputs::record::QuantitySource;

    use super::*;
    use crate::catalogue::element_numbered;
    use crate::cells::{Cells, Voxel};

    /// A 6 m x 3 m deck of 0.5 m voxels, one layer, its west `seen_m`
    /// metres inspected.
    fn deck(seen_m: f64) -> RecordedElement {
        let voxels: Vec<Voxel> = (0..12)
            .flat_map(|x| (0..6).map(move |y| (x, y)))
            .map(|(x, y)| Voxel {
                index: VoxelIndex([x, y, 0]),
                inspected: f64::from(x) * 0.5 < seen_m,
                exposed: true,
            })
            .collect();
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let cells = Cells::lay(Unit::SquareMetres, &grid, &voxels, Vector2::x(), 0.3);
        RecordedElement {
            name: "deck".into(),
            aashto: *element_numbered(12).unwrap(),
            total: cells.total(),
            cells,
            source: QuantitySource::Structure,
        }
    }

    /// A straight crack along x at `y`, from `x0` to `x1`, on the deck's top.
    fn crack(id: &str, y: f64, x0: f64, x1: f64, state: ConditionState) -> CountedCrack {
        CountedCrack {
            id: id.into(),
            element: "deck".into(),
            lines: vec![vec![[x0, y, 0.5], [x1, y, 0.5]]],
            state,
            sealed: false,
            pending: false,
        }
    }

    use postflight_core::outputs::record::Unit;

    #[test]
    fn a_heavy_pattern_puts_its_cracks_and_the_surface_between_them_in_state_3() {
        let d = deck(6.0);
        let a = crack("a", 1.05, 1.0, 2.5, ConditionState::Fair);
        let b = crack("b", 1.25, 1.0, 2.5, ConditionState::Fair);
        let t = tally(&d, &[&a, &b]);
        let defect = t.defect.unwrap();
        // 1.5 m of two cracks 0.2 m apart in 0.3 m cells: five cells along,
        // one or two across; all heavy pattern.
        assert_eq!(defect.states[1], 0.0);
        assert!(
            defect.states[2] >= 5.0 * 0.09 - 1e-9 && defect.states[2] <= 12.0 * 0.09,
            "{defect:?}"
        );
        // Alone, each is state 2 by its width.
        let alone = tally(&d, &[&a]).defect.unwrap();
        assert_eq!(alone.states[2], 0.0);
        assert!(alone.states[1] > 0.0);
        assert_eq!(t.element.states.iter().sum::<f64>(), d.total);
    }

    #[test]
    fn a_sealed_moderate_crack_is_state_1_and_a_sealed_wide_one_stays_3() {
        let d = deck(6.0);
        let mut moderate = crack("m", 1.0, 1.0, 2.0, ConditionState::Fair);
        moderate.sealed = true;
        let mut wide = crack("w", 2.5, 3.0, 4.0, ConditionState::Poor);
        wide.sealed = true;
        let t = tally(&d, &[&moderate, &wide]);
        let defect = t.defect.unwrap();
        assert!(defect.states[0] > 0.0 && defect.states[1] == 0.0 && defect.states[2] > 0.0);
        assert_eq!(t.element.candidates.iter().collect::<Vec<_>>(), ["w"]);
    }

    #[test]
    fn what_was_not_seen_goes_as_each_rule_says() {
        let d = deck(3.0);
        let c = crack("c", 1.0, 0.5, 2.5, ConditionState::Poor);
        let seen = tally(&d, &[&c]);
        let (inspected, unseen) = (seen.element.inspected, seen.element.not_inspected);
        assert!((inspected + unseen - d.total).abs() < 1e-9 && unseen > 0.4 * d.total);
        let filled = |rule, earlier| {
            let mut t = seen.clone();
            fill_not_inspected(&mut t, rule, earlier);
            t
        };
        let cs1 = filled(NotInspectedRule::Cs1, None);
        assert!((cs1.element.states[0] - seen.element.states[0] - unseen).abs() < 1e-9);
        assert_eq!(cs1.element.states[2], seen.element.states[2]);
        let refuse = filled(NotInspectedRule::Refuse, None);
        let scale = d.total / inspected;
        assert!((refuse.element.states[2] - seen.element.states[2] * scale).abs() < 1e-9);
        let earlier = EarlierShares {
            element: [0.5, 0.25, 0.25, 0.0],
            defect: [0.0, 0.25, 0.25, 0.0],
        };
        let previous = filled(NotInspectedRule::Previous, Some(earlier));
        assert!((previous.element.states[1] - unseen * 0.25).abs() < 1e-9);
        let defect = previous.defect.as_ref().unwrap();
        assert!((defect.not_inspected - unseen * 0.5).abs() < 1e-9);
        for t in [&cs1, &refuse, &previous] {
            assert!((t.element.total() - d.total).abs() < 1e-9);
        }
    }
}
