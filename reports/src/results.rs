//! What a run directory holds: each stage's summary and the tables the
//! reports draw from, read once. A stage that has not run is `None`, so a
//! report can be made at any point of the pipeline.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use postflight_core::outputs::changes::{ChangeKind, ChangeRecord, ChangesSummary, read_changes};
use postflight_core::outputs::coverage::{self, CoverageSummary, VoxelRecord};
use postflight_core::outputs::detect::DetectSummary;
use postflight_core::outputs::localise::{DefectRecord, LocaliseSummary, read_defects};
use postflight_core::outputs::record::{self, ElementRecord, RecordSummary};
use postflight_core::outputs::replan::ReplanSummary;
use postflight_core::outputs::report::CandidateRow;
use postflight_core::structure::{ElementMap, Place};
use postflight_core::{Flight, RunDir, RunLog, Stage};

use crate::error::ReportError;

/// Coverage status of a target voxel, as the report colours it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum VoxelStatus {
    Inspected,
    /// Planned and not inspected: the flight missed it.
    PlannedMissed,
    /// Not planned and not inspected, but a flight could inspect it.
    NotPlanned,
    /// No free standpoint can inspect it under the View model.
    Uninspectable,
}

impl VoxelStatus {
    pub const ALL: [Self; 4] = [
        Self::Inspected,
        Self::PlannedMissed,
        Self::NotPlanned,
        Self::Uninspectable,
    ];

    /// A name for files and entity paths.
    pub fn key(self) -> &'static str {
        match self {
            Self::Inspected => "inspected",
            Self::PlannedMissed => "planned_missed",
            Self::NotPlanned => "not_planned",
            Self::Uninspectable => "uninspectable",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Self::Inspected => "inspected",
            Self::PlannedMissed => "planned, missed",
            Self::NotPlanned => "not planned, not inspected",
            Self::Uninspectable => "uninspectable",
        }
    }
}

/// One target voxel of `coverage.parquet`, as the reports colour it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetVoxel {
    pub index: [i32; 3],
    /// Centre, world frame, metres.
    pub centre: [f64; 3],
    pub status: VoxelStatus,
}

impl TargetVoxel {
    pub fn of(r: &VoxelRecord) -> Self {
        Self {
            index: r.voxel.0,
            centre: r.centre,
            status: if r.inspected {
                VoxelStatus::Inspected
            } else if r.uninspectable {
                VoxelStatus::Uninspectable
            } else if r.planned == Some(true) {
                VoxelStatus::PlannedMissed
            } else {
                VoxelStatus::NotPlanned
            },
        }
    }
}

/// Everything the stages of one run wrote.
pub struct RunResults {
    /// The ingested flight (its summary, frames, cameras, trajectory and
    /// recording) and the run directory.
    pub flight: Flight,
    pub detect: Option<DetectSummary>,
    pub localise: Option<LocaliseSummary>,
    /// Defect candidates, in the order localise wrote them.
    pub defects: Vec<DefectRecord>,
    pub coverage: Option<CoverageSummary>,
    pub voxels: Vec<TargetVoxel>,
    /// The structure's elements, to name places by (from coverage).
    pub elements: Option<ElementMap>,
    /// Surface area by element and coverage status, in element order.
    pub element_areas: Vec<ElementArea>,
    pub replan: Option<ReplanSummary>,
    /// What changed since an earlier inspection (`postflight compare`).
    pub changes: Option<ChangesSummary>,
    /// The earlier run's candidates, by id (empty when it cannot be read).
    pub earlier: HashMap<String, DefectRecord>,
    /// The element record (`postflight record`) and its rows.
    pub record: Option<(RecordSummary, Vec<ElementRecord>)>,
    pub log: RunLog,
}

/// The element record, where the record stage completed.
fn read_record(dir: &RunDir) -> Result<Option<(RecordSummary, Vec<ElementRecord>)>, ReportError> {
    let Some(summary) = dir.summary::<RecordSummary>(Stage::Record)? else {
        return Ok(None);
    };
    let rows = dir.read_rows(record::files::ELEMENTS)?;
    Ok(Some((summary, rows)))
}

impl RunResults {
    /// Read the run directory at `path` (ingest must have completed).
    pub fn read(path: &Path) -> Result<Self, ReportError> {
        let flight = Flight::load(path)?;
        let dir = &flight.run;
        // A stage's other files count only once its summary says it completed.
        let localise: Option<LocaliseSummary> = dir.summary(Stage::Localise)?;
        let defects = match localise {
            Some(_) => read_defects(dir)?,
            None => Vec::new(),
        };
        let coverage: Option<CoverageSummary> = dir.summary(Stage::Coverage)?;
        let records = match coverage {
            Some(_) => coverage::read_coverage(dir, coverage::files::TABLE)?,
            None => Vec::new(),
        };
        let voxels = records.iter().map(TargetVoxel::of).collect();
        let elements = coverage
            .as_ref()
            .map(|c| coverage::element_map(c, &records));
        let changes = read_changes(dir)?;
        Ok(Self {
            detect: dir.summary(Stage::Detect)?,
            localise,
            defects,
            element_areas: coverage
                .as_ref()
                .map(|c| ElementArea::of(c, &records))
                .unwrap_or_default(),
            coverage,
            voxels,
            elements,
            replan: dir.summary(Stage::Replan)?,
            earlier: changes.as_ref().map(earlier_candidates).unwrap_or_default(),
            changes,
            record: read_record(dir)?,
            log: RunLog::read(dir)?,
            flight,
        })
    }

    /// A candidate's change since the earlier inspection.
    pub fn change_of(&self, id: &str) -> Option<&ChangeRecord> {
        let changes = &self.changes.as_ref()?.changes;
        changes.iter().find(|c| c.after.as_deref() == Some(id))
    }

    /// A JPEG of the earlier run's candidate `id` (its best view).
    pub fn earlier_crop(&self, id: &str) -> Option<Vec<u8>> {
        let crop = self.earlier.get(id)?.crop.as_ref()?;
        std::fs::read(self.changes.as_ref()?.before.join(crop)).ok()
    }

    /// The run directory.
    pub fn dir(&self) -> &RunDir {
        &self.flight.run
    }

    /// A file of the run directory.
    pub fn file(&self, name: &str) -> PathBuf {
        self.dir().file(name)
    }

    /// Defect candidates in review order: the likeliest and largest first
    /// (fused confidence times length, cracks of unknown length counted 5 cm).
    pub fn defects_for_review(&self) -> Vec<&DefectRecord> {
        self.review_order()
            .into_iter()
            .map(|i| &self.defects[i])
            .collect()
    }

    /// The same order as indices into `defects`: after a comparison with
    /// an earlier inspection, cracks whose change stands out first (new,
    /// first seen, grown, widened).
    pub fn review_order(&self) -> Vec<usize> {
        let d = &self.defects;
        // `false` (new or grown) sorts first.
        let older: Vec<bool> = d
            .iter()
            .map(|d| {
                let change = self.change_of(&d.id).map(|c| c.change);
                !change.is_some_and(ChangeKind::stands_out)
            })
            .collect();
        let mut order: Vec<usize> = (0..d.len()).collect();
        order.sort_by(|&a, &b| {
            older[a]
                .cmp(&older[b])
                .then_with(|| review_priority(&d[b]).total_cmp(&review_priority(&d[a])))
                .then_with(|| d[a].id.cmp(&d[b].id))
        });
        order
    }

    /// The recordings whose frames show a candidate (their places in
    /// `ingest.json`'s `recordings`), in order.
    pub fn recordings_of(&self, d: &DefectRecord) -> Vec<u16> {
        let frames = d.views.iter().filter_map(|v| self.flight.frame(v.frame));
        let seen: std::collections::BTreeSet<u16> = frames.map(|f| f.recording).collect();
        seen.into_iter().collect()
    }

    /// The names of the recordings that saw a candidate, comma-separated.
    pub fn recording_names_of(&self, d: &DefectRecord) -> String {
        let recordings = &self.flight.summary.recordings;
        let names: Vec<String> = self
            .recordings_of(d)
            .into_iter()
            .filter_map(|i| recordings.get(usize::from(i)).map(|r| r.name()))
            .collect();
        names.join(", ")
    }

    /// The recordings that saw each candidate ([`Self::recording_names_of`]),
    /// by id; empty for a flight of one recording.
    pub fn seen_in(&self) -> HashMap<String, String> {
        if self.flight.summary.recordings.len() < 2 {
            return HashMap::new();
        }
        let names = self
            .defects
            .iter()
            .map(|d| (d.id.clone(), self.recording_names_of(d)));
        names.collect()
    }

    /// Where a candidate is on the structure; `None` before coverage has
    /// found the structure's elements, or off them.
    pub fn place(&self, d: &DefectRecord) -> Option<Place> {
        self.elements
            .as_ref()?
            .place(&d.position.into(), &d.normal.into())
    }

    /// Every candidate's place as text, by id: as localise named it, else
    /// (runs localised before localise named places) as coverage's elements
    /// place it.
    pub fn places(&self) -> HashMap<String, String> {
        self.defects
            .iter()
            .filter_map(|d| {
                let place = d
                    .place
                    .clone()
                    .or_else(|| Some(self.place(d)?.to_string()))?;
                Some((d.id.clone(), place))
            })
            .collect()
    }

    /// Each element's cracks by condition state (elements named by
    /// localise, else placed by coverage's elements).
    pub fn element_cracks(&self) -> Vec<ElementCracks> {
        let order: Vec<String> = self
            .element_areas
            .iter()
            .map(|a| a.element.clone())
            .collect();
        let named = self.defects.iter().map(|d| {
            let element = d.element.clone().or_else(|| Some(self.place(d)?.element));
            (d, element)
        });
        ElementCracks::of(named, &order)
    }

    /// The candidates as `candidates.csv` lists them, in review order.
    pub fn candidate_rows(&self) -> Vec<CandidateRow> {
        self.defects_for_review()
            .into_iter()
            .enumerate()
            .map(|(i, d)| {
                let mut defect = d.clone();
                // Runs localised before localise named places: coverage's.
                if let (None, Some(place)) = (&defect.place, self.place(d)) {
                    defect.element = Some(place.element.clone());
                    defect.place = Some(place.to_string());
                }
                CandidateRow {
                    rank: i as u32 + 1,
                    review_priority: review_priority(d),
                    defect,
                }
            })
            .collect()
    }
}

/// One element's cracks: their length in each condition state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ElementCracks {
    /// The element's name; `None` for cracks on no element.
    pub element: Option<String>,
    pub cracks: usize,
    /// Length in condition states 1 to 4, metres.
    pub state_m: [f64; 4],
    /// Length of cracks whose width gave no state, metres.
    pub no_state_m: f64,
    /// Cracks of unknown length (counted, not in the metres).
    pub unmeasured: usize,
}

impl ElementCracks {
    /// The candidates' lengths by element (`element_of` names each one's)
    /// and state: elements in `order` first, then the rest by name, then
    /// cracks on no element.
    fn of<'a>(
        defects: impl IntoIterator<Item = (&'a DefectRecord, Option<String>)>,
        order: &[String],
    ) -> Vec<Self> {
        let mut by: Vec<Self> = Vec::new();
        for (d, element) in defects {
            let i = match by.iter().position(|e| e.element == element) {
                Some(i) => i,
                None => {
                    by.push(Self {
                        element,
                        ..Self::default()
                    });
                    by.len() - 1
                }
            };
            let e = &mut by[i];
            e.cracks += 1;
            match (d.length_m, d.state()) {
                (None, _) => e.unmeasured += 1,
                (Some(l), Some(state)) => e.state_m[usize::from(state.number() - 1)] += l,
                (Some(l), None) => e.no_state_m += l,
            }
        }
        let rank = |e: &Self| match &e.element {
            Some(name) => (
                0,
                order.iter().position(|o| o == name).unwrap_or(order.len()),
                name.clone(),
            ),
            None => (1, 0, String::new()),
        };
        by.sort_by_key(rank);
        by
    }
}

/// One element's exposed surface (voxel faces), square metres, by the
/// coverage status of its voxels.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ElementArea {
    pub element: String,
    pub target_m2: f64,
    pub inspected_m2: f64,
    /// Of voxels planned and missed.
    pub planned_missed_m2: f64,
    /// Of voxels neither planned nor inspected.
    pub not_planned_m2: f64,
    pub uninspectable_m2: f64,
}

impl ElementArea {
    fn of(c: &CoverageSummary, records: &[VoxelRecord]) -> Vec<Self> {
        let face = c.figures.resolution_m * c.figures.resolution_m;
        let mut areas: Vec<Self> = c
            .structure
            .elements
            .iter()
            .map(|e| Self {
                element: e.name.clone(),
                ..Self::default()
            })
            .collect();
        for r in records {
            let Some(a) = areas.iter_mut().find(|a| a.element == r.element) else {
                continue;
            };
            // Each voxel's exposed faces counted under its status, so the
            // columns add up to the surface, as the voxel counts do.
            let exposed = f64::from(r.faces_exposed) * face;
            a.target_m2 += exposed;
            *match TargetVoxel::of(r).status {
                VoxelStatus::Inspected => &mut a.inspected_m2,
                VoxelStatus::PlannedMissed => &mut a.planned_missed_m2,
                VoxelStatus::NotPlanned => &mut a.not_planned_m2,
                VoxelStatus::Uninspectable => &mut a.uninspectable_m2,
            } += exposed;
        }
        areas
    }
}

/// How urgently a candidate needs a reviewer's eye: its confidence times
/// its size. A candidate without a measured length counts at the diagonal
/// of its extent on the surface (what its boxes place), so an unmeasured
/// crack is not buried beneath every measured one.
pub fn review_priority(d: &DefectRecord) -> f64 {
    let size = d.length_m.unwrap_or_else(|| {
        let [lo, hi] = [d.extent_min, d.extent_max];
        (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt()
    });
    d.confidence * size.max(0.05)
}

/// The earlier run's candidates by id, read for their pictures; none when
/// that run has moved or is unreadable (the comparison's figures stand).
fn earlier_candidates(changes: &ChangesSummary) -> HashMap<String, DefectRecord> {
    let dir = RunDir::open(&changes.before, Stage::Localise);
    dir.and_then(|d| read_defects(&d))
        .map(|defects| defects.into_iter().map(|d| (d.id.clone(), d)).collect())
        .unwrap_or_default()
}
