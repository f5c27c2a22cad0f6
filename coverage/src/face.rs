//! The surface elements coverage is counted on: the exposed faces of the
//! target voxels (faces not shared with another solid voxel), each with its
//! centre and outward normal.

use std::collections::HashSet;

use nalgebra::{Point3, Vector3};
use postflight_core::map::{FaceSide, VoxelGrid, VoxelIndex};

/// One exposed face of a target voxel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Face {
    pub voxel: VoxelIndex,
    pub side: FaceSide,
    /// Centre of the face, world frame, metres.
    pub centre: Point3<f64>,
    /// Outward unit normal.
    pub normal: Vector3<f64>,
}

impl Face {
    /// The face of `voxel` on `side`.
    pub fn new(grid: &VoxelGrid, voxel: VoxelIndex, side: FaceSide) -> Self {
        let normal = side.normal();
        Self {
            voxel,
            side,
            centre: grid.center(voxel) + normal * (grid.resolution / 2.0),
            normal,
        }
    }

    pub fn name(&self) -> &'static str {
        self.side.name()
    }
}

/// The exposed faces of `targets`: sides whose neighbour is not in `solid`.
pub fn exposed_faces(
    grid: &VoxelGrid,
    targets: &[VoxelIndex],
    solid: &HashSet<VoxelIndex>,
) -> Vec<Face> {
    targets
        .iter()
        .flat_map(|&v| {
            FaceSide::ALL
                .into_iter()
                .filter(move |side| !solid.contains(&side.neighbour(v)))
                .map(move |side| Face::new(grid, v, side))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_two_voxels_thick_exposes_only_its_outer_faces() {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let wall: Vec<VoxelIndex> = (0..3)
            .flat_map(|y| (0..2).map(move |x| VoxelIndex([x, y, 0])))
            .collect();
        let solid: HashSet<VoxelIndex> = wall.iter().copied().collect();
        let faces = exposed_faces(&grid, &wall, &solid);
        // 6 voxels: +-z on each (12), the x sides of each row (6), the y ends (4).
        assert_eq!(faces.len(), 22);
        let f = faces
            .iter()
            .find(|f| f.voxel == VoxelIndex([1, 0, 0]) && f.name() == "+x")
            .unwrap();
        assert_eq!(f.centre, Point3::new(1.0, 0.25, 0.25));
        assert_eq!(f.normal, Vector3::x());
        assert!(
            !faces
                .iter()
                .any(|f| f.voxel == VoxelIndex([0, 1, 0]) && f.name() == "+x")
        );
    }
}
