//! Motion blur of a frame, as in the CARIC blur score: how far the scene
//! point at the image centre moves across the image during the exposure.
//! The camera's velocity comes from a straight-line fit to the trajectory
//! around the frame time, not from neighbouring poses alone: SLAM poses
//! carry centimetres of noise, which over one pose interval would read as
//! metres per second.

use crate::map::VoxelMap;
use crate::pose::StampedPose;
use crate::{Flight, Frame, Intrinsics, PoseAt, Trajectory};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// Poses within this time of the frame feed the velocity fit, seconds.
const FIT_HALF_WINDOW_S: f64 = 0.2;
/// Where the optical axis meets nothing in the map, the scene point is this far.
const FAR_M: f64 = 20.0;
/// The map is searched this far along the optical axis, metres.
const MAX_RANGE_M: f64 = 200.0;

/// Linear and angular velocity of the body in the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Velocity {
    /// Metres per second.
    pub linear: Vector3<f64>,
    /// Radians per second, as a world-frame rotation vector rate.
    pub angular: Vector3<f64>,
}

/// Least-squares velocity of the trajectory over the poses within
/// [`FIT_HALF_WINDOW_S`] of `time_ns`; `None` with fewer than two.
pub fn velocity(trajectory: &Trajectory, time_ns: i64) -> Option<Velocity> {
    let half = (FIT_HALF_WINDOW_S * 1e9) as i64;
    let poses = trajectory.poses();
    let lo = poses.partition_point(|p| p.time_ns < time_ns - half);
    let hi = poses.partition_point(|p| p.time_ns <= time_ns + half);
    let window: &[StampedPose] = &poses[lo..hi];
    if window.len() < 2 {
        return None;
    }
    let t: Vec<f64> = window
        .iter()
        .map(|p| (p.time_ns - time_ns) as f64 * 1e-9)
        .collect();
    let mean_t = t.iter().sum::<f64>() / t.len() as f64;
    let var: f64 = t.iter().map(|x| (x - mean_t).powi(2)).sum();
    if var <= 0.0 {
        return None;
    }
    // Rotations as small rotation vectors from the middle pose.
    let middle = window[window.len() / 2].pose.rotation;
    let slope = |value: &dyn Fn(&StampedPose) -> Vector3<f64>| {
        let values: Vec<Vector3<f64>> = window.iter().map(value).collect();
        let mean = values.iter().sum::<Vector3<f64>>() / values.len() as f64;
        t.iter()
            .zip(&values)
            .map(|(x, v)| (v - mean) * (x - mean_t))
            .sum::<Vector3<f64>>()
            / var
    };
    Some(Velocity {
        linear: slope(&|p| p.pose.translation.vector),
        angular: slope(&|p| (p.pose.rotation * middle.inverse()).scaled_axis()),
    })
}

/// The body pose `dt` seconds from `pose` at constant `velocity`.
fn moved(pose: &Isometry3<f64>, velocity: &Velocity, dt: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector + velocity.linear * dt),
        UnitQuaternion::from_scaled_axis(velocity.angular * dt) * pose.rotation,
    )
}

/// Blur streak, pixels, of a frame taken from body pose `body` with camera
/// mounting `extrinsic` (`T_body_camera`), moving at `velocity`, exposed
/// for `exposure_s`; the scene point is where the optical axis meets `map`.
pub fn blur_px(
    body: &Isometry3<f64>,
    extrinsic: &Isometry3<f64>,
    k: &Intrinsics,
    velocity: &Velocity,
    exposure_s: f64,
    map: &VoxelMap,
) -> f64 {
    let camera = body * extrinsic;
    let origin = Point3::from(camera.translation.vector);
    let axis = camera.rotation * Vector3::z();
    let target = map
        .cast(&origin, &axis, MAX_RANGE_M)
        .map_or(origin + axis * FAR_M, |h| h.point);
    let pixel = |dt: f64| {
        let cam = moved(body, velocity, dt) * extrinsic;
        k.project(&(cam.inverse() * target).coords)
    };
    match (pixel(-exposure_s / 2.0), pixel(exposure_s / 2.0)) {
        (Some(a), Some(b)) => (b - a).norm(),
        // The point left the front of the camera: blurred beyond use.
        _ => f64::INFINITY,
    }
}

/// Motion blur of one of `flight`'s frames, pixels, taken through lens `k`
/// and exposed for `exposure_s`; `None` when its camera's mounting is
/// unknown or the trajectory gives no pose or velocity at its time.
pub fn frame_blur_px(
    flight: &Flight,
    frame: &Frame,
    k: &Intrinsics,
    exposure_s: f64,
    map: &VoxelMap,
) -> Option<f64> {
    let trajectory = flight.trajectory(frame);
    let PoseAt::Pose(body) = trajectory.at(frame.time_ns, i64::MAX) else {
        return None;
    };
    // The frame's own mounting: a gimbal turns the camera from shot to shot.
    let extrinsic = match frame.camera_pose {
        Some(camera) => body.inverse() * camera,
        None => flight.camera(frame)?.extrinsic?,
    };
    let v = velocity(trajectory, frame.time_ns)?;
    Some(blur_px(&body, &extrinsic, k, &v, exposure_s, map))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::VoxelGrid;

    fn lens() -> Intrinsics {
        Intrinsics::pinhole(640, 480, 960.0)
    }

    /// Body moving along +y at `speed` past a wall 3.5 m ahead (+x), with
    /// 2 cm of alternating pose noise; camera looking along body x.
    fn flight(speed: f64) -> (Trajectory, Isometry3<f64>, VoxelMap) {
        let poses = (0..60)
            .map(|i| {
                let t = f64::from(i) / 30.0;
                let noise = if i % 2 == 0 { 0.02 } else { -0.02 };
                StampedPose {
                    time_ns: (t * 1e9) as i64,
                    pose: Isometry3::translation(noise, speed * t, 2.0),
                }
            })
            .collect();
        let trajectory = Trajectory::new("map".into(), "base".into(), "/pose".into(), poses);
        // Optical z along body x, y down.
        let extrinsic = Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.5, -0.5, 0.5, -0.5)),
        );
        let wall: Vec<Point3<f64>> = (-40..40)
            .flat_map(|y| {
                (0..20).map(move |z| Point3::new(3.6, f64::from(y) * 0.25, f64::from(z) * 0.25))
            })
            .collect();
        let map = VoxelMap::from_points(VoxelGrid::new(0.5, Point3::origin()), &wall, 1);
        (trajectory, extrinsic, map)
    }

    #[test]
    fn blur_grows_with_speed_and_exposure_and_ignores_pose_noise() {
        let t = 1_000_000_000;
        for (speed, exposure) in [(0.0, 0.008), (1.0, 0.008), (2.0, 0.008), (2.0, 0.004)] {
            let (trajectory, extrinsic, map) = flight(speed);
            let v = velocity(&trajectory, t).unwrap();
            let PoseAt::Pose(body) = trajectory.at(t, i64::MAX) else {
                panic!("pose")
            };
            let blur = blur_px(&body, &extrinsic, &lens(), &v, exposure, &map);
            // Sideways motion s over a wall at distance d: f * s / d pixels.
            let d = 3.5 - body.translation.x;
            let expected = 960.0 * speed * exposure / d;
            assert!(
                (blur - expected).abs() < 0.15,
                "{speed} m/s, {exposure} s: {blur:.2} px, expected {expected:.2}"
            );
        }
    }
}
