//! Errors of finding the structure, each naming the problem and the fix.

use std::path::PathBuf;

use postflight_core::setting::inputs;

#[derive(Debug, thiserror::Error)]
pub enum StructureError {
    #[error(transparent)]
    Run(#[from] postflight_core::Error),
    #[error("cannot read targets {}: {why}", path.display())]
    Targets { path: PathBuf, why: String },
    #[error(
        "no target voxels: pass the plan with {}, or the structure with {}, {} or {}",
        inputs::PLAN,
        inputs::TARGET_BOXES,
        inputs::TARGET_CLOUD,
        inputs::TARGET_MAP
    )]
    NoTargets,
    #[error(
        "the plan is a waypoint path, which names no targets; pass the structure with {}, {} or {}",
        inputs::TARGET_BOXES,
        inputs::TARGET_CLOUD,
        inputs::TARGET_MAP
    )]
    PathWithoutTargets,
    #[error(
        "the targets ({targets}) hold no voxel of the map; check that they are in the map's world frame and metres"
    )]
    TargetsOffMap { targets: String },
    #[error(
        "the targets ({targets}) do not overlap the map: {mapped} of {total} target voxels hold map points (targets span {targets_span}, map spans {map_span}); check that both are in the same world frame and in metres"
    )]
    TargetsMissMap {
        targets: String,
        mapped: usize,
        total: usize,
        targets_span: String,
        map_span: String,
    },
}
