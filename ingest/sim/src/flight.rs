//! The flight as flown: through the plan's viewpoints, skipping a seeded part
//! of it, some segments fast enough to blur, poses recorded with noise and a
//! few frames dropped.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use ingest::InspectionPlan;

use crate::rng::Rng;

/// Cruise speed between viewpoints, m/s.
pub const SPEED: f64 = 1.0;
/// Speed of the rushed segments, m/s: fast enough to blur at the exposure.
pub const FAST_SPEED: f64 = 3.5;
/// Pose noise of the recorded SLAM poses: position (m) and yaw (rad), 1 sigma.
pub const POSITION_NOISE: f64 = 0.02;
pub const YAW_NOISE: f64 = 0.003;
/// Pose rate of the recording, Hz.
pub const POSE_RATE: f64 = 30.0;

/// A straight leg between two waypoints.
#[derive(Debug, Clone)]
struct Leg {
    from: Point3<f64>,
    to: Point3<f64>,
    yaw_from: f64,
    yaw_to: f64,
    t0: f64,
    t1: f64,
    fast: bool,
}

/// The true motion of the vehicle.
#[derive(Debug, Clone)]
pub struct Flight {
    legs: Vec<Leg>,
    /// Plan viewpoints the flight skipped.
    pub skipped: Vec<usize>,
}

impl Flight {
    /// Fly the plan: skip a contiguous ~12% of it and rush through ~10%.
    pub fn fly(plan: &InspectionPlan, rng: &mut Rng) -> Self {
        let n = plan.viewpoints.len();
        let skip_len = (n as f64 * 0.12).round() as usize;
        let skip_start = n / 5 + (rng.uniform() * (n / 2) as f64) as usize;
        let skipped: Vec<usize> =
            (skip_start..(skip_start + skip_len).min(n.saturating_sub(1))).collect();
        let fast_len = (n as f64 * 0.10).round() as usize;
        let fast_start =
            (skip_start + skip_len + 2 + (rng.uniform() * (n / 5) as f64) as usize) % n.max(1);
        let kept: Vec<usize> = (0..n).filter(|i| !skipped.contains(i)).collect();
        let mut legs = Vec::new();
        let mut t = 0.0;
        for w in kept.windows(2) {
            let (a, b) = (&plan.viewpoints[w[0]], &plan.viewpoints[w[1]]);
            let fast = (fast_start..fast_start + fast_len).contains(&w[0]);
            let from = Point3::from(a.position);
            let to = Point3::from(b.position);
            let dist = (to - from).norm();
            // Turning on the spot takes time too: 30 deg/s.
            let turn = wrap(b.yaw - a.yaw).abs() / 30f64.to_radians();
            let duration = (dist / if fast { FAST_SPEED } else { SPEED })
                .max(turn)
                .max(0.5);
            legs.push(Leg {
                from,
                to,
                yaw_from: a.yaw,
                yaw_to: a.yaw + wrap(b.yaw - a.yaw),
                t0: t,
                t1: t + duration,
                fast,
            });
            t += duration;
        }
        Self { legs, skipped }
    }

    pub fn duration(&self) -> f64 {
        self.legs.last().map_or(0.0, |l| l.t1)
    }

    fn leg(&self, t: f64) -> &Leg {
        let i = self
            .legs
            .partition_point(|l| l.t1 < t)
            .min(self.legs.len() - 1);
        &self.legs[i]
    }

    /// True body pose at `t` seconds (level flight: yaw only).
    pub fn body_pose(&self, t: f64) -> Isometry3<f64> {
        let leg = self.leg(t);
        let s = ((t - leg.t0) / (leg.t1 - leg.t0)).clamp(0.0, 1.0);
        // Smooth start and stop at each viewpoint.
        let s = s * s * (3.0 - 2.0 * s);
        let p = leg.from + (leg.to - leg.from) * s;
        let yaw = leg.yaw_from + (leg.yaw_to - leg.yaw_from) * s;
        Isometry3::from_parts(
            Translation3::from(p.coords),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        )
    }

    /// Whether `t` falls in a rushed leg.
    pub fn is_fast(&self, t: f64) -> bool {
        self.leg(t).fast
    }
}

/// A recorded (noisy) pose: the SLAM estimate of the true pose.
pub fn noisy(pose: &Isometry3<f64>, rng: &mut Rng) -> Isometry3<f64> {
    let dp = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * POSITION_NOISE;
    let dyaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), rng.normal() * YAW_NOISE);
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector + dp),
        dyaw * pose.rotation,
    )
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}
