//! What the coverage stage writes: `coverage.parquet` (one row per target
//! voxel, its coverage folded from its faces; columns flat, angles in
//! degrees, lengths in metres) and its summary `coverage.json`; with a plan
//! to check instead of the flight, the same two as `coverage-viewpoints.*`.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::map::{VoxelGrid, VoxelIndex};
use crate::region::FocusModel;
use crate::run_dir::RunDir;
use crate::structure::{ElementMap, Structure};
use crate::table::Named;
use crate::view::{Miss, ViewModel};

/// Files of the coverage stage.
pub mod files {
    pub const TABLE: &str = "coverage.parquet";
    pub const SUMMARY: &str = "coverage.json";
    /// With `--viewpoints`: a plan checked before flying it.
    pub const VIEWPOINTS_TABLE: &str = "coverage-viewpoints.parquet";
    pub const VIEWPOINTS_SUMMARY: &str = "coverage-viewpoints.json";
}

/// Voxel counts by reason for not being inspected.
pub type ReasonCounts = BTreeMap<NotInspected, usize>;

/// Why a target voxel was not inspected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum NotInspected {
    /// The furthest rule of the View model any camera got to on its faces.
    Missed(Miss),
    /// None of its faces is exposed (occupied voxels on every side).
    NoExposedFace,
}

impl NotInspected {
    /// Every View model miss, then no exposed face.
    const ALL: [Self; Miss::ALL.len() + 1] = {
        let mut all = [Self::NoExposedFace; Miss::ALL.len() + 1];
        let mut i = 0;
        while i < Miss::ALL.len() {
            all[i] = Self::Missed(Miss::ALL[i]);
            i += 1;
        }
        all
    };
}

impl Named for NotInspected {
    const ALL: &'static [Self] = &Self::ALL;
    fn name(self) -> &'static str {
        match self {
            Self::Missed(miss) => miss.as_str(),
            Self::NoExposedFace => "no_exposed_face",
        }
    }
}

crate::serde_by_name!(NotInspected, "reason");

/// `coverage.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CoverageSummary {
    pub run: PathBuf,
    /// `flight`, or the viewpoints file judged instead.
    pub shots: String,
    pub view: ViewModel,
    /// World position of the corner of voxel `[0, 0, 0]`.
    pub grid_origin: [f64; 3],
    /// The map judged against: a file, or `None` for the flight's recorded map.
    pub map: Option<PathBuf>,
    pub targets: String,
    /// The targets' elements (coverage.parquet names each voxel's).
    pub structure: Structure,
    /// How much was inspected.
    #[serde(flatten)]
    pub figures: CoverageFigures,
    /// Occupied map voxels that are not targets (GATSBI's V_O).
    pub obstacle_voxels: usize,
    /// Not-inspected voxels by the furthest rule any frame reached.
    pub reasons: ReasonCounts,
    pub shots_blurred: usize,
    pub frames_without_pose: usize,
    pub frames_without_exposure: usize,
    pub faces_needing_more_views: usize,
    /// The focus regions, each with its View model and its target voxels
    /// (those with their centre inside, judged under that model).
    #[serde(default)]
    pub focus: Vec<FocusCoverage>,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

crate::table! {
    /// How much a flight inspected: `coverage.json`'s figures, and a row of
    /// the fleet's `coverage.parquet` after its flight's columns.
    #[derive(Serialize, Deserialize)]
    pub struct CoverageFigures {
        resolution_m: f64,
        target_voxels: usize,
        planned_voxels: Option<usize>,
        inspected_voxels: usize,
        inspected_pct: f64,
        /// Of the planned voxels, the share inspected.
        planned_inspected_pct: Option<f64>,
        /// Planned voxels not inspected.
        planned_missed_voxels: Option<usize>,
        /// Target voxels not inspected that a follow-up flight could inspect.
        gap_voxels: usize,
        /// Target voxels no free standpoint can inspect under the View model.
        uninspectable_voxels: usize,
        exposed_faces: usize,
        inspected_faces: usize,
        face_area_coverage_pct: f64,
        shots_total: usize,
        shots_usable: usize,
    }
}

/// A focus region's View model, and its target voxels judged under it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FocusCoverage {
    #[serde(flatten)]
    pub model: FocusModel,
    pub target_voxels: usize,
    pub inspected_voxels: usize,
}

/// Everything judged about one target voxel.
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelRecord {
    pub voxel: VoxelIndex,
    /// Centre, world frame, metres.
    pub centre: [f64; 3],
    /// Inspected by the plan's viewpoints; `None` without a plan.
    pub planned: Option<bool>,
    pub inspected: bool,
    /// No free standpoint can inspect it under the View model.
    pub uninspectable: bool,
    pub faces_exposed: u32,
    pub faces_inspected: u32,
    /// Most views any of its faces had.
    pub views: u32,
    pub views_required: u32,
    /// Its finest inspecting view.
    pub best: Option<BestView>,
    /// The structure element it is part of (`pier 2`).
    pub element: String,
    /// Where it is: `pier 2, east face, 1.4 m above its base`.
    pub place: String,
    /// Why not inspected; `None` when inspected.
    pub reason: Option<NotInspected>,
}

/// The finest view of a voxel (by GSD).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BestView {
    pub distance_m: f64,
    pub incidence_deg: f64,
    /// The View model's GSD: fronto-parallel, distance over focal length.
    pub gsd_mm: f64,
    /// The frame (or plan viewpoint) it was taken from.
    pub shot: u32,
}

/// Write a coverage table (`name`: [`files::TABLE`] or
/// [`files::VIEWPOINTS_TABLE`]) of voxels `resolution` metres wide.
pub fn write_coverage(
    run: &RunDir,
    name: &str,
    records: &[VoxelRecord],
    resolution: f64,
) -> Result<(), Error> {
    let rows: Vec<VoxelRow> = records
        .iter()
        .map(|r| VoxelRow::of(r, resolution))
        .collect();
    run.write_rows(name, &rows)
}

/// Read a coverage table.
pub fn read_coverage(run: &RunDir, name: &str) -> Result<Vec<VoxelRecord>, Error> {
    let rows: Vec<VoxelRow> = run.read_rows(name)?;
    Ok(rows.into_iter().map(VoxelRow::record).collect())
}

/// The structure's elements as the coverage stage found them (its summary
/// and table), to name places by.
pub fn element_map(summary: &CoverageSummary, records: &[VoxelRecord]) -> ElementMap {
    let index: BTreeMap<&str, usize> = summary
        .structure
        .elements
        .iter()
        .enumerate()
        .map(|(i, e)| (e.name.as_str(), i))
        .collect();
    let voxels: Vec<(VoxelIndex, usize)> = records
        .iter()
        .filter_map(|r| index.get(r.element.as_str()).map(|&e| (r.voxel, e)))
        .collect();
    let grid = VoxelGrid::new(summary.figures.resolution_m, summary.grid_origin.into());
    ElementMap::new(summary.structure.clone(), grid, voxels)
}

crate::kind! {
    /// GATSBI's classes of a target voxel: inspected or not.
    pub enum VoxelClass("voxel class") {
        /// `V_BI`: inspected.
        Inspected = "V_BI",
        /// `V_BN`: not inspected.
        NotInspected = "V_BN",
    }
}

crate::table! {
    /// One row of a coverage table: a target voxel.
    pub struct VoxelRow {
        voxel_x: i32,
        voxel_y: i32,
        voxel_z: i32,
        /// Its centre, world frame, metres.
        x: f64,
        y: f64,
        z: f64,
        element: String,
        place: String,
        class: VoxelClass,
        planned: Option<bool>,
        inspected: bool,
        uninspectable: bool,
        faces_exposed: u32,
        faces_inspected: u32,
        /// Its exposed and inspected faces' area, square metres.
        face_area_m2: f64,
        inspected_area_m2: f64,
        views: u32,
        views_required: u32,
        best_distance_m: Option<f64>,
        best_incidence_deg: Option<f64>,
        /// The View model's GSD of its finest view.
        best_gsd_mm: Option<f64>,
        best_frame: Option<u32>,
        reason: Option<NotInspected>,
    }
}

impl VoxelRow {
    /// A voxel's row, its voxels `resolution` metres wide.
    fn of(r: &VoxelRecord, resolution: f64) -> Self {
        let [voxel_x, voxel_y, voxel_z] = r.voxel.0;
        let [x, y, z] = r.centre;
        let area = resolution * resolution;
        let best = r.best.as_ref();
        Self {
            voxel_x,
            voxel_y,
            voxel_z,
            x,
            y,
            z,
            element: r.element.clone(),
            place: r.place.clone(),
            class: if r.inspected {
                VoxelClass::Inspected
            } else {
                VoxelClass::NotInspected
            },
            planned: r.planned,
            inspected: r.inspected,
            uninspectable: r.uninspectable,
            faces_exposed: r.faces_exposed,
            faces_inspected: r.faces_inspected,
            face_area_m2: f64::from(r.faces_exposed) * area,
            inspected_area_m2: f64::from(r.faces_inspected) * area,
            views: r.views,
            views_required: r.views_required,
            best_distance_m: best.map(|b| b.distance_m),
            best_incidence_deg: best.map(|b| b.incidence_deg),
            best_gsd_mm: best.map(|b| b.gsd_mm),
            best_frame: best.map(|b| b.shot),
            reason: r.reason,
        }
    }

    fn record(self) -> VoxelRecord {
        let best = match (
            self.best_distance_m,
            self.best_incidence_deg,
            self.best_gsd_mm,
            self.best_frame,
        ) {
            (Some(distance_m), Some(incidence_deg), Some(gsd_mm), Some(shot)) => Some(BestView {
                distance_m,
                incidence_deg,
                gsd_mm,
                shot,
            }),
            _ => None,
        };
        VoxelRecord {
            voxel: VoxelIndex([self.voxel_x, self.voxel_y, self.voxel_z]),
            centre: [self.x, self.y, self.z],
            planned: self.planned,
            inspected: self.inspected,
            uninspectable: self.uninspectable,
            faces_exposed: self.faces_exposed,
            faces_inspected: self.faces_inspected,
            views: self.views,
            views_required: self.views_required,
            best,
            element: self.element,
            place: self.place,
            reason: self.reason,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_reason_has_its_own_name_and_reads_back() {
        let json = serde_json::to_string(&NotInspected::ALL).unwrap();
        assert!(json.starts_with(r#"["too_far","too_close","#), "{json}");
        assert!(
            json.ends_with(r#""too_few_views","no_exposed_face"]"#),
            "{json}"
        );
        let back: Vec<NotInspected> = serde_json::from_str(&json).unwrap();
        assert_eq!(back, NotInspected::ALL);
    }
}
