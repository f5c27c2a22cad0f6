//! The record's settings, declared once: the `[record]` table of
//! `postflight.toml` (with its `[[record.element]]` tables) and the flags of
//! `postflight record`.

use postflight_core::InvalidSetting;
use postflight_core::kind::parse_named;
use postflight_core::outputs::record::{NotInspectedRule, PendingRule};
use serde::{Deserialize, Serialize};

use crate::catalogue::{self, element_numbered};

postflight_core::settings! {
    table = "record", keys = keys;
    /// `[record]`: the owner's numbers for the structure and its elements,
    /// and how the record counts what the flight did not see.
    pub struct RecordSettings =>
    /// How the record is made.
    struct RecordConfig {
        /// The owner's structure number (NBI item 8, SNBI B.ID.01), up to
        /// 15 characters, e.g. "000000000012345"; without it no submission
        /// file is written.
        #[arg(long = "structure-number", value_name = "NUMBER")]
        structure_number: String,
        /// The state's two-digit FIPS code, as the FHWA's files name the
        /// state, e.g. "06"; without it no submission file is written.
        #[arg(long = "state-code", value_name = "NN")]
        state_code: String,
        /// The side of the cells an area element (a deck, a slab) is judged
        /// on, and the length of the stretches a linear one is, metres: each
        /// cell is in the worst state of the cracks in it.
        #[arg(long = "cell", value_name = "METRES")]
        cell_m: f64 = 0.3,
        /// What the part of an element the flight did not inspect counts as:
        /// `previous` (an earlier record's states, `--previous RUN`), `cs1`
        /// (no defect seen, flagged) or `refuse` (no submission files while
        /// an element is under min_inspected_pct).
        #[arg(long = "not-inspected", value_name = "previous|cs1|refuse", value_parser = parse_named::<NotInspectedRule>)]
        not_inspected: NotInspectedRule = NotInspectedRule::Refuse,
        /// With not_inspected = "refuse": the share of every element the
        /// flight must inspect for the submission files, percent.
        #[arg(long = "min-inspected", value_name = "PCT")]
        min_inspected_pct: f64 = 80.0,
        /// Whether candidates no reviewer has decided count (`count`,
        /// flagged in every row) or wait for a reviewer (`skip`).
        #[arg(long = "pending", value_name = "count|skip", value_parser = parse_named::<PendingRule>)]
        pending: PendingRule = PendingRule::Count,
        /// The owner's numbers for postflight's elements, over the defaults
        /// by kind (deck 12, girder 110, pier 205 or 210 by its shape):
        /// each `[[record.element]]` table names elements by `name` or by a
        /// `pattern` (`girder *`), gives the AASHTO `number` and, where the
        /// owner's inventory has it, the element's `quantity`, which wins
        /// over the one measured. The flag takes one as a TOML inline table.
        #[arg(long = "element", value_name = "ELEMENT")]
        element: Vec<ElementChoice> = Vec::new(),
    }
}

/// The owner's number (and inventory quantity) for some of postflight's
/// elements.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ElementChoice {
    /// The element postflight names so (`deck`, a named target box).
    #[serde(default)]
    pub name: Option<String>,
    /// Or every element whose name matches this shell pattern.
    #[serde(default)]
    pub pattern: Option<String>,
    /// The AASHTO element number.
    pub number: u16,
    /// The owner's inventory quantity, in the element's unit.
    #[serde(default)]
    pub quantity: Option<f64>,
}

postflight_core::inline_table_setting!(
    ElementChoice,
    "an element {name = \"...\" or pattern = \"...\", number = N, quantity = Q}"
);

impl ElementChoice {
    /// Whether it names the element `name`.
    pub fn names(&self, name: &str) -> bool {
        match (&self.name, &self.pattern) {
            (Some(n), _) => n == name,
            (None, Some(p)) => glob::Pattern::new(p).is_ok_and(|p| p.matches(name)),
            (None, None) => false,
        }
    }
}

/// Structure numbers have at most this many characters (NBI item 8).
const STRUCTURE_NUMBER_CHARS: usize = 15;

impl RecordConfig {
    /// Refuse a setting that cannot work.
    pub fn check(&self) -> Result<(), InvalidSetting> {
        InvalidSetting::check(
            self.cell_m.is_finite() && (0.05..=10.0).contains(&self.cell_m),
            keys::cell_m,
            self.cell_m,
            "0.05 to 10 metres",
        )?;
        InvalidSetting::check(
            (0.0..=100.0).contains(&self.min_inspected_pct),
            keys::min_inspected_pct,
            self.min_inspected_pct,
            "0 to 100 percent",
        )?;
        if let Some(number) = &self.structure_number {
            InvalidSetting::check(
                !number.is_empty()
                    && number.chars().count() <= STRUCTURE_NUMBER_CHARS
                    && number.chars().all(|c| c.is_ascii_graphic() || c == ' '),
                keys::structure_number,
                format!("{number:?}"),
                "1 to 15 printable ASCII characters",
            )?;
        }
        if let Some(code) = &self.state_code {
            InvalidSetting::check(
                code.len() == 2 && code.chars().all(|c| c.is_ascii_digit()),
                keys::state_code,
                format!("{code:?}"),
                "two digits (the state's FIPS code, e.g. \"06\")",
            )?;
        }
        for choice in &self.element {
            self.check_choice(choice)?;
        }
        Ok(())
    }

    fn check_choice(&self, choice: &ElementChoice) -> Result<(), InvalidSetting> {
        let shown = || {
            let by = choice
                .name
                .as_deref()
                .map(|n| format!("name = {n:?}"))
                .or_else(|| {
                    choice
                        .pattern
                        .as_deref()
                        .map(|p| format!("pattern = {p:?}"))
                })
                .unwrap_or_else(|| "no name or pattern".into());
            format!("{{{by}, number = {}}}", choice.number)
        };
        InvalidSetting::check(
            choice.name.is_some() != choice.pattern.is_some(),
            keys::element,
            shown(),
            "a table with a name or a pattern (one of the two)",
        )?;
        if let Some(p) = &choice.pattern {
            InvalidSetting::check(
                glob::Pattern::new(p).is_ok(),
                keys::element,
                shown(),
                "a pattern of the shell's form (`girder *`, `pier ?`)",
            )?;
        }
        InvalidSetting::check(
            element_numbered(choice.number).is_some(),
            keys::element,
            shown(),
            &format!(
                "an element number postflight records ({})",
                catalogue::numbers()
            ),
        )?;
        if let Some(q) = choice.quantity {
            InvalidSetting::check(
                q.is_finite() && q > 0.0,
                keys::element,
                format!("{} with quantity = {q}", shown()),
                "a quantity above 0",
            )?;
        }
        Ok(())
    }

    /// The owner's choice for element `name`: the first that names it.
    pub fn choice_for(&self, name: &str) -> Option<&ElementChoice> {
        self.element.iter().find(|c| c.names(name))
    }
}
