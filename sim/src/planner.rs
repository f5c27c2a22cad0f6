//! The inspection plan the simulated flight was meant to fly: the
//! structure's voxels, and a viewpoint in front of each patch of vertical
//! voxel faces at the standoff distance, ordered into a tour.
//!
//! The camera is fixed and pitched down (see `CAMERA_PITCH_DEG`), so faces
//! pointing up or down cannot be seen within the View model's incidence
//! limit: they are left to the coverage stage to report as uninspectable.
//! A gimballed camera ([`Mount::Gimbal`]) also gets a viewpoint above each
//! patch of faces pointing up (a deck's top), looking straight down.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::{Isometry3, Point3, Vector3};
use postflight_core::map::{VoxelGrid, VoxelIndex};
use postflight_core::{InspectionPlan, ViewModel, Viewpoint};

use crate::scene::{Scene, area};

/// Distance from a face to its viewpoint by default, metres (mid View
/// distance band).
pub const STANDOFF: f64 = 3.5;
/// Viewpoints merge the faces of patches this wide, metres.
const PATCH: f64 = 1.0;

/// How far apart viewpoints are on a face, metres: along it and across
/// it (in height for the sides).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spacing {
    pub along: f64,
    pub across: f64,
}

/// A survey's overlap of neighbouring photos, as `--overlap` takes it:
/// forward (along a face) and side (across it), shares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Overlap {
    pub forward: f64,
    pub side: f64,
}

impl Overlap {
    pub fn parse(s: &str) -> Result<Self, String> {
        match postflight_core::setting::comma_numbers(s).as_deref() {
            Some(&[forward, side])
                if (0.0..=0.95).contains(&forward) && (0.0..=0.95).contains(&side) =>
            {
                Ok(Self { forward, side })
            }
            _ => Err(format!(
                "expected two shares FORWARD,SIDE from 0 to 0.95 (as 0.8,0.7), not '{s}'"
            )),
        }
    }
}

impl Spacing {
    /// One viewpoint per square metre of face, as inspection plans have it.
    pub const PATCHES: Spacing = Spacing {
        along: PATCH,
        across: PATCH,
    };

    /// A photogrammetry survey's: neighbouring photos overlap by
    /// `overlap`, for a frame `footprint` metres (across, in height) at the
    /// standoff.
    pub fn survey(overlap: Overlap, footprint: (f64, f64)) -> Spacing {
        Spacing {
            along: footprint.0 * (1.0 - overlap.forward),
            across: footprint.1 * (1.0 - overlap.side),
        }
    }
}
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

/// How the camera is carried.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mount {
    /// Fixed to the body, pitched down this much (radians).
    Fixed { pitch: f64 },
    /// On a gimbal that holds `pitch` (radians down) for the sides and
    /// turns straight down over faces pointing up.
    Gimbal { pitch: f64 },
}

impl Mount {
    /// The pitch the sides are shot at, radians down.
    pub fn side_pitch(self) -> f64 {
        match self {
            Self::Fixed { pitch } | Self::Gimbal { pitch } => pitch,
        }
    }
}

/// Outward normals of the faces a viewpoint is planned for: the four sides,
/// and up where the gimbal can look straight down.
const SIDES: [[i32; 3]; 4] = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]];
const UP: [i32; 3] = [0, 0, 1];

/// The plan: viewpoints `standoff` metres in front of the structure's
/// faces, `spacing` apart.
pub fn plan(
    scene: &Scene,
    resolution: f64,
    mount: Mount,
    standoff: f64,
    spacing: Spacing,
) -> InspectionPlan {
    let grid = VoxelGrid::new(resolution, Point3::origin());
    let targets = target_voxels(scene, &grid);
    let mut viewpoints = Vec::new();
    for (n, faces) in patches(&grid, &targets, mount, spacing).values() {
        let centre =
            Point3::from(faces.iter().map(|p| p.coords).sum::<Vector3<f64>>() / faces.len() as f64);
        let viewpoint = if n.z > 0.5 {
            // Above the faces, looking straight down; heading along x.
            Viewpoint {
                position: (centre + n * standoff).coords.into(),
                yaw: 0.0,
                gimbal_pitch: std::f64::consts::FRAC_PI_2,
            }
        } else {
            // Raised so the pitched optical axis meets the face.
            let pitch = mount.side_pitch();
            let position = centre + n * standoff + Vector3::z() * (standoff * pitch.tan());
            Viewpoint {
                position: position.coords.into(),
                yaw: (-n.y).atan2(-n.x),
                gimbal_pitch: pitch,
            }
        };
        if feasible(scene, &Point3::from(viewpoint.position), &centre) {
            viewpoints.push(viewpoint);
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

/// `plan` flown again in another SLAM frame (`iso` takes the plan's frame
/// to it) over `scene` as that frame records it: the same viewpoints, as
/// a team re-flies a mission, and the targets voxelised in the new frame,
/// where the run's coverage counts them.
pub fn reflown(plan: InspectionPlan, iso: &Isometry3<f64>, scene: &Scene) -> InspectionPlan {
    let grid = VoxelGrid::new(plan.resolution, Point3::from(plan.origin));
    let turn = iso.rotation.euler_angles().2;
    let viewpoints = plan
        .viewpoints
        .iter()
        .map(|v| Viewpoint {
            position: (iso * Point3::from(v.position)).coords.into(),
            yaw: v.yaw + turn,
            gimbal_pitch: v.gimbal_pitch,
        })
        .collect();
    InspectionPlan {
        target_voxels: target_voxels(scene, &grid),
        viewpoints,
        ..plan
    }
}

/// The targets' exposed faces the mount can shoot face-on, grouped by
/// (direction, plane, patch along the plane, patch across it).
fn patches(
    grid: &VoxelGrid,
    targets: &[VoxelIndex],
    mount: Mount,
    spacing: Spacing,
) -> BTreeMap<(usize, i64, i64, i64), Patch> {
    let set: BTreeSet<VoxelIndex> = targets.iter().copied().collect();
    let directions: &[[i32; 3]] = match mount {
        Mount::Fixed { .. } => &SIDES,
        Mount::Gimbal { .. } => &[SIDES[0], SIDES[1], SIDES[2], SIDES[3], UP],
    };
    let key = |x: f64, step: f64| (x / step).floor() as i64;
    let mut patches: BTreeMap<(usize, i64, i64, i64), Patch> = BTreeMap::new();
    for v in targets {
        for (k, d) in directions.iter().enumerate() {
            if set.contains(&VoxelIndex([v.0[0] + d[0], v.0[1] + d[1], v.0[2] + d[2]])) {
                continue;
            }
            let n = Vector3::new(f64::from(d[0]), f64::from(d[1]), f64::from(d[2]));
            let face = grid.center(*v) + n * (grid.resolution / 2.0);
            // (plane, along, across): sides are patched along and in height,
            // tops in x and y.
            let (depth, along, across) = match d {
                [0, 0, _] => (face.z, face.x, face.y),
                [0, _, _] => (face.y, face.x, face.z),
                _ => (face.x, face.y, face.z),
            };
            patches
                .entry((
                    k,
                    (depth / grid.resolution).round() as i64,
                    key(along, spacing.along),
                    key(across, spacing.across),
                ))
                .or_insert((n, Vec::new()))
                .1
                .push(face);
        }
    }
    patches
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn a_gimbal_adds_viewpoints_looking_straight_down_at_the_deck() {
        let scene = Scene::girder_bridge();
        let pitch = 12f64.to_radians();
        let with = |mount| plan(&scene, 0.5, mount, STANDOFF, Spacing::PATCHES);
        let (fixed, gimbal) = (with(Mount::Fixed { pitch }), with(Mount::Gimbal { pitch }));
        let key = |v: &Viewpoint| v.position.map(|c| (c * 1e6).round() as i64);
        let sides: BTreeSet<_> = fixed.viewpoints.iter().map(key).collect();
        let (down, level): (Vec<_>, Vec<_>) = gimbal
            .viewpoints
            .iter()
            .partition(|v| v.gimbal_pitch == FRAC_PI_2);
        // The sides are shot as before; the rest look down from above a top.
        assert_eq!(level.iter().map(|v| key(v)).collect::<BTreeSet<_>>(), sides);
        assert!(fixed.viewpoints.iter().all(|v| v.gimbal_pitch == pitch));
        assert!(down.len() > 100, "{} viewpoints looking down", down.len());
        // Each `STANDOFF` above the top of a target voxel of its patch.
        let grid = gimbal.grid();
        let tops: Vec<Point3<f64>> = gimbal
            .target_voxels
            .iter()
            .map(|v| grid.center(*v) + Vector3::z() * 0.25)
            .collect();
        for v in down {
            let p = Point3::from(v.position) - Vector3::z() * STANDOFF;
            let near =
                |t: &&Point3<f64>| (t.z - p.z).abs() < 1e-9 && (t.xy() - p.xy()).norm() < PATCH;
            assert!(tops.iter().any(|t| near(&t)), "nothing below {p}");
        }
    }

    #[test]
    fn a_mission_flown_again_sees_the_structure_from_where_it_did() {
        let scene = Scene::girder_bridge();
        let mount = Mount::Fixed { pitch: 0.2 };
        let first = plan(&scene, 0.5, mount, STANDOFF, Spacing::PATCHES);
        let iso = Isometry3::new(
            Vector3::new(1.2, -0.5, 0.0),
            Vector3::z() * 35f64.to_radians(),
        );
        let moved = scene.transformed(&iso);
        let again = reflown(first.clone(), &iso, &moved);
        assert_eq!(again.viewpoints.len(), first.viewpoints.len());
        // Each camera's axis meets the structure where it did, but where it
        // grazes an edge (aimed at a patch's centre on the deck's top edge,
        // one in ten here, it hits or passes it by rounding); a turn the
        // wrong way would agree nowhere.
        let axis = |v: &Viewpoint| {
            Vector3::new(v.yaw.cos(), v.yaw.sin(), 0.0) * v.gimbal_pitch.cos()
                - Vector3::z() * v.gimbal_pitch.sin()
        };
        let hit = |s: &Scene, v: &Viewpoint| s.cast(&Point3::from(v.position), &axis(v), 30.0);
        let same = first
            .viewpoints
            .iter()
            .zip(&again.viewpoints)
            .filter(|(a, b)| match (hit(&scene, a), hit(&moved, b)) {
                (Some(x), Some(y)) => (x.distance - y.distance).abs() < 1e-3,
                (x, y) => x.is_none() && y.is_none(),
            })
            .count();
        assert!(
            same * 100 > first.viewpoints.len() * 85,
            "{same} of {}",
            first.viewpoints.len()
        );
        // Its targets are this frame's voxels of the structure.
        let grid = VoxelGrid::new(0.5, Point3::origin());
        assert_eq!(again.target_voxels, target_voxels(&moved, &grid));
        assert_ne!(again.target_voxels, first.target_voxels);
    }
}
