//! Which voxels are the structure to inspect: the plan's target voxels, or
//! the map's occupied voxels inside axis-aligned boxes (the box filter the
//! GATSBI flights segmented their bridge with), or the voxels of a
//! separately segmented infrastructure cloud.

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use nalgebra::{Point3, Vector3};
use postflight_core::FlownPlan;
use postflight_core::map::{PointCloud, SlamMap, VoxelGrid, VoxelIndex, VoxelMap};
use serde::Deserialize;

use crate::error::StructureError;

/// Where the target voxels come from (serialised as which, not the file's
/// path: its contents are what `postflight run` fingerprints).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Targets {
    /// The plan's target voxels (needs a plan).
    Plan,
    /// Occupied map voxels inside axis-aligned boxes (JSON file).
    Boxes(#[serde(skip)] PathBuf),
    /// Voxels of a segmented infrastructure cloud or octomap (PLY, PCD, `.bt`, `.ot`).
    Cloud(#[serde(skip)] PathBuf),
}

impl Targets {
    /// The file the targets come from, unless they are the plan's.
    pub fn file(&self) -> Option<&Path> {
        match self {
            Self::Plan => None,
            Self::Boxes(path) | Self::Cloud(path) => Some(path),
        }
    }
}

/// The target voxels (deduplicated, in index order), where they came
/// from, and the element names named boxes give them.
#[derive(Debug, Clone)]
pub struct TargetVoxels {
    pub voxels: Vec<VoxelIndex>,
    /// Where they came from, for summaries and messages.
    pub name: String,
    pub labels: HashMap<VoxelIndex, String>,
}

/// Below this share of target voxels holding map points, the map is not
/// the targets' (another frame or unit).
const MIN_MAPPED_SHARE: f64 = 0.25;

impl TargetVoxels {
    /// The targets `source` names on `map`; an error when they miss it.
    pub fn load(
        source: &Targets,
        plan: Option<&FlownPlan>,
        map: &SlamMap,
    ) -> Result<Self, StructureError> {
        let mut labels = HashMap::new();
        let (voxels, name): (Vec<VoxelIndex>, String) = match source {
            Targets::Plan => (plan_targets(plan)?.to_vec(), "plan".into()),
            Targets::Boxes(path) => {
                let boxes = load_boxes(path)?;
                let inside = in_boxes(&map.voxels, &boxes);
                labels = self::labels(&map.voxels.grid, &inside, &boxes);
                (inside, format!("boxes {}", path.display()))
            }
            Targets::Cloud(path) => (
                of_cloud(&map.voxels.grid, &PointCloud::load(path)?),
                format!("cloud {}", path.display()),
            ),
        };
        let voxels: Vec<VoxelIndex> = voxels
            .into_iter()
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect();
        if voxels.is_empty() {
            return Err(StructureError::TargetsOffMap { targets: name });
        }
        let mapped = voxels
            .iter()
            .filter(|v| map.voxels.is_occupied(**v))
            .count();
        if (mapped as f64) < MIN_MAPPED_SHARE * voxels.len() as f64 {
            return Err(StructureError::TargetsMissMap {
                mapped,
                total: voxels.len(),
                targets_span: span(voxels.iter().map(|v| map.voxels.grid.center(*v))),
                map_span: span(map.cloud.points.iter().copied()),
                targets: name,
            });
        }
        Ok(Self {
            voxels,
            name,
            labels,
        })
    }
}

/// The plan's target voxels: an error without a plan, or for a waypoint
/// path (it names none).
pub fn plan_targets(plan: Option<&FlownPlan>) -> Result<&[VoxelIndex], StructureError> {
    plan.ok_or(StructureError::NoTargets)?
        .target_voxels()
        .ok_or(StructureError::PathWithoutTargets)
}

/// `[x, y, z]..[x, y, z]`, the bounding box of some points, for messages.
pub fn span(points: impl Iterator<Item = Point3<f64>>) -> String {
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for p in points {
        lo = lo.inf(&p.coords);
        hi = hi.sup(&p.coords);
    }
    format!(
        "[{:.1}, {:.1}, {:.1}]..[{:.1}, {:.1}, {:.1}]",
        lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
    )
}

/// An axis-aligned box in the world frame, metres; a named box's voxels are
/// the structure element it names ("pier P2").
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct AxisBox {
    pub min: [f64; 3],
    pub max: [f64; 3],
    #[serde(default)]
    pub name: Option<String>,
}

impl AxisBox {
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        (0..3).all(|a| p[a] >= self.min[a] && p[a] <= self.max[a])
    }
}

/// Read boxes from JSON: `[{"min": [x, y, z], "max": [x, y, z], "name": "pier 1"}, ...]`
/// (the name is optional).
pub fn load_boxes(path: &Path) -> Result<Vec<AxisBox>, StructureError> {
    let bad = |why: String| StructureError::Targets {
        path: path.to_owned(),
        why,
    };
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    let boxes: Vec<AxisBox> = serde_json::from_str(&text).map_err(|e| {
        bad(format!(
            "{e}; expected a JSON list of {{\"min\": [x, y, z], \"max\": [x, y, z]}} in metres"
        ))
    })?;
    if let Some(b) = boxes
        .iter()
        .find(|b| (0..3).any(|a| b.min[a].partial_cmp(&b.max[a]).is_none_or(|o| o.is_gt())))
    {
        return Err(bad(format!(
            "box {:?}..{:?} has a min above its max; give min then max corner",
            b.min, b.max
        )));
    }
    Ok(boxes)
}

/// Occupied voxels of `map` whose centre lies in one of `boxes`.
pub fn in_boxes(map: &VoxelMap, boxes: &[AxisBox]) -> Vec<VoxelIndex> {
    let set: BTreeSet<VoxelIndex> = map
        .voxels()
        .filter(|v| {
            let c = map.grid.center(*v);
            boxes.iter().any(|b| b.contains(&c))
        })
        .collect();
    set.into_iter().collect()
}

/// The element names the named boxes give their voxels (the first named
/// box holding a voxel's centre).
pub fn labels(
    grid: &VoxelGrid,
    targets: &[VoxelIndex],
    boxes: &[AxisBox],
) -> HashMap<VoxelIndex, String> {
    targets
        .iter()
        .filter_map(|v| {
            let c = grid.center(*v);
            boxes
                .iter()
                .find(|b| b.name.is_some() && b.contains(&c))
                .and_then(|b| b.name.clone())
                .map(|name| (*v, name))
        })
        .collect()
}

/// Voxels of `grid` holding points of a segmented infrastructure cloud.
pub fn of_cloud(grid: &VoxelGrid, cloud: &PointCloud) -> Vec<VoxelIndex> {
    let set: BTreeSet<VoxelIndex> = cloud.points.iter().map(|p| grid.voxel_of(p)).collect();
    set.into_iter().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_pick_the_occupied_voxels_inside_them() {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let points = [
            Point3::new(0.1, 0.1, 0.1),
            Point3::new(3.1, 0.1, 0.1),
            Point3::new(0.6, 0.1, 0.1),
        ];
        let map = VoxelMap::from_points(grid, &points, 1);
        let boxes = [AxisBox {
            min: [0.0, 0.0, 0.0],
            max: [1.0, 1.0, 1.0],
            name: None,
        }];
        assert_eq!(
            in_boxes(&map, &boxes),
            vec![VoxelIndex([0, 0, 0]), VoxelIndex([1, 0, 0])]
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("boxes.json");
        std::fs::write(&path, r#"[{"min": [0, 0, 0], "max": [1, 1, -1]}]"#).unwrap();
        let err = load_boxes(&path).unwrap_err().to_string();
        assert!(err.contains("min above its max"), "{err}");
    }
}
