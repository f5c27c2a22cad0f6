//! The flight as flown: viewpoint to viewpoint, hovering to shoot each one,
//! except a seeded part of the plan it skips and a seeded stretch it rushes
//! (shooting on the move, so those frames blur). Poses are recorded with
//! noise; a few frames are dropped by the recorder.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use postflight_core::InspectionPlan;

use crate::rng::Rng;
use crate::scene::Scene;
use crate::truth::PoseNoise;

/// Cruise speed between viewpoints, m/s.
pub const SPEED: f64 = 1.5;
/// Speed of the rushed stretch, m/s: fast enough to blur at the exposure.
pub const FAST_SPEED: f64 = 3.5;
/// Hover at each viewpoint, seconds; the shot is taken mid-hover.
const HOVER: f64 = 1.0;
/// Default pose noise of the recorded SLAM poses: position (m) and yaw (rad), 1 sigma.
pub const POSITION_NOISE: f64 = 0.02;
pub const YAW_NOISE: f64 = 0.003;
/// Pose rate of the recording, Hz.
pub const POSE_RATE: f64 = 30.0;
/// Transit altitude above the structure when the direct way is blocked, metres.
const OVER: f64 = 3.0;

/// A straight leg between two waypoints.
#[derive(Debug, Clone)]
struct Leg {
    from: Point3<f64>,
    to: Point3<f64>,
    yaw_from: f64,
    yaw_to: f64,
    /// The camera's pitch (radians down): a gimbal turns it on the way.
    pitch_from: f64,
    pitch_to: f64,
    t0: f64,
    t1: f64,
    /// Ease in and out (stop at both ends); rushed legs fly through.
    ease: bool,
    fast: bool,
}

/// The true motion of the vehicle.
#[derive(Debug, Clone)]
pub struct Flight {
    legs: Vec<Leg>,
    /// Plan viewpoints the flight skipped.
    pub skipped: Vec<usize>,
    /// Times the camera was triggered at a viewpoint, seconds.
    pub shots: Vec<f64>,
}

impl Flight {
    /// Fly the plan: skip a contiguous ~12% of it and rush through ~10%.
    pub fn fly(plan: &InspectionPlan, scene: &Scene, rng: &mut Rng) -> Self {
        let n = plan.viewpoints.len();
        let skip_len = (n as f64 * 0.12).round() as usize;
        let skip_start = n / 5 + (rng.uniform() * (n / 2) as f64) as usize;
        let skipped: Vec<usize> =
            (skip_start..(skip_start + skip_len).min(n.saturating_sub(1))).collect();
        let fast_len = (n as f64 * 0.10).round() as usize;
        let fast_start =
            (skip_start + skip_len + 2 + (rng.uniform() * (n / 5) as f64) as usize) % n.max(1);
        let rushed = |i: usize| (fast_start..fast_start + fast_len).contains(&i);
        let top = scene.infrastructure_bounds().1.z + OVER;
        let mut flight = Self {
            legs: Vec::new(),
            skipped: skipped.clone(),
            shots: Vec::new(),
        };
        let mut prev: Option<(Point3<f64>, f64, f64)> = None;
        for i in (0..n).filter(|i| !skipped.contains(i)) {
            let v = &plan.viewpoints[i];
            let (p, yaw, pitch) = (Point3::from(v.position), v.yaw, v.gimbal_pitch);
            let fast = rushed(i);
            if let Some((from, from_yaw, from_pitch)) = prev {
                let speed = if fast { FAST_SPEED } else { SPEED };
                let direct = clear(scene, &from, &p);
                let over = [
                    Point3::new(from.x, from.y, top.max(from.z)),
                    Point3::new(p.x, p.y, top.max(p.z)),
                ];
                let route: Vec<Point3<f64>> =
                    if direct || !clear(scene, &from, &over[0]) || !clear(scene, &over[1], &p) {
                        vec![p]
                    } else {
                        vec![over[0], over[1], p]
                    };
                let mut at = from;
                let mut yaw_at = from_yaw;
                let last = route.len() - 1;
                for (k, to) in route.into_iter().enumerate() {
                    // Turned and tilted on the last stretch, towards the face.
                    let (yaw_to, pitch) = if k == last {
                        (yaw_at + wrap(yaw - yaw_at), (from_pitch, pitch))
                    } else {
                        (yaw_at, (from_pitch, from_pitch))
                    };
                    let turn = Turn {
                        yaw: (yaw_at, yaw_to),
                        pitch,
                    };
                    flight.leg(at, to, turn, speed, !(fast && k == last), fast);
                    (at, yaw_at) = (to, yaw_to);
                }
            }
            if fast {
                // Shot on the move at the viewpoint.
                flight.shots.push(flight.duration());
            } else {
                let t = flight.duration();
                let turn = Turn {
                    yaw: (yaw, yaw),
                    pitch: (pitch, pitch),
                };
                flight.leg(p, p, turn, SPEED, true, false);
                flight.legs.last_mut().expect("just pushed").t1 = t + HOVER;
                flight.shots.push(t + HOVER / 2.0);
            }
            prev = Some((p, yaw, pitch));
        }
        flight
    }

    fn leg(
        &mut self,
        from: Point3<f64>,
        to: Point3<f64>,
        turn: Turn,
        speed: f64,
        ease: bool,
        fast: bool,
    ) {
        let t0 = self.duration();
        let ((yaw_from, yaw_to), (pitch_from, pitch_to)) = (turn.yaw, turn.pitch);
        // Turning takes time too: 45 deg/s at most.
        let turning =
            (yaw_to - yaw_from).abs().max((pitch_to - pitch_from).abs()) / 45f64.to_radians();
        let duration = ((to - from).norm() / speed).max(turning).max(0.2);
        self.legs.push(Leg {
            from,
            to,
            yaw_from,
            yaw_to,
            pitch_from,
            pitch_to,
            t0,
            t1: t0 + duration,
            ease,
            fast,
        });
    }

    pub fn duration(&self) -> f64 {
        self.legs.last().map_or(0.0, |l| l.t1)
    }

    fn leg_at(&self, t: f64) -> &Leg {
        let i = self
            .legs
            .partition_point(|l| l.t1 < t)
            .min(self.legs.len() - 1);
        &self.legs[i]
    }

    /// True body pose at `t` seconds (level flight: yaw only).
    pub fn body_pose(&self, t: f64) -> Isometry3<f64> {
        let leg = self.leg_at(t);
        let s = smooth(leg, t);
        let p = leg.from + (leg.to - leg.from) * s;
        let yaw = leg.yaw_from + (leg.yaw_to - leg.yaw_from) * s;
        Isometry3::from_parts(
            Translation3::from(p.coords),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw),
        )
    }

    /// The camera's true pitch at `t` seconds, radians down (the plan's
    /// gimbal pitch at each viewpoint, turned between them).
    pub fn camera_pitch(&self, t: f64) -> f64 {
        let leg = self.leg_at(t);
        let s = smooth(leg, t);
        leg.pitch_from + (leg.pitch_to - leg.pitch_from) * s
    }

    /// Whether `t` falls in a rushed leg.
    pub fn is_fast(&self, t: f64) -> bool {
        self.leg_at(t).fast
    }

    /// Capture times of `n` frames: the viewpoint shots, evenly thinned when
    /// there are more than `n`, else topped up with frames in transit.
    pub fn frame_times(&self, n: usize) -> Vec<f64> {
        let shots = &self.shots;
        if n <= shots.len() {
            return (0..n).map(|k| shots[k * shots.len() / n]).collect();
        }
        let extra = n - shots.len();
        let mut times: Vec<f64> = shots.clone();
        times.extend((0..extra).map(|k| self.duration() * (k as f64 + 0.5) / extra as f64));
        times.sort_by(f64::total_cmp);
        times
    }
}

/// Turning on a leg: heading and camera pitch (from, to), radians.
struct Turn {
    yaw: (f64, f64),
    pitch: (f64, f64),
}

/// How far along `leg` the vehicle is at `t`, 0 to 1 (eased at stops).
fn smooth(leg: &Leg, t: f64) -> f64 {
    let s = ((t - leg.t0) / (leg.t1 - leg.t0)).clamp(0.0, 1.0);
    if leg.ease { s * s * (3.0 - 2.0 * s) } else { s }
}

/// Whether the straight way from `a` to `b` misses the scene.
fn clear(scene: &Scene, a: &Point3<f64>, b: &Point3<f64>) -> bool {
    let d = b - a;
    let len = d.norm();
    len < 1e-9 || scene.cast(a, &(d / len), len).is_none()
}

/// A recorded (noisy) pose: the SLAM estimate of the true pose.
pub fn noisy(pose: &Isometry3<f64>, noise: &PoseNoise, rng: &mut Rng) -> Isometry3<f64> {
    let dp = Vector3::new(rng.normal(), rng.normal(), rng.normal()) * noise.position_m;
    let dyaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), rng.normal() * noise.yaw_rad);
    Isometry3::from_parts(
        Translation3::from(pose.translation.vector + dp),
        dyaw * pose.rotation,
    )
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}
