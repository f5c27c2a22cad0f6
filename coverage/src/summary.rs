//! What `coverage.json` says: the targets inspected, planned and missed,
//! why faces were missed, and the shots that counted.

use postflight_core::ViewModel;
use postflight_core::outputs::coverage::{
    CoverageFigures, CoverageSummary, ReasonCounts, VoxelRecord,
};

use crate::cover::FaceCover;
use crate::shots::FlightShots;
use crate::stage::{CoverageOptions, Scene};

/// What `coverage.json` says.
pub(crate) fn summarise(
    options: &CoverageOptions,
    view: ViewModel,
    scene: &Scene,
    counts: Counts,
    shots: &FlightShots,
    need: &[u32],
    seconds: f64,
) -> CoverageSummary {
    let n = scene.targets.len();
    let faces = scene.faces.len();
    let shots_blurred = shots
        .shots
        .iter()
        .filter(|s| view.blur_miss(s.blur_px).is_some())
        .count();
    CoverageSummary {
        run: options.run.clone(),
        shots: options
            .viewpoints
            .as_ref()
            .map_or("flight".into(), |p| p.path.display().to_string()),
        view,
        grid_origin: scene.grid.origin.coords.into(),
        map: options.map.clone(),
        targets: scene.targets_name.clone(),
        structure: scene.elements.structure.clone(),
        figures: CoverageFigures {
            resolution_m: scene.grid.resolution,
            target_voxels: n,
            planned_voxels: counts.planned,
            inspected_voxels: counts.inspected,
            inspected_pct: pct(counts.inspected, n),
            planned_inspected_pct: counts.planned.map(|p| pct(counts.planned_inspected, p)),
            planned_missed_voxels: counts.planned.map(|p| p - counts.planned_inspected),
            gap_voxels: n - counts.inspected - counts.uninspectable,
            uninspectable_voxels: counts.uninspectable,
            exposed_faces: faces,
            inspected_faces: counts.inspected_faces,
            // Every face of a voxel grid has the same area.
            face_area_coverage_pct: pct(counts.inspected_faces, faces),
            shots_total: shots.shots.len(),
            shots_usable: shots.shots.len() - shots_blurred,
        },
        obstacle_voxels: scene
            .map
            .voxels
            .voxels()
            .filter(|v| !scene.target_set.contains(v))
            .count(),
        reasons: counts.reasons,
        shots_blurred,
        frames_without_pose: shots.without_pose,
        frames_without_exposure: shots.without_exposure,
        faces_needing_more_views: need
            .iter()
            .filter(|n| **n > view.views_required.max(1))
            .count(),
        focus: Vec::new(),
        seconds,
        warnings: shots
            .warnings()
            .into_iter()
            .chain(scene.map.cloud.coarsened())
            .collect(),
    }
}

/// Voxel and face counts of the judged targets.
pub(crate) struct Counts {
    inspected: usize,
    planned: Option<usize>,
    planned_inspected: usize,
    uninspectable: usize,
    reasons: ReasonCounts,
    inspected_faces: usize,
}

impl Counts {
    pub(crate) fn of(records: &[VoxelRecord], flown: &[FaceCover], has_plan: bool) -> Self {
        let mut reasons = ReasonCounts::new();
        for r in records {
            if let Some(m) = r.reason {
                *reasons.entry(m).or_default() += 1;
            }
        }
        Self {
            inspected: records.iter().filter(|r| r.inspected).count(),
            planned: has_plan.then(|| records.iter().filter(|r| r.planned == Some(true)).count()),
            planned_inspected: records
                .iter()
                .filter(|r| r.planned == Some(true) && r.inspected)
                .count(),
            uninspectable: records.iter().filter(|r| r.uninspectable).count(),
            reasons,
            inspected_faces: flown.iter().filter(|c| c.miss.is_none()).count(),
        }
    }
}

/// `a` as a percentage of `b` (0 of nothing).
fn pct(a: usize, b: usize) -> f64 {
    if b == 0 {
        0.0
    } else {
        100.0 * a as f64 / b as f64
    }
}
