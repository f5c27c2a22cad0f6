//! The inspection plan that was flown: postflight's `plan.json` (the
//! structure's target voxels, the voxel grid and the planned viewpoints),
//! or a waypoint path of `X,Y,Z,Yaw` rows (GATSBI's), which holds only where
//! the vehicle went.

pub mod path_csv;

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::map::{VoxelGrid, VoxelIndex};
use crate::view::ViewModel;

/// A planned camera viewpoint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Viewpoint {
    /// Position of the vehicle in the world frame, metres.
    pub position: [f64; 3],
    /// Heading about world z, radians (ROS: counter-clockwise from x).
    pub yaw: f64,
    /// Gimbal pitch, radians, positive looking down.
    pub gimbal_pitch: f64,
}

/// An inspection plan: which voxels must be seen, and from where.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InspectionPlan {
    /// World frame of positions, e.g. `map`.
    pub frame_id: String,
    /// Voxel edge, metres.
    pub resolution: f64,
    /// World position of the corner of voxel `[0, 0, 0]`.
    #[serde(default)]
    pub origin: [f64; 3],
    /// Voxels of the structure to inspect.
    pub target_voxels: Vec<VoxelIndex>,
    /// Viewpoints in flight order.
    pub viewpoints: Vec<Viewpoint>,
    /// The View model the plan was made for.
    #[serde(default)]
    pub view: ViewModel,
}

impl InspectionPlan {
    /// Read and check a `plan.json`.
    pub fn load(path: &Path) -> Result<Self, Error> {
        let error = |why: String| Error::Plan {
            path: path.to_owned(),
            why,
        };
        let text = read_plan(path)?;
        let plan: Self = serde_json::from_str(&text)
            .map_err(|e| error(format!("not a postflight plan: {e}")))?;
        // Also rejects NaN.
        if plan.resolution.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(error(
                "resolution must be a positive number of metres".into(),
            ));
        }
        if plan.target_voxels.is_empty() {
            return Err(error("the plan has no target voxels".into()));
        }
        Ok(plan)
    }

    pub fn grid(&self) -> VoxelGrid {
        VoxelGrid::new(self.resolution, Point3::from(self.origin))
    }
}

/// How the yaw column of a waypoint path is read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum YawUnit {
    /// Radians, as GATSBI writes them (and ROS measures yaw).
    #[default]
    Radians,
    Degrees,
}

/// A plan file as given on the command line (`--plan`, `--viewpoints`), and
/// how to read a waypoint path's yaw.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlanFile {
    /// Not serialised: settings fingerprints hash the file's contents.
    #[serde(skip)]
    pub path: PathBuf,
    pub yaw: YawUnit,
}

impl PlanFile {
    /// A file whose waypoint yaws, if any, are in radians.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            yaw: YawUnit::default(),
        }
    }

    /// Whether the file is a waypoint path (by its `.csv` extension).
    pub fn is_path(&self) -> bool {
        self.path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
    }

    /// Read the plan: a waypoint path if the file is a `.csv`, else `plan.json`.
    pub fn load(&self) -> Result<FlownPlan, Error> {
        if !self.is_path() {
            return InspectionPlan::load(&self.path).map(FlownPlan::Inspection);
        }
        let text = read_plan(&self.path)?;
        let path = path_csv::parse(&text, self.yaw).map_err(|why| Error::Plan {
            path: self.path.clone(),
            why,
        })?;
        Ok(FlownPlan::Path(path))
    }
}

/// A point of a waypoint path: where the vehicle was sent and its heading.
/// The camera is as mounted on the vehicle (a path names no gimbal pitch).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    /// Position in the world frame, metres.
    pub position: [f64; 3],
    /// Heading about world z, radians (ROS: counter-clockwise from x).
    pub yaw: f64,
    /// Camera pitch, radians, positive looking down, when the path gives
    /// it; else the camera is taken as mounted on the vehicle.
    pub gimbal_pitch: Option<f64>,
}

crate::kind! {
    /// What a point of a path is, as its `Point` column names it
    /// (`replan.csv` writes one; a path may have none).
    pub enum PointKind("point") {
        /// Where a sortie takes off and lands.
        Home = "home",
        /// On the collision-free path between waypoints.
        Transit = "transit",
        /// Where the vehicle hovers and the camera shoots.
        Waypoint = "waypoint",
    }
}

/// The plan that was flown, as the inspector has it.
#[derive(Debug, Clone, PartialEq)]
pub enum FlownPlan {
    /// postflight's plan: targets, grid, View model and viewpoints.
    Inspection(InspectionPlan),
    /// A waypoint path (`X,Y,Z,Yaw`): viewpoints only; the targets come
    /// from a targets file.
    Path(Vec<PathPoint>),
}

impl FlownPlan {
    /// The voxel grid the plan was made on (a path names none).
    pub fn grid(&self) -> Option<VoxelGrid> {
        match self {
            Self::Inspection(plan) => Some(plan.grid()),
            Self::Path(_) => None,
        }
    }

    /// The View model the plan was made for (a path names none).
    pub fn view(&self) -> Option<ViewModel> {
        match self {
            Self::Inspection(plan) => Some(plan.view),
            Self::Path(_) => None,
        }
    }

    /// The structure's voxels (a path names none).
    pub fn target_voxels(&self) -> Option<&[VoxelIndex]> {
        match self {
            Self::Inspection(plan) => Some(&plan.target_voxels),
            Self::Path(_) => None,
        }
    }

    /// The planned viewpoints in flight order; a path's with the camera
    /// pitched as mounted (`mount_pitch`, radians, positive down).
    pub fn viewpoints(&self, mount_pitch: f64) -> Vec<Viewpoint> {
        match self {
            Self::Inspection(plan) => plan.viewpoints.clone(),
            Self::Path(points) => points
                .iter()
                .map(|p| Viewpoint {
                    position: p.position,
                    yaw: p.yaw,
                    gimbal_pitch: p.gimbal_pitch.unwrap_or(mount_pitch),
                })
                .collect(),
        }
    }
}

fn read_plan(path: &Path) -> Result<String, Error> {
    crate::user_file::read_to_string(path).map_err(|e| Error::Plan {
        path: path.to_owned(),
        why: format!(
            "{e}; check the path given to {}",
            crate::setting::inputs::PLAN
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loads_and_validates() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("plan.json");
        std::fs::write(
            &path,
            r#"{"frame_id":"map","resolution":0.5,"target_voxels":[[1,2,3]],
               "viewpoints":[{"position":[0,0,5],"yaw":1.57,"gimbal_pitch":0.3}]}"#,
        )
        .unwrap();
        let plan = InspectionPlan::load(&path).unwrap();
        assert_eq!(plan.target_voxels, vec![VoxelIndex([1, 2, 3])]);
        assert_eq!(plan.grid().center(VoxelIndex([0, 0, 0])).x, 0.25);
        std::fs::write(
            &path,
            r#"{"frame_id":"map","resolution":0,"target_voxels":[[1,2,3]],"viewpoints":[]}"#,
        )
        .unwrap();
        let err = InspectionPlan::load(&path).unwrap_err().to_string();
        assert!(err.contains("resolution"), "{err}");
    }
}
