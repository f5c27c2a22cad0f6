//! The inspection plan the simulated flight was meant to fly: the
//! structure's voxels, and viewpoint loops around it at a standoff distance.

use std::collections::BTreeSet;

use ingest::map::{VoxelGrid, VoxelIndex};
use ingest::{InspectionPlan, Viewpoint};
use nalgebra::Point3;

use crate::scene::{Scene, area};

/// Distance from the structure's bounding box to the viewpoints, metres.
pub const STANDOFF: f64 = 3.5;
/// Spacing of viewpoints along a loop and between loops, metres.
const SPACING: f64 = 2.0;

/// Voxels (of `resolution`) holding any of the structure's surface.
pub fn target_voxels(scene: &Scene, grid: &VoxelGrid) -> Vec<VoxelIndex> {
    let step = grid.resolution / 4.0;
    let mut voxels = BTreeSet::new();
    for t in scene.infrastructure() {
        let [a, b, c] = scene.triangles[t as usize];
        let n = ((area(&[a, b, c]).sqrt() / step).ceil() as usize).max(2) * 2;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (s, r) = (i as f64 / n as f64, j as f64 / n as f64);
                voxels.insert(grid.voxel_of(&(a + (b - a) * s + (c - a) * r)));
            }
        }
    }
    voxels.into_iter().collect()
}

/// Loops of viewpoints around the structure's bounding box, bottom to top,
/// each facing the nearest side, with the camera's fixed pitch.
pub fn plan(scene: &Scene, resolution: f64, camera_pitch: f64) -> InspectionPlan {
    let grid = VoxelGrid::new(resolution, Point3::origin());
    let (lo, hi) = scene.infrastructure_bounds();
    let (x0, y0, x1, y1) = (
        lo.x - STANDOFF,
        lo.y - STANDOFF,
        hi.x + STANDOFF,
        hi.y + STANDOFF,
    );
    let mut viewpoints = Vec::new();
    let mut z = lo.z.max(0.0) + 1.5;
    let mut level = 0;
    while z <= hi.z + 1.0 {
        // Counter-clockwise around the box: south side facing north, and so on.
        let sides = [
            ((x0, y0), (x1, y0), std::f64::consts::FRAC_PI_2),
            ((x1, y0), (x1, y1), std::f64::consts::PI),
            ((x1, y1), (x0, y1), -std::f64::consts::FRAC_PI_2),
            ((x0, y1), (x0, y0), 0.0),
        ];
        let mut ring = Vec::new();
        for ((ax, ay), (bx, by), yaw) in sides {
            let len = (bx - ax).hypot(by - ay);
            let n = (len / SPACING).ceil() as usize;
            for k in 0..n {
                let s = k as f64 / n as f64;
                // At a corner, look diagonally at the structure.
                let yaw = if k == 0 {
                    yaw - std::f64::consts::FRAC_PI_4
                } else {
                    yaw
                };
                ring.push(Viewpoint {
                    position: [ax + (bx - ax) * s, ay + (by - ay) * s, z],
                    yaw,
                    gimbal_pitch: camera_pitch,
                });
            }
        }
        // Alternate direction per level so the path zig-zags up.
        if level % 2 == 1 {
            ring.reverse();
        }
        viewpoints.extend(ring);
        z += SPACING;
        level += 1;
    }
    InspectionPlan {
        frame_id: "map".into(),
        resolution,
        origin: [0.0; 3],
        target_voxels: target_voxels(scene, &grid),
        viewpoints,
        view: ingest::ViewModel::default(),
    }
}
