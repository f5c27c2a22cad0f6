//! The inspection plan that was flown: postflight's `plan.json` (the
//! structure's target voxels, the voxel grid and the planned viewpoints),
//! or a waypoint path of `X,Y,Z,Yaw` rows (GATSBI's), which holds only where
//! the vehicle went.

mod path_csv;

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

use crate::Intrinsics;
use crate::error::Error;
use crate::map::{VoxelGrid, VoxelIndex};

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

/// When a voxel face counts as inspected by a frame (the GATSBI View model,
/// with the Zhao et al. view count). Defaults are GATSBI's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ViewModel {
    /// Apex angle of the viewing cone around the optical axis, degrees.
    pub cone_apex_deg: f64,
    /// Distance band from the camera to the face centre, metres.
    pub min_distance_m: f64,
    pub max_distance_m: f64,
    /// Largest angle between the face normal and the direction to the camera, degrees.
    pub max_incidence_deg: f64,
    /// Largest motion blur streak of a usable frame, pixels.
    pub max_blur_px: f64,
    /// Coarsest ground sampling distance of a usable view, millimetres per pixel.
    pub max_gsd_mm: f64,
    /// Views a face needs to count as inspected.
    pub views_required: u32,
}

impl Default for ViewModel {
    fn default() -> Self {
        Self {
            cone_apex_deg: 20.0,
            min_distance_m: 2.0,
            max_distance_m: 5.0,
            max_incidence_deg: 60.0,
            max_blur_px: 3.0,
            max_gsd_mm: 6.0,
            views_required: 1,
        }
    }
}

impl ViewModel {
    /// The View model's GSD: a pixel's fronto-parallel footprint at
    /// `distance_m` through lens `k` (its finer axis), millimetres.
    pub fn gsd_mm(distance_m: f64, k: &Intrinsics) -> f64 {
        distance_m * 1000.0 / k.fx.min(k.fy)
    }
}

/// View model settings; unset ones keep the plan's (or the defaults).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ViewSettings {
    pub cone_apex_deg: Option<f64>,
    pub min_distance_m: Option<f64>,
    pub max_distance_m: Option<f64>,
    pub max_incidence_deg: Option<f64>,
    pub max_blur_px: Option<f64>,
    pub max_gsd_mm: Option<f64>,
    pub views_required: Option<u32>,
}

impl ViewSettings {
    /// `self` over `base`.
    pub fn apply(&self, base: ViewModel) -> ViewModel {
        ViewModel {
            cone_apex_deg: self.cone_apex_deg.unwrap_or(base.cone_apex_deg),
            min_distance_m: self.min_distance_m.unwrap_or(base.min_distance_m),
            max_distance_m: self.max_distance_m.unwrap_or(base.max_distance_m),
            max_incidence_deg: self.max_incidence_deg.unwrap_or(base.max_incidence_deg),
            max_blur_px: self.max_blur_px.unwrap_or(base.max_blur_px),
            max_gsd_mm: self.max_gsd_mm.unwrap_or(base.max_gsd_mm),
            views_required: self.views_required.unwrap_or(base.views_required),
        }
    }

    /// `self` where set, else `other`.
    pub fn or(&self, other: &Self) -> Self {
        Self {
            cone_apex_deg: self.cone_apex_deg.or(other.cone_apex_deg),
            min_distance_m: self.min_distance_m.or(other.min_distance_m),
            max_distance_m: self.max_distance_m.or(other.max_distance_m),
            max_incidence_deg: self.max_incidence_deg.or(other.max_incidence_deg),
            max_blur_px: self.max_blur_px.or(other.max_blur_px),
            max_gsd_mm: self.max_gsd_mm.or(other.max_gsd_mm),
            views_required: self.views_required.or(other.views_required),
        }
    }
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
#[derive(Debug, Clone, PartialEq)]
pub struct PlanFile {
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
    std::fs::read_to_string(path).map_err(|e| Error::Plan {
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
