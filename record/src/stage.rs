//! The record stage: `postflight record --run RUN`. Reads the structure and
//! what was inspected of each element (coverage), the candidates
//! (localise) and the reviewers' decisions, and writes `elements.parquet`,
//! `nbe.xml`, `snbi-elements.json` and `record.json`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use postflight_core::condition::ConditionConfig;
use postflight_core::map::VoxelGrid;
use postflight_core::outputs::coverage::{
    CoverageSummary, element_map, files as coverage_files, read_coverage,
};
use postflight_core::outputs::localise::{DefectRecord, read_defects};
use postflight_core::outputs::record::{
    CandidateCounts, ElementCoverage, ElementRecord, MANUAL, NotInspectedRule, PendingRule,
    RecordSummary, Submission, files,
};
use postflight_core::structure::ElementMap;
use postflight_core::{RunDir, Stage};

use crate::cracks::{CountedCrack, Decisions, counted_cracks};
use crate::elements::{RecordedElement, recorded_elements};
use crate::error::RecordError;
use crate::quantities::{EarlierShares, ElementTally, Tally, fill_not_inspected, tally};
use crate::settings::RecordConfig;
use crate::submission::{nbe_xml, snbi};

/// What the record is made from besides the run directory. Serialised, it
/// is what the stage's result depends on (`postflight run`'s fingerprint):
/// the settings and the decisions, not the paths.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RecordOptions {
    #[serde(skip)]
    pub run: PathBuf,
    pub settings: RecordConfig,
    /// The crack-width limits (`[condition]`), for elements of its material.
    pub condition: ConditionConfig,
    /// The earlier run whose record fills what this flight missed.
    #[serde(skip)]
    pub previous: Option<PathBuf>,
    /// The reviewers' decisions so far.
    pub decisions: Decisions,
}

impl RecordOptions {
    /// The record of `run` with the default settings and no decision yet.
    pub fn new(run: PathBuf) -> Self {
        Self {
            run,
            settings: RecordConfig::default(),
            condition: ConditionConfig::default(),
            previous: None,
            decisions: Decisions::new(),
        }
    }
}

/// Make the record of a run.
pub fn record(options: &RecordOptions) -> Result<RecordSummary, RecordError> {
    let start = Instant::now();
    options.settings.check()?;
    options.condition.check()?;
    let run = RunDir::open(&options.run, Stage::Coverage)?;
    run.require(Stage::Localise)?;
    // From here on nothing of an earlier record stays to be taken for this one.
    for name in [
        files::SUMMARY,
        files::NBE_XML,
        files::SNBI_JSON,
        files::ELEMENTS,
    ] {
        run.remove(name)?;
    }
    let made = make(&run, options)?;
    run.write_rows(files::ELEMENTS, &made.rows)?;
    if let Submission::Written { .. } = made.submission {
        let s = &options.settings;
        let (state, number) = (
            s.state_code.as_deref().unwrap_or_default(),
            s.structure_number.as_deref().unwrap_or_default(),
        );
        run.write_text(files::NBE_XML, &nbe_xml(state, &made.rows))?;
        run.write_json(files::SNBI_JSON, &snbi(state, number, &made.rows))?;
    }
    let summary = summarise(options, made, start.elapsed().as_secs_f64());
    run.write_json(files::SUMMARY, &summary)?;
    Ok(summary)
}

/// `record.json` for the record `made` with `options`.
pub fn summarise(options: &RecordOptions, made: Made, seconds: f64) -> RecordSummary {
    let s = &options.settings;
    RecordSummary {
        run: options.run.clone(),
        manual: MANUAL.to_string(),
        structure_number: s.structure_number.clone().unwrap_or_default(),
        state_code: s.state_code.clone().unwrap_or_default(),
        cell_m: s.cell_m,
        not_inspected: s.not_inspected,
        min_inspected_pct: s.min_inspected_pct,
        pending: s.pending,
        previous: options.previous.clone(),
        elements: made.coverage,
        candidates: made.candidates,
        submission: made.submission,
        settings: serde_json::json!({ "record": s, "condition": options.condition }),
        seconds,
        warnings: made.warnings,
    }
}

impl RecordOptions {
    /// The options a record in `run` was made with (its `record.json`),
    /// with `decisions` instead of those it was made from.
    pub fn remade(
        run: PathBuf,
        summary: &RecordSummary,
        decisions: Decisions,
    ) -> Result<Self, RecordError> {
        let setting = |table: &str| summary.settings.get(table).cloned().unwrap_or_default();
        let unreadable = |e: serde_json::Error| RecordError::Unreadable {
            run: run.clone(),
            why: e.to_string(),
        };
        Ok(Self {
            settings: serde_json::from_value(setting("record")).map_err(unreadable)?,
            condition: serde_json::from_value(setting("condition")).map_err(unreadable)?,
            previous: summary.previous.clone(),
            decisions,
            run,
        })
    }
}

/// The record, before it is written.
pub struct Made {
    pub rows: Vec<ElementRecord>,
    pub coverage: Vec<ElementCoverage>,
    pub candidates: CandidateCounts,
    pub submission: Submission,
    pub warnings: Vec<String>,
}

/// The structure's elements as the record lays them out, read from the
/// run's coverage.
pub struct Layout {
    pub elements: Vec<RecordedElement>,
    /// Where points on the map are on the structure (coverage's elements).
    pub element_map: ElementMap,
    pub warnings: Vec<String>,
}

impl Layout {
    /// The candidates of `defects` the record counts on these elements,
    /// each in its state, and how many of each decision there were.
    pub fn counted_cracks(
        &self,
        defects: &[DefectRecord],
        decisions: &Decisions,
        pending: PendingRule,
        condition: &ConditionConfig,
    ) -> (Vec<CountedCrack>, CandidateCounts) {
        let cracking: BTreeMap<&str, _> = self
            .elements
            .iter()
            .map(|e| (e.name.as_str(), e.aashto.cracking))
            .collect();
        counted_cracks(defects, decisions, pending, condition, &|name| {
            cracking.get(name).copied()
        })
    }
}

/// The owner's elements of the run in `run`, laid out in cells.
pub fn lay_out(run: &RunDir, settings: &RecordConfig) -> Result<Layout, RecordError> {
    let summary: CoverageSummary = run.read_json(coverage_files::SUMMARY)?;
    let voxels = read_coverage(run, coverage_files::TABLE)?;
    let grid = VoxelGrid::new(summary.figures.resolution_m, summary.grid_origin.into());
    let mut warnings = Vec::new();
    let elements = recorded_elements(&summary.structure, &grid, &voxels, settings, &mut warnings);
    Ok(Layout {
        element_map: element_map(&summary, &voxels),
        elements,
        warnings,
    })
}

/// The record of the run in `run`, in memory: for the stage, and for the
/// review queue's view of it as decisions are made.
pub fn make(run: &RunDir, options: &RecordOptions) -> Result<Made, RecordError> {
    let s = &options.settings;
    // Phase: the owner's elements, laid out in cells.
    let layout = lay_out(run, s)?;
    // Phase: the cracks that count, each in its state.
    let (cracks, candidates) = layout.counted_cracks(
        &read_defects(run)?,
        &options.decisions,
        s.pending,
        &options.condition,
    );
    // Phase: each element's quantities, and what was not inspected.
    let earlier = match (&options.previous, s.not_inspected) {
        (Some(previous), _) => Some(earlier_record(previous)?),
        (None, NotInspectedRule::Previous) => return Err(RecordError::NoPrevious),
        (None, _) => None,
    };
    let mut rows = Vec::new();
    let mut coverage = Vec::new();
    for element in &layout.elements {
        let on: Vec<&CountedCrack> = cracks
            .iter()
            .filter(|c| c.element == element.name)
            .collect();
        let mut t = tally(element, &on);
        let shares = earlier.as_ref().and_then(|e| e.shares(element));
        if s.not_inspected == NotInspectedRule::Previous
            && shares.is_none()
            && t.element.not_inspected > 0.0
        {
            return Err(RecordError::PreviousLacks {
                run: options.previous.clone().unwrap_or_default(),
                element: element.name.clone(),
                number: element.aashto.number,
            });
        }
        fill_not_inspected(&mut t, s.not_inspected, shares);
        coverage.push(ElementCoverage {
            element: element.name.clone(),
            number: element.aashto.number,
            unit: element.aashto.unit,
            total: element.total,
            inspected: t.element.inspected,
            inspected_pct: percent(t.element.inspected, element.total),
        });
        rows.extend(element_rows(s, element, &t));
    }
    // Phase: whether the files an owner submits can be written.
    let submission = submission(s, &coverage);
    Ok(Made {
        rows,
        coverage,
        candidates,
        submission,
        warnings: layout.warnings,
    })
}

fn percent(part: f64, whole: f64) -> f64 {
    if whole > 0.0 {
        100.0 * part / whole
    } else {
        0.0
    }
}

/// The element's row and its defect's.
fn element_rows(s: &RecordConfig, e: &RecordedElement, t: &ElementTally) -> Vec<ElementRecord> {
    let row = |number: u16, parent: Option<u16>, name: &str, tally: &Tally| ElementRecord {
        structure_number: s.structure_number.clone().unwrap_or_default(),
        element: e.name.clone(),
        number,
        parent,
        name: name.to_string(),
        unit: e.aashto.unit,
        total: tally.total(),
        quantity_source: e.source,
        inspected: tally.inspected,
        not_inspected: tally.not_inspected,
        not_inspected_rule: s.not_inspected,
        cs1: tally.states[0],
        cs2: tally.states[1],
        cs3: tally.states[2],
        cs4: tally.states[3],
        candidates: tally
            .candidates
            .iter()
            .cloned()
            .collect::<Vec<_>>()
            .join(","),
        pending: tally.pending.len() as u32,
    };
    let mut rows = vec![row(e.aashto.number, None, e.aashto.name, &t.element)];
    if let Some(d) = &t.defect {
        let defect = e.aashto.cracking.defect();
        rows.push(row(defect.number, Some(e.aashto.number), defect.name, d));
    }
    rows
}

/// Written, unless the owner's numbers are missing or an element was seen
/// too little for the rule `refuse`.
fn submission(s: &RecordConfig, coverage: &[ElementCoverage]) -> Submission {
    let mut why = Vec::new();
    if s.structure_number.is_none() || s.state_code.is_none() {
        why.push(
            "the owner's numbers are not given: set [record] structure_number and state_code"
                .to_string(),
        );
    }
    if coverage.is_empty() {
        why.push("no element has an AASHTO number: give them in [[record.element]]".to_string());
    }
    if s.not_inspected == NotInspectedRule::Refuse {
        let fix =
            "fly the follow-up (replan.csv), or choose not_inspected = \"previous\" or \"cs1\"";
        // An element nothing was seen of shows nothing of what the rest is.
        let unseen: Vec<&str> = coverage
            .iter()
            .filter(|c| c.inspected <= 0.0)
            .map(|c| c.element.as_str())
            .collect();
        let under: Vec<String> = coverage
            .iter()
            .filter(|c| c.inspected > 0.0 && c.inspected_pct < s.min_inspected_pct)
            .map(|c| format!("{} {:.0}%", c.element, c.inspected_pct))
            .collect();
        if !under.is_empty() {
            why.push(format!(
                "inspected under [record] min_inspected_pct ({:.0}%): {}; {fix}",
                s.min_inspected_pct,
                under.join(", ")
            ));
        }
        if !unseen.is_empty() {
            why.push(format!("nothing inspected of {}; {fix}", unseen.join(", ")));
        }
    }
    if why.is_empty() {
        Submission::Written {
            files: vec![files::NBE_XML.to_string(), files::SNBI_JSON.to_string()],
        }
    } else {
        Submission::Refused {
            why: why.join("; "),
        }
    }
}

/// An earlier run's record, by element.
struct EarlierRecord {
    rows: Vec<ElementRecord>,
}

fn earlier_record(previous: &Path) -> Result<EarlierRecord, RecordError> {
    let run = RunDir::open(previous, Stage::Record)?;
    Ok(EarlierRecord {
        rows: run.read_rows(files::ELEMENTS)?,
    })
}

impl EarlierRecord {
    /// The shares of the element's total the earlier record put in each
    /// state, its own and its cracking defect's; `None` where it has no row
    /// for the element under the same number.
    fn shares(&self, e: &RecordedElement) -> Option<EarlierShares> {
        let own = self
            .rows
            .iter()
            .find(|r| r.element == e.name && r.number == e.aashto.number && r.parent.is_none())?;
        let defect_number = e.aashto.cracking.defect().number;
        let defect = self.rows.iter().find(|r| {
            r.element == e.name && r.number == defect_number && r.parent == Some(e.aashto.number)
        });
        let total = own.total;
        let share = |r: &ElementRecord| {
            [r.cs1, r.cs2, r.cs3, r.cs4].map(|q| if total > 0.0 { q / total } else { 0.0 })
        };
        Some(EarlierShares {
            element: share(own),
            defect: defect.map_or([0.0; 4], share),
        })
    }
}
