//! The files an owner submits, from `elements.parquet`'s rows:
//!
//! - `nbe.xml`, the FHWA's element file under the *Specification for the
//!   National Bridge Inventory Bridge Elements* (2014): an `FHWAELEMENT`
//!   root of flat `FHWAED` records (`STATE`, `STRUCNUM`, `EN`, `EPN` on a
//!   defect's record only, `TOTALQTY`, `CS1`-`CS4`), quantities in metric
//!   units (square metres, metres, each) as whole numbers;
//! - `snbi-elements.json`, the element items of the *Specifications for the
//!   National Bridge Inventory* (SNBI, 2022), which replace the file from
//!   2026: per element or defect `BE01` (its number), `BE02` (the parent
//!   element's, on a defect only), `BE03` (total quantity) and `BCS01`-
//!   `BCS04`, in the SNBI's US customary units (square feet, feet, each)
//!   as whole numbers.
//!
//! Rounded, a row's states still sum to its total: the total is rounded,
//! and the states are rounded down and the units left over go to the
//! states with the largest remainders. A defect present at all is at least
//! one unit.

use postflight_core::outputs::record::{ElementRecord, Unit};
use quick_xml::Writer;
use quick_xml::events::{BytesDecl, BytesEnd, BytesStart, BytesText, Event};
use serde::Serialize;

/// Square feet in a square metre, feet in a metre.
const FT2_PER_M2: f64 = 10.763_910_416_709_722;
const FT_PER_M: f64 = 3.280_839_895_013_123;

/// A row's quantities in whole units: its total and its four states, which
/// sum to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Whole {
    pub total: u64,
    pub states: [u64; 4],
}

impl Whole {
    /// `states` (summing to the row's total) rounded so they still sum;
    /// `at_least_one` for a defect, present however small.
    pub fn of(states: [f64; 4], at_least_one: bool) -> Self {
        let sum: f64 = states.iter().sum();
        let mut total = sum.round().max(0.0) as u64;
        if at_least_one && sum > 0.0 {
            total = total.max(1);
        }
        // Scale to the rounded total, then hand out what flooring leaves.
        let scaled: Vec<f64> = states
            .iter()
            .map(|q| {
                if sum > 0.0 {
                    q.max(0.0) * total as f64 / sum
                } else {
                    0.0
                }
            })
            .collect();
        let mut whole: [u64; 4] = std::array::from_fn(|i| scaled[i].floor() as u64);
        let left = total - whole.iter().sum::<u64>();
        let mut by_remainder: Vec<usize> = (0..4).collect();
        by_remainder.sort_by(|&a, &b| {
            let r = |i: usize| scaled[i] - scaled[i].floor();
            r(b).total_cmp(&r(a)).then(a.cmp(&b))
        });
        for &i in by_remainder.iter().take(left as usize) {
            whole[i] += 1;
        }
        Self {
            total,
            states: whole,
        }
    }
}

/// The row's states in the SNBI's units.
fn us_customary(row: &ElementRecord) -> [f64; 4] {
    let factor = match row.unit {
        Unit::SquareMetres => FT2_PER_M2,
        Unit::Metres => FT_PER_M,
        Unit::Each => 1.0,
    };
    [row.cs1, row.cs2, row.cs3, row.cs4].map(|q| q * factor)
}

fn metric(row: &ElementRecord) -> [f64; 4] {
    [row.cs1, row.cs2, row.cs3, row.cs4]
}

/// `nbe.xml`'s text.
pub fn nbe_xml(state_code: &str, rows: &[ElementRecord]) -> String {
    let mut w = Writer::new_with_indent(Vec::new(), b' ', 2);
    let text = |w: &mut Writer<Vec<u8>>, tag: &str, value: &str| {
        // Writing to a Vec<u8> cannot fail.
        w.write_event(Event::Start(BytesStart::new(tag)))
            .expect("in memory");
        w.write_event(Event::Text(BytesText::new(value)))
            .expect("in memory");
        w.write_event(Event::End(BytesEnd::new(tag)))
            .expect("in memory");
    };
    w.write_event(Event::Decl(BytesDecl::new("1.0", Some("UTF-8"), None)))
        .expect("in memory");
    w.write_event(Event::Start(BytesStart::new("FHWAELEMENT")))
        .expect("in memory");
    for row in rows {
        let q = Whole::of(metric(row), row.parent.is_some());
        w.write_event(Event::Start(BytesStart::new("FHWAED")))
            .expect("in memory");
        text(&mut w, "STATE", state_code);
        text(&mut w, "STRUCNUM", &row.structure_number);
        text(&mut w, "EN", &row.number.to_string());
        if let Some(parent) = row.parent {
            text(&mut w, "EPN", &parent.to_string());
        }
        text(&mut w, "TOTALQTY", &q.total.to_string());
        for (i, s) in q.states.iter().enumerate() {
            text(&mut w, &format!("CS{}", i + 1), &s.to_string());
        }
        w.write_event(Event::End(BytesEnd::new("FHWAED")))
            .expect("in memory");
    }
    w.write_event(Event::End(BytesEnd::new("FHWAELEMENT")))
        .expect("in memory");
    let mut out = String::from_utf8(w.into_inner()).expect("written from UTF-8 text");
    out.push('\n');
    out
}

/// One element or defect as the SNBI's items.
#[derive(Debug, Clone, Serialize)]
#[allow(non_snake_case)]
struct SnbiElement {
    BE01: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    BE02: Option<String>,
    BE03: u64,
    BCS01: u64,
    BCS02: u64,
    BCS03: u64,
    BCS04: u64,
}

/// `snbi-elements.json`.
#[derive(Debug, Clone, Serialize)]
pub struct SnbiFile {
    /// What the items follow, and their units.
    specification: &'static str,
    units: &'static str,
    state_code: String,
    /// SNBI B.ID.01.
    structure_number: String,
    elements: Vec<SnbiElement>,
}

/// `snbi-elements.json`'s content.
pub fn snbi(state_code: &str, structure_number: &str, rows: &[ElementRecord]) -> SnbiFile {
    let elements = rows
        .iter()
        .map(|row| {
            let q = Whole::of(us_customary(row), row.parent.is_some());
            SnbiElement {
                BE01: row.number.to_string(),
                BE02: row.parent.map(|p| p.to_string()),
                BE03: q.total,
                BCS01: q.states[0],
                BCS02: q.states[1],
                BCS03: q.states[2],
                BCS04: q.states[3],
            }
        })
        .collect();
    SnbiFile {
        specification: "FHWA Specifications for the National Bridge Inventory (SNBI, 2022): items BE01-BE03 and BCS01-BCS04",
        units: "ft2 for area elements, ft for linear ones, each for counted ones; whole numbers",
        state_code: state_code.to_string(),
        structure_number: structure_number.to_string(),
        elements,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounded_states_sum_to_the_rounded_total() {
        let w = Whole::of([100.4, 20.3, 0.2, 0.0], false);
        assert_eq!(w.total, 121);
        assert_eq!(w.states.iter().sum::<u64>(), 121);
        assert_eq!(w.states, [101, 20, 0, 0]);
        // Three equal thirds of 10: the first two remainders win the unit.
        let w = Whole::of(
            [10.0 / 3.0; 3]
                .into_iter()
                .chain([0.0])
                .collect::<Vec<_>>()
                .try_into()
                .unwrap(),
            false,
        );
        assert_eq!(w.total, 10);
        assert_eq!(w.states, [4, 3, 3, 0]);
        // A defect of a fifth of a square metre is one.
        let w = Whole::of([0.0, 0.2, 0.0, 0.0], true);
        assert_eq!((w.total, w.states), (1, [0, 1, 0, 0]));
        assert_eq!(Whole::of([0.0; 4], true).total, 0);
    }
}
