//! The inspection plan the simulated flight was meant to fly: the
//! structure's voxels, and a viewpoint in front of each patch of vertical
//! voxel faces at the standoff distance, ordered into a tour.
//!
//! The camera is fixed and pitched down (see `CAMERA_PITCH_DEG`), so faces
//! pointing up or down cannot be seen within the View model's incidence
//! limit: they are left to the coverage stage to report as uninspectable.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::{Point3, Vector3};
use postflight_core::map::{VoxelGrid, VoxelIndex};
use postflight_core::{InspectionPlan, ViewModel, Viewpoint};

use crate::scene::{Scene, area};

/// Distance from a face to its viewpoint by default, metres (mid View
/// distance band).
pub const STANDOFF: f64 = 3.5;
/// Viewpoints merge the faces of patches this wide, metres.
const PATCH: f64 = 1.0;
/// Closest a viewpoint may be to anything, metres.
const CLEARANCE: f64 = 1.0;

/// Voxels (of `grid`) holding any of the structure's surface.
pub fn target_voxels(scene: &Scene, grid: &VoxelGrid) -> Vec<VoxelIndex> {
    let step = grid.resolution / 4.0;
    let mut voxels = BTreeSet::new();
    for t in scene.infrastructure() {
        let [a, b, c] = scene.triangles[t as usize];
        let n = ((area(&[a, b, c]).sqrt() / step).ceil() as usize).max(2) * 2;
        for i in 0..=n {
            for j in 0..=(n - i) {
                let (s, r) = (i as f64 / n as f64, j as f64 / n as f64);
                // Just inside the surface, so the voxel is the structure's.
                let p = a + (b - a) * s + (c - a) * r - scene.normal(t) * 1e-4;
                voxels.insert(grid.voxel_of(&p));
            }
        }
    }
    voxels.into_iter().collect()
}

/// Whether a viewpoint is flyable: above ground, clear of everything, and
/// with a clear line of sight to the outside of the face it is for.
fn feasible(scene: &Scene, p: &Point3<f64>, face: &Point3<f64>) -> bool {
    if p.z < CLEARANCE {
        return false;
    }
    let directions = [
        Vector3::x(),
        -Vector3::x(),
        Vector3::y(),
        -Vector3::y(),
        Vector3::z(),
        -Vector3::z(),
    ];
    if directions
        .iter()
        .any(|d| scene.cast(p, d, CLEARANCE).is_some())
    {
        return false;
    }
    let to_face = face - p;
    let dist = to_face.norm();
    let dir = to_face / dist;
    // The face must be seen from outside: a voxel face inside a closed
    // structure (a tower's hollow core) is seen from within its walls.
    scene
        .cast(p, &dir, dist + 1.0)
        .is_none_or(|h| h.distance > dist - 0.3 && scene.normal(h.triangle).dot(&dir) < 0.0)
}

/// A patch of faces: their common outward normal and their centres.
type Patch = (Vector3<f64>, Vec<Point3<f64>>);

/// The plan: viewpoints `standoff` metres in front of the structure's faces.
pub fn plan(scene: &Scene, resolution: f64, camera_pitch: f64, standoff: f64) -> InspectionPlan {
    let grid = VoxelGrid::new(resolution, Point3::origin());
    let targets = target_voxels(scene, &grid);
    let set: BTreeSet<VoxelIndex> = targets.iter().copied().collect();
    // Raise the viewpoint so the pitched optical axis meets the face.
    let rise = standoff * camera_pitch.tan();
    // Faces grouped by (side, plane, patch along the plane, patch in height).
    let mut patches: BTreeMap<(usize, i64, i64, i64), Patch> = BTreeMap::new();
    for v in &targets {
        for (k, d) in [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]]
            .iter()
            .enumerate()
        {
            if set.contains(&VoxelIndex([v.0[0] + d[0], v.0[1] + d[1], v.0[2] + d[2]])) {
                continue;
            }
            let n = Vector3::new(f64::from(d[0]), f64::from(d[1]), 0.0);
            let face = grid.center(*v) + n * (resolution / 2.0);
            let key = |x: f64| (x / PATCH).floor() as i64;
            let along = if d[0] != 0 { face.y } else { face.x };
            let depth = if d[0] != 0 { face.x } else { face.y };
            let entry = patches
                .entry((
                    k,
                    (depth / resolution).round() as i64,
                    key(along),
                    key(face.z),
                ))
                .or_insert((n, Vec::new()));
            entry.1.push(face);
        }
    }
    let mut viewpoints = Vec::new();
    for (n, faces) in patches.values() {
        let centre =
            Point3::from(faces.iter().map(|p| p.coords).sum::<Vector3<f64>>() / faces.len() as f64);
        let position = centre + n * standoff + Vector3::z() * rise;
        if feasible(scene, &position, &centre) {
            viewpoints.push(Viewpoint {
                position: [position.x, position.y, position.z],
                yaw: (-n.y).atan2(-n.x),
                gimbal_pitch: camera_pitch,
            });
        }
    }
    InspectionPlan {
        frame_id: "map".into(),
        resolution,
        origin: [0.0; 3],
        target_voxels: targets,
        viewpoints: tour(viewpoints),
        view: ViewModel::default(),
    }
}

/// Order viewpoints by nearest neighbour from the lowest south-west one
/// (the follow-up planner solves this properly as a GTSP).
fn tour(mut left: Vec<Viewpoint>) -> Vec<Viewpoint> {
    let key = |v: &Viewpoint| v.position[0] + v.position[1] + v.position[2];
    let Some(first) = (0..left.len()).min_by(|a, b| key(&left[*a]).total_cmp(&key(&left[*b])))
    else {
        return left;
    };
    let mut order = vec![left.swap_remove(first)];
    while !left.is_empty() {
        let here = Point3::from(order[order.len() - 1].position);
        let next = (0..left.len())
            .min_by(|a, b| {
                let da = (Point3::from(left[*a].position) - here).norm();
                let db = (Point3::from(left[*b].position) - here).norm();
                da.total_cmp(&db)
            })
            .expect("not empty");
        order.push(left.swap_remove(next));
    }
    order
}
