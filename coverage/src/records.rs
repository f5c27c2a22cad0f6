//! The stage's output table: one record per target voxel, folded from the
//! per-face results, and `coverage.parquet`. Columns are flat, angles in
//! degrees, lengths in metres.

use ingest::map::{VoxelGrid, VoxelIndex};
use nalgebra::Point3;
use polars::prelude::*;

use crate::cover::FaceCover;
use crate::face::Face;
use crate::view::{Miss, Sight};

/// Everything judged about one target voxel.
pub struct VoxelRecord {
    pub voxel: VoxelIndex,
    pub centre: Point3<f64>,
    pub planned: Option<bool>,
    pub inspected: bool,
    pub uninspectable: bool,
    pub faces_exposed: u32,
    pub faces_inspected: u32,
    pub views: u32,
    pub views_required: u32,
    pub best: Option<(Sight, u32)>,
    /// Why not inspected: a [`Miss`] name, or `no_exposed_face`.
    pub reason: Option<&'static str>,
}

/// Per-voxel records from per-face results (faces are grouped by voxel, in
/// target order).
#[allow(clippy::too_many_arguments)]
pub fn voxel_records(
    grid: &VoxelGrid,
    targets: &[VoxelIndex],
    faces: &[Face],
    need: &[u32],
    flown: &[FaceCover],
    planned: &[FaceCover],
    reachable: &[bool],
    has_plan: bool,
) -> Vec<VoxelRecord> {
    let mut records = Vec::with_capacity(targets.len());
    let mut i = 0;
    for &voxel in targets {
        let start = i;
        while i < faces.len() && faces[i].voxel == voxel {
            i += 1;
        }
        let range = start..i;
        let got = &flown[range.clone()];
        let inspected = got.iter().any(|c| c.miss.is_none());
        let best = got
            .iter()
            .filter(|c| c.miss.is_none())
            .filter_map(|c| c.best)
            .min_by(|a, b| a.0.gsd_mm.total_cmp(&b.0.gsd_mm));
        let uninspectable = !inspected && !reachable[range.clone()].iter().any(|r| *r);
        records.push(VoxelRecord {
            voxel,
            centre: grid.center(voxel),
            planned: has_plan.then(|| planned[range.clone()].iter().any(|c| c.miss.is_none())),
            inspected,
            uninspectable,
            faces_exposed: range.len() as u32,
            faces_inspected: got.iter().filter(|c| c.miss.is_none()).count() as u32,
            views: got.iter().map(|c| c.views).max().unwrap_or(0),
            views_required: need[range].iter().copied().min().unwrap_or(1),
            best,
            reason: if inspected {
                None
            } else {
                Some(
                    got.iter()
                        .filter_map(|c| c.miss)
                        .max()
                        .map_or("no_exposed_face", Miss::as_str),
                )
            },
        });
    }
    records
}

/// GATSBI's classes of a target voxel: inspected or not.
fn class(r: &VoxelRecord) -> &'static str {
    if r.inspected { "V_BI" } else { "V_BN" }
}

pub fn coverage_table(records: &[VoxelRecord], resolution: f64) -> PolarsResult<DataFrame> {
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
    let best = |f: &dyn Fn(&Sight) -> f64| {
        r.iter()
            .map(|r| r.best.map(|(s, _)| f(&s)))
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
                .map(|r| r.best.map(|(_, id)| id))
                .collect::<Vec<Option<u32>>>(),
        ),
        Column::new(
            "reason".into(),
            r.iter().map(|r| r.reason).collect::<Vec<Option<&str>>>(),
        ),
    ];
    DataFrame::new(r.len(), columns)
}
