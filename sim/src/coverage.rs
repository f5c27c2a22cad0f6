//! True coverage: which faces of the structure's voxels the flight really
//! inspected under the plan's View model, judged with true camera poses and
//! the true mesh (not the voxel map), and what the plan would have inspected.

use std::collections::HashSet;

use nalgebra::{Isometry3, Point3, Vector3};
use postflight_core::map::{FaceSide, VoxelGrid, VoxelIndex};
use postflight_core::{Intrinsics, ViewModel};
use rayon::prelude::*;
use serde::Serialize;

use crate::scene::Scene;

/// A camera that looked: its optical frame in the world, and whether the
/// frame is usable (recorded and sharp enough).
pub struct View {
    pub camera: Isometry3<f64>,
    pub usable: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct FaceTruth {
    pub face: FaceSide,
    /// Usable frames of the flight that inspected the face.
    pub views: u32,
    /// Plan viewpoints that would have inspected it.
    pub planned_views: u32,
    /// Of those, viewpoints the flight skipped.
    pub skipped_views: u32,
}

#[derive(Debug, Clone, Serialize)]
pub struct VoxelTruth {
    pub voxel: VoxelIndex,
    pub inspected: bool,
    pub planned: bool,
    /// Not inspected, and the viewpoints the flight skipped would have: a
    /// gap the skipped segment left.
    pub skipped_gap: bool,
    /// Exposed faces (not shared with another target voxel).
    pub faces: Vec<FaceTruth>,
}

#[derive(Debug, Clone, Serialize)]
pub struct CoverageTruth {
    pub view: ViewModel,
    pub target_voxels: usize,
    pub inspected_voxels: usize,
    pub planned_voxels: usize,
    pub voxels: Vec<VoxelTruth>,
}

/// Whether `camera` inspects the face with centre `centre` and outward `normal`.
fn inspects(
    scene: &Scene,
    view: &ViewModel,
    k: &Intrinsics,
    camera: &Isometry3<f64>,
    centre: &Point3<f64>,
    normal: &Vector3<f64>,
    resolution: f64,
) -> bool {
    let origin = Point3::from(camera.translation.vector);
    let to_face = centre - origin;
    let dist = to_face.norm();
    if dist < view.min_distance_m
        || dist > view.max_distance_m
        || dist * 1000.0 / k.fx > view.max_gsd_mm
    {
        return false;
    }
    let dir = to_face / dist;
    let axis = camera.rotation * Vector3::z();
    if axis.dot(&dir).clamp(-1.0, 1.0).acos() > (view.cone_apex_deg / 2.0).to_radians() {
        return false;
    }
    if normal.dot(&-dir).clamp(-1.0, 1.0).acos() > view.max_incidence_deg.to_radians() {
        return false;
    }
    let Some(px) = k.project(&(camera.inverse() * centre).coords) else {
        return false;
    };
    if !k.contains(&px) {
        return false;
    }
    // The face centre sits on the voxel boundary, up to a voxel from the true
    // surface: anything hit well before it blocks the view.
    scene
        .cast(&origin, &dir, dist)
        .is_none_or(|h| h.distance > dist - resolution)
}

/// Coverage of the plan's target voxels by `flown` frames and `planned`
/// views (each flagged whether the flight skipped it).
pub fn coverage(
    scene: &Scene,
    grid: &VoxelGrid,
    targets: &[VoxelIndex],
    view: &ViewModel,
    k: &Intrinsics,
    flown: &[View],
    planned: &[(Isometry3<f64>, bool)],
) -> CoverageTruth {
    let skipped: Vec<Isometry3<f64>> = planned.iter().filter(|p| p.1).map(|p| p.0).collect();
    let planned: Vec<Isometry3<f64>> = planned.iter().map(|p| p.0).collect();
    let set: HashSet<VoxelIndex> = targets.iter().copied().collect();
    let usable: Vec<&Isometry3<f64>> = flown
        .iter()
        .filter(|v| v.usable)
        .map(|v| &v.camera)
        .collect();
    let voxels: Vec<VoxelTruth> = targets
        .par_iter()
        .map(|&v| {
            let faces: Vec<FaceTruth> = FaceSide::ALL
                .into_iter()
                .filter(|side| !set.contains(&side.neighbour(v)))
                .map(|side| {
                    let normal = side.normal();
                    let centre = grid.center(v) + normal * (grid.resolution / 2.0);
                    let count = |cams: &mut dyn Iterator<Item = &Isometry3<f64>>| {
                        cams.filter(|c| {
                            inspects(scene, view, k, c, &centre, &normal, grid.resolution)
                        })
                        .count() as u32
                    };
                    FaceTruth {
                        face: side,
                        views: count(&mut usable.iter().copied()),
                        planned_views: count(&mut planned.iter()),
                        skipped_views: count(&mut skipped.iter()),
                    }
                })
                .collect();
            let need = view.views_required.max(1);
            let inspected = faces.iter().any(|f| f.views >= need);
            VoxelTruth {
                voxel: v,
                inspected,
                planned: faces.iter().any(|f| f.planned_views >= need),
                skipped_gap: !inspected && faces.iter().any(|f| f.skipped_views >= need),
                faces,
            }
        })
        .collect();
    CoverageTruth {
        view: *view,
        target_voxels: voxels.len(),
        inspected_voxels: voxels.iter().filter(|v| v.inspected).count(),
        planned_voxels: voxels.iter().filter(|v| v.planned).count(),
        voxels,
    }
}
