//! The inspection plan that was flown: the structure's target voxels and the
//! planned viewpoints, as written by the planner (`plan.json`).

use std::path::Path;

use nalgebra::Point3;
use serde::{Deserialize, Serialize};

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
    pub fn load(path: &Path) -> Result<Self, Error> {
        let error = |why: String| Error::Plan {
            path: path.to_owned(),
            why,
        };
        let text = std::fs::read_to_string(path)
            .map_err(|e| error(format!("{e}; check the path given to --plan")))?;
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
