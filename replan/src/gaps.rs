//! The voxels a follow-up flight goes back for: coverage's gaps as the
//! `gaps` setting chooses them, and the voxels of candidates flagged for a
//! re-shoot, each with the views it needs.

use std::collections::HashMap;

use postflight_core::RunDir;
use postflight_core::map::VoxelIndex;
use postflight_core::outputs::coverage as coverage_outputs;
use postflight_core::outputs::localise::{self as localise_outputs, read_defects};
use postflight_core::outputs::replan::{GapChoice, ReshootSpot};

use crate::error::ReplanError;

/// The voxels a follow-up flight goes back for.
pub(crate) struct ChosenGaps {
    /// Every target voxel (from `coverage.parquet`).
    pub(crate) targets: Vec<VoxelIndex>,
    /// Gap voxels coverage found (not inspected, not uninspectable).
    pub(crate) coverage_gaps: usize,
    /// The chosen gaps and the re-shoot spots' voxels, sorted, once each.
    pub(crate) voxels: Vec<VoxelIndex>,
    /// The views each of them needs (coverage's `views_required`: its View
    /// model's, or its focus region's, or more near a defect).
    pub(crate) views: Vec<u32>,
    pub(crate) reshoot: Vec<ReshootSpot>,
}

/// The gaps `choice` asks for, from `coverage.parquet`, with the voxels of
/// the candidates `defects.json` flags for a re-shoot.
pub(crate) fn choose_gaps(run: &RunDir, choice: GapChoice) -> Result<ChosenGaps, ReplanError> {
    let records = coverage_outputs::read_coverage(run, coverage_outputs::files::TABLE)?;
    let targets: Vec<VoxelIndex> = records.iter().map(|r| r.voxel).collect();
    let gaps = || records.iter().filter(|r| !r.inspected && !r.uninspectable);
    let coverage_gaps = gaps().count();
    let mut voxels: Vec<VoxelIndex> = match choice {
        // Without a plan nothing says what was planned: every gap was missed.
        GapChoice::Missed => gaps()
            .filter(|r| r.planned.unwrap_or(true))
            .map(|r| r.voxel)
            .collect(),
        GapChoice::All => gaps().map(|r| r.voxel).collect(),
        GapChoice::Reshoot => Vec::new(),
    };
    let reshoot: Vec<ReshootSpot> = if run.file(localise_outputs::files::DEFECTS_JSON).exists() {
        read_defects(run)?
            .into_iter()
            .filter(|d| d.evidence.reshoot)
            .map(|d| ReshootSpot {
                defect: d.id,
                voxel: VoxelIndex(d.voxel),
            })
            .collect()
    } else {
        Vec::new()
    };
    voxels.extend(reshoot.iter().map(|r| r.voxel));
    voxels.sort_unstable();
    voxels.dedup();
    let required: HashMap<VoxelIndex, u32> = records
        .iter()
        .map(|r| (r.voxel, r.views_required))
        .collect();
    let views = voxels
        .iter()
        .map(|v| required.get(v).copied().unwrap_or(1).max(1))
        .collect();
    Ok(ChosenGaps {
        targets,
        coverage_gaps,
        voxels,
        views,
        reshoot,
    })
}
