//! What the record stage writes: the element record a bridge owner
//! submits. `elements.parquet` holds one row per element and one per
//! defect under it (metric quantities, states 1 to 4); `nbe.xml` and
//! `snbi-elements.json` are the same quantities as the FHWA's element
//! files want them; `record.json` says what the record rests on (the
//! edition of the manual, how much of each element the flight saw, what
//! was done with the rest) and whether the submission files were written.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// Files of the record stage.
pub mod files {
    pub const ELEMENTS: &str = "elements.parquet";
    /// The FHWA's element XML (flat `FHWAED` records).
    pub const NBE_XML: &str = "nbe.xml";
    /// The SNBI's element items (`BE01`-`BE03`, `BCS01`-`BCS04`).
    pub const SNBI_JSON: &str = "snbi-elements.json";
    pub const SUMMARY: &str = "record.json";
}

/// The edition of the AASHTO manual whose elements, defects and condition
/// states the record follows.
pub const MANUAL: &str = "AASHTO Manual for Bridge Element Inspection, 2nd edition (2019)";

crate::kind! {
    /// The unit an element is quantified in.
    pub enum Unit("unit") {
        /// Square metres of plan area (decks, slabs).
        SquareMetres = "m2",
        /// Metres along the element (girders, walls, caps, abutments).
        Metres = "m",
        /// Counted (columns).
        Each = "each",
    }
}

crate::kind! {
    /// What the record does with the part of an element the flight did not
    /// inspect (`[record] not_inspected`).
    pub enum NotInspectedRule("not-inspected rule") {
        /// The states of an earlier record (`--previous RUN`), in the shares
        /// that record gave each state, for the part this flight missed.
        Previous = "previous",
        /// Condition state 1, the common practice of counting what was not
        /// seen as no defect seen; flagged in every output.
        Cs1 = "cs1",
        /// No submission files while an element is under `[record]
        /// min_inspected_pct` inspected; an element at or over it counts its
        /// unseen part in the shares of the states its inspected part shows.
        Refuse = "refuse",
    }
}

crate::kind! {
    /// What the record does with a candidate no reviewer has decided
    /// (`[record] pending`).
    pub enum PendingRule("pending rule") {
        /// It counts as measured, and its rows say how many such there are.
        Count = "count",
        /// It does not count until a reviewer accepts it.
        Skip = "skip",
    }
}

crate::kind! {
    /// Where an element's total quantity came from.
    pub enum QuantitySource("quantity source") {
        /// Measured from the structure: the target voxels of the element.
        Structure = "structure",
        /// The owner's inventory (`[[record.element]] quantity`).
        Inventory = "inventory",
    }
}

crate::table! {
    /// One row of `elements.parquet`: an element, or a defect under it.
    /// Quantities are in the element's unit; `cs1`..`cs4` sum to `total`,
    /// and `inspected` plus `not_inspected` is `total`.
    #[derive(Serialize, Deserialize)]
    pub struct ElementRecord {
        /// The owner's structure number (NBI item 8, SNBI B.ID.01).
        structure_number: String,
        /// postflight's name of the element (`deck`, `pier west`).
        element: String,
        /// The AASHTO element number on an element row, the defect number on
        /// a defect row.
        number: u16,
        /// On a defect row, its element's number; none on an element row.
        parent: Option<u16>,
        /// The manual's name of the element or defect.
        name: String,
        unit: Unit,
        total: f64,
        /// Where `total` came from.
        quantity_source: QuantitySource,
        /// The part of the element the flight inspected.
        inspected: f64,
        not_inspected: f64,
        /// What was done with the part not inspected.
        not_inspected_rule: NotInspectedRule,
        cs1: f64,
        cs2: f64,
        cs3: f64,
        cs4: f64,
        /// The candidates counted in the row's states 2 to 4 (on an element
        /// row, those of all its defects), ids joined by `,`.
        candidates: String,
        /// Of those, how many no reviewer has decided yet.
        pending: u32,
    }
}

/// `record.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RecordSummary {
    pub run: PathBuf,
    /// The manual followed ([`MANUAL`]).
    pub manual: String,
    pub structure_number: String,
    /// The state's two-digit FIPS code, as the FHWA files name it.
    pub state_code: String,
    /// The side of the cells area elements are judged on, metres.
    pub cell_m: f64,
    pub not_inspected: NotInspectedRule,
    pub min_inspected_pct: f64,
    /// Whether candidates no reviewer has decided count.
    pub pending: PendingRule,
    /// The earlier run whose record the missed parts took, with
    /// `not_inspected = "previous"`.
    pub previous: Option<PathBuf>,
    /// Each element: how much of it was inspected.
    pub elements: Vec<ElementCoverage>,
    /// Candidates counted by what the reviewers decided.
    pub candidates: CandidateCounts,
    /// The submission files written, or why none was.
    pub submission: Submission,
    /// The settings it was made with, `{"record": ..., "condition": ...}`
    /// (`[record]` and `[condition]` resolved), so that the review queue
    /// remakes it alike as decisions are made.
    pub settings: serde_json::Value,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

/// How much of one element the record rests on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ElementCoverage {
    pub element: String,
    pub number: u16,
    pub unit: Unit,
    pub total: f64,
    pub inspected: f64,
    pub inspected_pct: f64,
}

/// The candidates the record weighed.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CandidateCounts {
    /// Accepted or needing repair.
    pub accepted: usize,
    /// Rejected: not counted.
    pub rejected: usize,
    /// Not decided yet (counted or not as `[record] pending` says).
    pub pending: usize,
    /// On no element with an AASHTO number: not counted.
    pub off_elements: usize,
    /// Counted candidates no view measured across, in no state until a
    /// reviewer gives one (or a gauge on site): their ids.
    pub unmeasured: Vec<String>,
}

/// Whether the files an owner submits were written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "state", rename_all = "snake_case")]
pub enum Submission {
    Written { files: Vec<String> },
    Refused { why: String },
}
