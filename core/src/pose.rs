//! Rigid poses in time: the building block of trajectories and transforms.
//!
//! A pose `T_a_b` is the pose of frame `b` expressed in frame `a` (it maps
//! points from `b` to `a`), matching ROS's `TransformStamped` with
//! `header.frame_id = a`, `child_frame_id = b`.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};

/// A pose at a time, in nanoseconds of the recording's clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StampedPose {
    pub time_ns: i64,
    pub pose: Isometry3<f64>,
}

/// Interpolate between two poses: linear in position, spherical (slerp) in rotation.
pub fn interpolate(a: &Isometry3<f64>, b: &Isometry3<f64>, s: f64) -> Isometry3<f64> {
    let translation = a.translation.vector.lerp(&b.translation.vector, s);
    let rotation = a
        .rotation
        .try_slerp(&b.rotation, s, 1e-9)
        // Exactly opposite rotations have no unique arc; fall back to nlerp.
        .unwrap_or_else(|| a.rotation.nlerp(&b.rotation, s));
    Isometry3::from_parts(Translation3::from(translation), rotation)
}

/// Quaternion of a pose as ROS orders it: `[x, y, z, w]`.
pub fn quaternion_xyzw(pose: &Isometry3<f64>) -> [f64; 4] {
    let q = pose.rotation.quaternion();
    [q.i, q.j, q.k, q.w]
}

/// Pose from a translation and a ROS-ordered `[x, y, z, w]` quaternion.
/// `None` for a quaternion that is zero or a value that is not finite (a
/// common "unset" value in drivers).
pub fn from_parts_xyzw(t: [f64; 3], q: [f64; 4]) -> Option<Isometry3<f64>> {
    if t.iter().chain(&q).any(|v| !v.is_finite()) {
        return None;
    }
    let quaternion = Quaternion::new(q[3], q[0], q[1], q[2]);
    if quaternion.norm() < 1e-9 {
        return None;
    }
    Some(Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_quaternion(quaternion),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn interpolates_position_and_rotation() {
        let a = Isometry3::new(Vector3::new(0.0, 0.0, 0.0), Vector3::zeros());
        let b = Isometry3::new(
            Vector3::new(2.0, 4.0, 6.0),
            Vector3::z() * std::f64::consts::FRAC_PI_2,
        );
        let m = interpolate(&a, &b, 0.5);
        assert!((m.translation.vector - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
        assert!((m.rotation.angle() - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
    }

    #[test]
    fn rejects_zero_quaternion() {
        assert!(from_parts_xyzw([0.0; 3], [0.0; 4]).is_none());
        assert!(from_parts_xyzw([f64::NAN, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]).is_none());
    }
}
