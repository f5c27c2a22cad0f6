//! The View model's rules: whether one camera inspects one face. A face is
//! inspected by a frame when its centre is inside the viewing cone and the
//! image, within the distance band, facing the camera, fine enough (GSD),
//! not hidden behind another occupied voxel, and the frame is sharp.

use nalgebra::{Isometry3, Point3};
use postflight_core::map::SlamMap;
use postflight_core::{Intrinsics, ViewModel};

use crate::face::Face;

pub use postflight_core::view::Miss;

/// How a camera sees a face it inspects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sight {
    /// Camera centre to face centre, metres.
    pub distance_m: f64,
    /// Between the face normal and the direction to the camera, degrees.
    pub incidence_deg: f64,
    /// Millimetres per pixel at the face's distance.
    pub gsd_mm: f64,
}

/// The geometric rules (cone, image, distance band, incidence, GSD) for the
/// camera whose optical frame is `camera` (x right, y down, z forward).
pub fn look(
    camera: &Isometry3<f64>,
    k: &Intrinsics,
    face: &Face,
    view: &ViewModel,
) -> Result<Sight, Miss> {
    let origin = Point3::from(camera.translation.vector);
    let to_face = face.centre - origin;
    let distance_m = to_face.norm();
    view.distance_miss(distance_m).map_or(Ok(()), Err)?;
    let dir = to_face / distance_m;
    let axis = camera.rotation * nalgebra::Vector3::z();
    let off_axis_deg = axis.dot(&dir).clamp(-1.0, 1.0).acos().to_degrees();
    view.cone_miss(off_axis_deg).map_or(Ok(()), Err)?;
    let in_image = k
        .project(&(camera.inverse() * face.centre).coords)
        .is_some_and(|px| k.contains(&px));
    if !in_image {
        return Err(Miss::OutsideImage);
    }
    let incidence_deg = face.normal.dot(&-dir).clamp(-1.0, 1.0).acos().to_degrees();
    view.incidence_miss(incidence_deg).map_or(Ok(()), Err)?;
    let gsd_mm = ViewModel::gsd_mm(distance_m, k);
    view.gsd_miss(gsd_mm).map_or(Ok(()), Err)?;
    Ok(Sight {
        distance_m,
        incidence_deg,
        gsd_mm,
    })
}

/// A ray passing this close to a map point is blocked by its surface,
/// metres: wide enough that a ray crossing a mapped surface always passes
/// that close to one of its points, narrow enough that a ray passing a
/// surface by a hand's breadth is not.
pub const OCCLUDER_RADIUS_M: f64 = 0.1;

/// Whether the map hides the face from `origin`: some map point lies within
/// [`OCCLUDER_RADIUS_M`] of the line of sight (voxels walked by 3D DDA, and
/// only occupied ones searched). The walk ends where the ray enters the
/// voxel layer in front of the face's plane: the face stands for a surface
/// somewhere in its voxel, and that surface's own points lie there.
pub fn occluded(map: &SlamMap, origin: &Point3<f64>, face: &Face) -> bool {
    let to_face = face.centre - origin;
    let distance = to_face.norm();
    let dir = to_face / distance;
    let facing = face.normal.dot(&-dir).max(0.5);
    let reach = distance - map.voxels.grid.resolution / facing;
    if reach <= 0.0 {
        return false;
    }
    let r2 = OCCLUDER_RADIUS_M * OCCLUDER_RADIUS_M;
    let blocks = |v| {
        map.points_in(v).any(|p| {
            let along = (p - origin).dot(&dir);
            along > 0.0 && along < reach && (p - origin - dir * along).norm_squared() <= r2
        })
    };
    map.voxels
        .cast_past(origin, &dir, reach, |v| !blocks(v))
        .is_some()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};
    use postflight_core::map::{FaceSide, VoxelGrid, VoxelIndex};

    fn lens() -> Intrinsics {
        Intrinsics::pinhole(640, 480, 960.0)
    }

    /// A camera at `position` looking along `forward` (optical z), level.
    fn camera(position: Point3<f64>, forward: Vector3<f64>) -> Isometry3<f64> {
        let z = forward.normalize();
        let x = z.cross(&Vector3::z()).normalize();
        let y = z.cross(&x);
        let m = nalgebra::Matrix3::from_columns(&[x, y, z]);
        Isometry3::from_parts(
            Translation3::from(position.coords),
            UnitQuaternion::from_matrix(&m),
        )
    }

    /// The +x face of voxel [0, 0, 0] on a 0.5 m grid: centre (0.5, 0.25, 0.25).
    fn face() -> Face {
        Face::new(
            &VoxelGrid::new(0.5, Point3::origin()),
            VoxelIndex([0, 0, 0]),
            FaceSide::PosX,
        )
    }

    fn view() -> ViewModel {
        ViewModel::default()
    }

    #[test]
    fn a_face_straight_ahead_in_the_band_is_inspected() {
        let f = face();
        let cam = camera(f.centre + Vector3::x() * 3.5, -Vector3::x());
        let s = look(&cam, &lens(), &f, &view()).unwrap();
        assert!((s.distance_m - 3.5).abs() < 1e-9);
        assert!(s.incidence_deg < 1e-6);
        assert!((s.gsd_mm - 3.5 / 0.96).abs() < 1e-9);
    }

    #[test]
    fn the_cone_edge_is_half_the_apex_angle() {
        let f = face();
        let at = f.centre + Vector3::x() * 3.5;
        for (off_axis_deg, inside) in [(9.9, true), (10.1, false)] {
            // Turn the camera away from the face about z by the angle.
            let a = (180.0f64 + off_axis_deg).to_radians();
            let cam = camera(at, Vector3::new(a.cos(), a.sin(), 0.0));
            let r = look(&cam, &lens(), &f, &view());
            assert_eq!(r.is_ok(), inside, "{off_axis_deg} deg: {r:?}");
            if !inside {
                assert_eq!(r.unwrap_err(), Miss::OutOfCone);
            }
        }
        // A narrow lens clips the cone: 15 deg off axis is outside a 37 deg image...
        let wide = ViewModel {
            cone_apex_deg: 60.0,
            ..view()
        };
        let a = (180.0f64 + 25.0).to_radians();
        let cam = camera(at, Vector3::new(a.cos(), a.sin(), 0.0));
        assert_eq!(look(&cam, &lens(), &f, &wide), Err(Miss::OutsideImage));
    }

    #[test]
    fn the_distance_band_edges_are_inclusive() {
        let f = face();
        for (d, expect) in [
            (1.99, Err(Miss::TooClose)),
            (2.0, Ok(())),
            (5.0, Ok(())),
            (5.01, Err(Miss::TooFar)),
        ] {
            let cam = camera(f.centre + Vector3::x() * d, -Vector3::x());
            let view = ViewModel {
                max_gsd_mm: 100.0,
                ..view()
            };
            assert_eq!(look(&cam, &lens(), &f, &view).map(|_| ()), expect, "{d} m");
        }
    }

    #[test]
    fn a_back_facing_or_too_oblique_face_is_not_inspected() {
        let f = face();
        // Behind the face, looking at it through the voxel.
        let cam = camera(f.centre - Vector3::x() * 3.0, Vector3::x());
        assert_eq!(look(&cam, &lens(), &f, &view()), Err(Miss::TooOblique));
        // 59 and 61 degrees from the normal, in the horizontal plane.
        for (deg, ok) in [(59.0f64, true), (61.0, false)] {
            let d = Vector3::new(deg.to_radians().cos(), deg.to_radians().sin(), 0.0);
            let cam = camera(f.centre + d * 3.0, -d);
            assert_eq!(look(&cam, &lens(), &f, &view()).is_ok(), ok, "{deg}");
        }
    }

    #[test]
    fn a_coarse_view_fails_the_gsd_target() {
        let f = face();
        let cam = camera(f.centre + Vector3::x() * 4.0, -Vector3::x());
        let fine = ViewModel {
            max_gsd_mm: 4.0,
            ..view()
        };
        // 4 m at 960 px focal length: 4.17 mm per pixel.
        assert_eq!(look(&cam, &lens(), &f, &fine), Err(Miss::TooCoarse));
    }

    fn map(points: &[Point3<f64>]) -> SlamMap {
        let cloud = postflight_core::map::PointCloud {
            frame_id: "map".into(),
            points: points.to_vec(),
            grid: None,
            mesh_spacing_m: None,
        };
        SlamMap::on_grid(cloud, VoxelGrid::new(0.5, Point3::origin())).unwrap()
    }

    #[test]
    fn an_occluder_between_hides_the_face() {
        let f = face();
        let cam = f.centre + Vector3::x() * 3.5;
        let wall = Point3::new(0.25, 0.25, 0.25);
        assert!(!occluded(&map(&[wall]), &cam, &f));
        // A post 2 m in front of the face, on the line of sight.
        assert!(occluded(
            &map(&[wall, Point3::new(2.6, 0.28, 0.3)]),
            &cam,
            &f
        ));
        // In a voxel the ray crosses, but 15 cm beside it: the ray passes.
        assert!(!occluded(
            &map(&[wall, Point3::new(2.6, 0.4, 0.25)]),
            &cam,
            &f
        ));
        // A voxel away from the ray does not either.
        assert!(!occluded(
            &map(&[wall, Point3::new(2.6, 1.3, 0.3)]),
            &cam,
            &f
        ));
        // The face's own surface points in front of it do not block.
        assert!(!occluded(
            &map(&[wall, Point3::new(0.6, 0.25, 0.25)]),
            &cam,
            &f
        ));
    }
}
