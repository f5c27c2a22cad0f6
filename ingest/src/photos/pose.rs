//! A photo's camera pose in the run's map frame (east-north-up at the geo
//! origin, turned by its yaw) from its position and DJI's gimbal angles.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use postflight_core::geo::{GeoOrigin, Geodetic};

use super::tags::Attitude;

/// The camera pose (`T_map_optical`, ROS optical axes: x right, y down, z
/// forward) of a photo taken at `at` with the gimbal at `gimbal`.
pub(crate) fn camera_pose(origin: &GeoOrigin, at: &Geodetic, gimbal: &Attitude) -> Isometry3<f64> {
    // DJI's angles turn the camera's body (x forward, y right, z down) in
    // north-east-down, yaw then pitch then roll.
    let ned_body = Rotation3::from_euler_angles(
        gimbal.roll_deg.to_radians(),
        gimbal.pitch_deg.to_radians(),
        gimbal.yaw_deg.to_radians(),
    );
    let body_optical = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[
        Vector3::y(),
        Vector3::z(),
        Vector3::x(),
    ]));
    let rotation = map_from_local_ned(origin, at) * ned_body * body_optical;
    Isometry3::from_parts(
        Translation3::from(origin.to_local(at).coords),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

/// A velocity tagged north-east-down at `at`, in the map frame.
pub(crate) fn velocity(origin: &GeoOrigin, at: &Geodetic, ned: &Vector3<f64>) -> Vector3<f64> {
    map_from_local_ned(origin, at) * ned
}

/// The rotation from north-east-down at `at` to the map frame: through the
/// Earth-centred frame, so a photo far from the origin keeps its heading
/// exactly.
fn map_from_local_ned(origin: &GeoOrigin, at: &Geodetic) -> Rotation3<f64> {
    let enu_ned = Rotation3::from_matrix_unchecked(Matrix3::new(
        0.0, 1.0, 0.0, //
        1.0, 0.0, 0.0, //
        0.0, 0.0, -1.0,
    ));
    let map_origin_enu =
        Rotation3::from_axis_angle(&Vector3::z_axis(), -origin.yaw_deg.to_radians());
    map_origin_enu * ecef_enu(&origin.position).inverse() * ecef_enu(at) * enu_ned
}

/// East, north and up at `g` as axes of the Earth-centred frame.
fn ecef_enu(g: &Geodetic) -> Rotation3<f64> {
    let (lat, lon) = (g.latitude_deg.to_radians(), g.longitude_deg.to_radians());
    let (sl, cl, so, co) = (lat.sin(), lat.cos(), lon.sin(), lon.cos());
    Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[
        Vector3::new(-so, co, 0.0),
        Vector3::new(-sl * co, -sl * so, cl),
        Vector3::new(cl * co, cl * so, sl),
    ]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn origin() -> GeoOrigin {
        GeoOrigin::parse("47.3977,8.5456,488").unwrap()
    }

    fn attitude(yaw_deg: f64, pitch_deg: f64, roll_deg: f64) -> Attitude {
        Attitude {
            yaw_deg,
            pitch_deg,
            roll_deg,
        }
    }

    #[test]
    fn gimbal_angles_point_the_optical_axis() {
        let o = origin();
        let at = o.position;
        let axis = |a: Attitude| camera_pose(&o, &at, &a).rotation * Vector3::z();
        let right = |a: Attitude| camera_pose(&o, &at, &a).rotation * Vector3::x();
        let close = |a: Vector3<f64>, b: Vector3<f64>| (a - b).norm() < 1e-9;
        // Level, yaw 0: looking north, the image's right is east.
        assert!(close(axis(attitude(0.0, 0.0, 0.0)), Vector3::y()));
        assert!(close(right(attitude(0.0, 0.0, 0.0)), Vector3::x()));
        // Yaw 90: looking east; pitch -90: straight down.
        assert!(close(axis(attitude(90.0, 0.0, 0.0)), Vector3::x()));
        assert!(close(axis(attitude(37.0, -90.0, 0.0)), -Vector3::z()));
        // Looking down 30 degrees to the west.
        let down_west = Vector3::new(-30f64.to_radians().cos(), 0.0, -0.5);
        assert!(close(axis(attitude(-90.0, -30.0, 0.0)), down_west));
        // Roll turns the image about the axis: right side down, so the
        // image's down points west.
        let rolled = camera_pose(&o, &at, &attitude(0.0, 0.0, 90.0)).rotation * Vector3::y();
        assert!(close(rolled, -Vector3::x()), "{rolled}");
        // A map frame turned 90 degrees (its x north): north is +x.
        let turned = GeoOrigin { yaw_deg: 90.0, ..o };
        let north = camera_pose(&turned, &at, &attitude(0.0, 0.0, 0.0)).rotation * Vector3::z();
        assert!(close(north, Vector3::x()), "{north}");
    }

    #[test]
    fn far_from_the_origin_north_is_the_local_north() {
        let o = origin();
        // 20 km east, north there is turned from the origin's by the
        // meridians' convergence (about sin(latitude) * longitude change).
        let at = o.to_geodetic(&nalgebra::Point3::new(20_000.0, 0.0, 0.0));
        let axis = camera_pose(&o, &at, &attitude(0.0, 0.0, 0.0)).rotation * Vector3::z();
        let convergence = (at.longitude_deg - o.position.longitude_deg).to_radians()
            * o.position.latitude_deg.to_radians().sin();
        let turned = (-axis.x).atan2(axis.y);
        assert!(
            (turned - convergence).abs() < 1e-5,
            "{turned} {convergence}"
        );
        let v = velocity(&o, &o.position, &Vector3::new(1.0, 2.0, 3.0));
        assert!((v - Vector3::new(2.0, 1.0, -3.0)).norm() < 1e-12);
    }
}
