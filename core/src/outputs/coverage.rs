//! What the coverage stage writes: `coverage.parquet` (one row per target
//! voxel, its coverage folded from its faces; columns flat, angles in
//! degrees, lengths in metres) and its summary `coverage.json`; with a plan
//! to check instead of the flight, the same two as `coverage-viewpoints.*`.

use std::collections::BTreeMap;
use std::path::PathBuf;

use polars::prelude::*;
use serde::{Deserialize, Serialize};

use super::{required, required3};
use crate::error::Error;
use crate::map::{VoxelGrid, VoxelIndex};
use crate::run_dir::RunDir;
use crate::structure::{ElementMap, Structure};
use crate::view::ViewModel;

/// Files of the coverage stage.
pub mod files {
    pub const TABLE: &str = "coverage.parquet";
    pub const SUMMARY: &str = "coverage.json";
    /// With `--viewpoints`: a plan checked before flying it.
    pub const VIEWPOINTS_TABLE: &str = "coverage-viewpoints.parquet";
    pub const VIEWPOINTS_SUMMARY: &str = "coverage-viewpoints.json";
}

/// Voxel counts by reason for not being inspected.
pub type ReasonCounts = BTreeMap<String, usize>;

/// `coverage.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CoverageSummary {
    pub run: PathBuf,
    /// `flight`, or the viewpoints file judged instead.
    pub shots: String,
    pub view: ViewModel,
    pub resolution_m: f64,
    /// World position of the corner of voxel `[0, 0, 0]`.
    pub grid_origin: [f64; 3],
    /// The map judged against: a file, or `None` for the flight's recorded map.
    pub map: Option<PathBuf>,
    pub targets: String,
    /// The targets' elements (coverage.parquet names each voxel's).
    pub structure: Structure,
    pub target_voxels: usize,
    pub planned_voxels: Option<usize>,
    pub inspected_voxels: usize,
    pub inspected_pct: f64,
    /// Of the planned voxels, the share inspected.
    pub planned_inspected_pct: Option<f64>,
    /// Planned voxels not inspected.
    pub planned_missed_voxels: Option<usize>,
    /// Target voxels not inspected that a follow-up flight could inspect.
    pub gap_voxels: usize,
    /// Target voxels no free standpoint can inspect under the View model.
    pub uninspectable_voxels: usize,
    pub exposed_faces: usize,
    pub inspected_faces: usize,
    pub face_area_coverage_pct: f64,
    /// Occupied map voxels that are not targets (GATSBI's V_O).
    pub obstacle_voxels: usize,
    /// Not-inspected voxels by the furthest rule any frame reached.
    pub reasons: ReasonCounts,
    pub shots_total: usize,
    pub shots_usable: usize,
    pub shots_blurred: usize,
    pub frames_without_pose: usize,
    pub frames_without_exposure: usize,
    pub faces_needing_more_views: usize,
    pub seconds: f64,
    pub warnings: Vec<String>,
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
    /// Why not inspected: the furthest rule of the View model a camera got
    /// to (`too_far`, `occluded`, ...), or `no_exposed_face`.
    pub reason: Option<String>,
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
    run.write_table(name, coverage_table(records, resolution))
}

/// Read a coverage table.
pub fn read_coverage(run: &RunDir, name: &str) -> Result<Vec<VoxelRecord>, Error> {
    run.read_table(name, coverage_from)
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
    let grid = VoxelGrid::new(summary.resolution_m, summary.grid_origin.into());
    ElementMap::new(summary.structure.clone(), grid, voxels)
}

/// GATSBI's classes of a target voxel: inspected or not.
fn class(r: &VoxelRecord) -> &'static str {
    if r.inspected { "V_BI" } else { "V_BN" }
}

fn coverage_table(records: &[VoxelRecord], resolution: f64) -> PolarsResult<DataFrame> {
    let r = records;
    let col_i = |name: &str, a: usize| {
        Column::new(
            name.into(),
            r.iter().map(|r| r.voxel.0[a]).collect::<Vec<i32>>(),
        )
    };
    let col_f = |name: &str, a: usize| {
        Column::new(
            name.into(),
            r.iter().map(|r| r.centre[a]).collect::<Vec<f64>>(),
        )
    };
    let best = |f: &dyn Fn(&BestView) -> f64| {
        r.iter()
            .map(|r| r.best.as_ref().map(f))
            .collect::<Vec<Option<f64>>>()
    };
    let area = resolution * resolution;
    let columns = vec![
        col_i("voxel_x", 0),
        col_i("voxel_y", 1),
        col_i("voxel_z", 2),
        col_f("x", 0),
        col_f("y", 1),
        col_f("z", 2),
        Column::new(
            "element".into(),
            r.iter().map(|r| r.element.as_str()).collect::<Vec<&str>>(),
        ),
        Column::new(
            "place".into(),
            r.iter().map(|r| r.place.as_str()).collect::<Vec<&str>>(),
        ),
        Column::new("class".into(), r.iter().map(class).collect::<Vec<&str>>()),
        Column::new(
            "planned".into(),
            r.iter().map(|r| r.planned).collect::<Vec<Option<bool>>>(),
        ),
        Column::new(
            "inspected".into(),
            r.iter().map(|r| r.inspected).collect::<Vec<bool>>(),
        ),
        Column::new(
            "uninspectable".into(),
            r.iter().map(|r| r.uninspectable).collect::<Vec<bool>>(),
        ),
        Column::new(
            "faces_exposed".into(),
            r.iter().map(|r| r.faces_exposed).collect::<Vec<u32>>(),
        ),
        Column::new(
            "faces_inspected".into(),
            r.iter().map(|r| r.faces_inspected).collect::<Vec<u32>>(),
        ),
        Column::new(
            "face_area_m2".into(),
            r.iter()
                .map(|r| f64::from(r.faces_exposed) * area)
                .collect::<Vec<f64>>(),
        ),
        Column::new(
            "inspected_area_m2".into(),
            r.iter()
                .map(|r| f64::from(r.faces_inspected) * area)
                .collect::<Vec<f64>>(),
        ),
        Column::new(
            "views".into(),
            r.iter().map(|r| r.views).collect::<Vec<u32>>(),
        ),
        Column::new(
            "views_required".into(),
            r.iter().map(|r| r.views_required).collect::<Vec<u32>>(),
        ),
        Column::new("best_distance_m".into(), best(&|s| s.distance_m)),
        Column::new("best_incidence_deg".into(), best(&|s| s.incidence_deg)),
        Column::new("best_gsd_mm".into(), best(&|s| s.gsd_mm)),
        Column::new(
            "best_frame".into(),
            r.iter()
                .map(|r| r.best.map(|b| b.shot))
                .collect::<Vec<Option<u32>>>(),
        ),
        Column::new(
            "reason".into(),
            r.iter()
                .map(|r| r.reason.as_deref())
                .collect::<Vec<Option<&str>>>(),
        ),
    ];
    DataFrame::new(r.len(), columns)
}

fn coverage_from(df: &DataFrame) -> PolarsResult<Vec<VoxelRecord>> {
    let i32s = |name: &str| df.column(name).and_then(|c| c.i32());
    let f64s = |name: &str| df.column(name).and_then(|c| c.f64());
    let u32s = |name: &str| df.column(name).and_then(|c| c.u32());
    let bools = |name: &str| df.column(name).and_then(|c| c.bool());
    let voxel = [i32s("voxel_x")?, i32s("voxel_y")?, i32s("voxel_z")?];
    let centre = [f64s("x")?, f64s("y")?, f64s("z")?];
    let (planned, inspected, uninspectable) = (
        bools("planned")?,
        bools("inspected")?,
        bools("uninspectable")?,
    );
    let (faces_exposed, faces_inspected) = (u32s("faces_exposed")?, u32s("faces_inspected")?);
    let (views, views_required) = (u32s("views")?, u32s("views_required")?);
    let (distance, incidence, gsd) = (
        f64s("best_distance_m")?,
        f64s("best_incidence_deg")?,
        f64s("best_gsd_mm")?,
    );
    let (shot, reason) = (u32s("best_frame")?, df.column("reason")?.str()?);
    let (element, place) = (df.column("element")?.str()?, df.column("place")?.str()?);
    (0..df.height())
        .map(|i| {
            Ok(VoxelRecord {
                voxel: VoxelIndex(required3(voxel, i)?),
                centre: required3(centre, i)?,
                planned: planned.get(i),
                inspected: required(inspected, i)?,
                uninspectable: required(uninspectable, i)?,
                faces_exposed: required(faces_exposed, i)?,
                faces_inspected: required(faces_inspected, i)?,
                views: required(views, i)?,
                views_required: required(views_required, i)?,
                best: match (distance.get(i), incidence.get(i), gsd.get(i), shot.get(i)) {
                    (Some(distance_m), Some(incidence_deg), Some(gsd_mm), Some(shot)) => {
                        Some(BestView {
                            distance_m,
                            incidence_deg,
                            gsd_mm,
                            shot,
                        })
                    }
                    _ => None,
                },
                element: required(element, i)?.to_string(),
                place: required(place, i)?.to_string(),
                reason: reason.get(i).map(str::to_string),
            })
        })
        .collect()
}
