//! Whether a face can be inspected at all: some free standpoint in the
//! distance band, within the incidence limit, above the ground and with a
//! clear line of sight. A face no standpoint satisfies is uninspectable (as
//! GATSBI reports them) rather than a gap to replan forever.

use nalgebra::{Point3, Vector3};
use postflight_core::ViewModel;
use postflight_core::map::{SlamMap, VoxelMap};

use crate::face::Face;
use crate::view::occluded;

/// Tilts from the face normal tried for standpoints, as shares of the
/// largest incidence.
const TILTS: [f64; 3] = [0.0, 0.5, 0.95];
/// Directions around the normal tried at each tilt.
const AZIMUTHS: usize = 8;
/// The ground is searched this far below a standpoint, metres.
const GROUND_SEARCH_M: f64 = 100.0;

/// Candidate camera positions for inspecting `face`: distances across the
/// band (up to `max_distance_m`, which the GSD target may shorten), tilts
/// up to the incidence limit, in a fixed order.
pub fn standpoints(face: &Face, view: &ViewModel, max_distance_m: f64) -> Vec<Point3<f64>> {
    let (lo, hi) = (view.min_distance_m, max_distance_m.min(view.max_distance_m));
    if hi < lo {
        return Vec::new();
    }
    let n = face.normal;
    let u = if n.z.abs() < 0.9 {
        n.cross(&Vector3::z()).normalize()
    } else {
        n.cross(&Vector3::x()).normalize()
    };
    let w = n.cross(&u);
    let mut out = Vec::new();
    for d in [0.5 * (lo + hi), lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo)] {
        for tilt in TILTS {
            let tilt = (tilt * view.max_incidence_deg).to_radians();
            let turns = if tilt == 0.0 { 1 } else { AZIMUTHS };
            for k in 0..turns {
                let a = std::f64::consts::TAU * k as f64 / AZIMUTHS as f64;
                let dir = n * tilt.cos() + (u * a.cos() + w * a.sin()) * tilt.sin();
                out.push(face.centre + dir * d);
            }
        }
    }
    out
}

/// Whether a camera at `p` would be in free space: its voxel unoccupied and
/// mapped ground (any occupied voxel) somewhere straight below it.
pub fn free(map: &VoxelMap, p: &Point3<f64>) -> bool {
    !map.is_occupied(map.grid.voxel_of(p)) && map.cast(p, &-Vector3::z(), GROUND_SEARCH_M).is_some()
}

/// Whether any standpoint inspects `face` under the View model.
pub fn inspectable(face: &Face, map: &SlamMap, view: &ViewModel, max_distance_m: f64) -> bool {
    standpoints(face, view, max_distance_m)
        .iter()
        .any(|p| free(&map.voxels, p) && !occluded(map, p, face))
}

#[cfg(test)]
mod tests {
    use super::*;
    use postflight_core::map::{FaceSide, VoxelGrid, VoxelIndex};

    #[test]
    fn a_face_walled_in_is_uninspectable_and_an_open_one_is_not() {
        let grid = VoxelGrid::new(0.5, Point3::origin());
        let ground: Vec<Point3<f64>> = (-30..30)
            .flat_map(|x| {
                (-30..30).map(move |y| Point3::new(f64::from(x) * 0.5, f64::from(y) * 0.5, -5.0))
            })
            .collect();
        let face = Face::new(&grid, VoxelIndex([0, 0, 0]), FaceSide::PosX);
        let view = ViewModel::default();
        let slam = |points: Vec<Point3<f64>>| {
            SlamMap::on_grid(
                postflight_core::map::PointCloud {
                    frame_id: "map".into(),
                    points,
                    grid: None,
                    mesh_spacing_m: None,
                },
                grid,
            )
            .unwrap()
        };
        let open = slam(ground.clone());
        assert!(inspectable(&face, &open, &view, 5.0));
        // A wall 1.25 m in front, wider than any tilt reaches past, mapped as
        // densely as a SLAM map maps a surface (a point every 10 cm).
        let mut walled = ground.clone();
        for y in -100..100 {
            for z in -22..100 {
                walled.push(Point3::new(1.75, f64::from(y) * 0.1, f64::from(z) * 0.1));
            }
        }
        let walled = slam(walled);
        assert!(!inspectable(&face, &walled, &view, 5.0));
        // A GSD target that caps the distance below the band: nowhere.
        assert!(!inspectable(&face, &open, &view, 1.5));
    }
}
