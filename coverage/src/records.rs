//! The stage's records: one per target voxel, folded from the per-face
//! results (written as `coverage.parquet`, see
//! `postflight_core::outputs::coverage`).

use postflight_core::map::{VoxelGrid, VoxelIndex};
use postflight_core::outputs::coverage::{BestView, NotInspected, VoxelRecord};
use postflight_core::structure::Place;

use crate::cover::FaceCover;
use crate::face::Face;

/// Per-voxel records from per-face results (faces are grouped by voxel, in
/// target order), with each target's place on the structure.
#[allow(clippy::too_many_arguments)]
pub fn voxel_records(
    grid: &VoxelGrid,
    targets: &[VoxelIndex],
    places: &[Place],
    faces: &[Face],
    need: &[u32],
    flown: &[FaceCover],
    planned: &[FaceCover],
    reachable: &[bool],
    has_plan: bool,
) -> Vec<VoxelRecord> {
    let mut records = Vec::with_capacity(targets.len());
    let mut i = 0;
    for (&voxel, place) in targets.iter().zip(places) {
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
            .min_by(|a, b| a.0.gsd_mm.total_cmp(&b.0.gsd_mm))
            .map(|(sight, shot)| BestView {
                distance_m: sight.distance_m,
                incidence_deg: sight.incidence_deg,
                gsd_mm: sight.gsd_mm,
                shot,
            });
        let uninspectable = !inspected && !reachable[range.clone()].iter().any(|r| *r);
        records.push(VoxelRecord {
            voxel,
            centre: grid.center(voxel).coords.into(),
            planned: has_plan.then(|| planned[range.clone()].iter().any(|c| c.miss.is_none())),
            inspected,
            uninspectable,
            faces_exposed: range.len() as u32,
            faces_inspected: got.iter().filter(|c| c.miss.is_none()).count() as u32,
            views: got.iter().map(|c| c.views).max().unwrap_or(0),
            views_required: need[range].iter().copied().min().unwrap_or(1),
            best,
            element: place.element.clone(),
            place: place.to_string(),
            reason: (!inspected).then(|| {
                got.iter()
                    .filter_map(|c| c.miss)
                    .max()
                    .map_or(NotInspected::NoExposedFace, NotInspected::Missed)
            }),
        });
    }
    records
}
