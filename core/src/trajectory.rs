//! The trajectory of the vehicle body in the world (map) frame, and pose
//! look-up at arbitrary times by interpolation.

use nalgebra::Isometry3;

use crate::pose::{StampedPose, interpolate};

/// Time-ordered poses of `child_frame_id` (the body) in `frame_id` (the world).
#[derive(Debug, Clone, Default)]
pub struct Trajectory {
    /// World frame, e.g. `map`.
    pub frame_id: String,
    /// Body frame, e.g. `base_link`.
    pub child_frame_id: String,
    /// Where the poses came from: a topic name, or `/tf` for a transform chain.
    pub source: String,
    poses: Vec<StampedPose>,
}

/// Result of looking up the pose at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PoseAt {
    Pose(Isometry3<f64>),
    /// The time is before the first pose.
    BeforeStart,
    /// The time is after the last pose.
    AfterEnd,
    /// The poses either side are further apart than the allowed gap.
    InGap {
        gap_ns: i64,
    },
}

impl Trajectory {
    /// Build from poses in any order; of poses with equal times the last is kept.
    pub fn new(
        frame_id: String,
        child_frame_id: String,
        source: String,
        mut poses: Vec<StampedPose>,
    ) -> Self {
        poses.sort_by_key(|p| p.time_ns);
        poses.dedup_by(|later, earlier| {
            if later.time_ns == earlier.time_ns {
                *earlier = *later;
                true
            } else {
                false
            }
        });
        Self {
            frame_id,
            child_frame_id,
            source,
            poses,
        }
    }

    pub fn poses(&self) -> &[StampedPose] {
        &self.poses
    }

    /// The same poses in another world frame: `t` is `T_new_old`.
    pub fn moved(mut self, t: &Isometry3<f64>) -> Self {
        for p in &mut self.poses {
            p.pose = t * p.pose;
        }
        self
    }

    pub fn len(&self) -> usize {
        self.poses.len()
    }

    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// First and last pose times.
    pub fn time_span(&self) -> Option<(i64, i64)> {
        Some((self.poses.first()?.time_ns, self.poses.last()?.time_ns))
    }

    /// Pose at `time_ns`, interpolated between the poses either side when
    /// they are at most `max_gap_ns` apart.
    pub fn at(&self, time_ns: i64, max_gap_ns: i64) -> PoseAt {
        pose_at(&self.poses, time_ns, max_gap_ns)
    }
}

/// [`Trajectory::at`] over time-sorted poses.
pub fn pose_at(poses: &[StampedPose], time_ns: i64, max_gap_ns: i64) -> PoseAt {
    let after = poses.partition_point(|p| p.time_ns < time_ns);
    let Some(next) = poses.get(after) else {
        return PoseAt::AfterEnd;
    };
    if next.time_ns == time_ns {
        return PoseAt::Pose(next.pose);
    }
    if after == 0 {
        return PoseAt::BeforeStart;
    }
    let prev = &poses[after - 1];
    let gap_ns = next.time_ns - prev.time_ns;
    if gap_ns > max_gap_ns {
        return PoseAt::InGap { gap_ns };
    }
    let s = (time_ns - prev.time_ns) as f64 / gap_ns as f64;
    PoseAt::Pose(interpolate(&prev.pose, &next.pose, s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn at_x(time_ns: i64, x: f64) -> StampedPose {
        StampedPose {
            time_ns,
            pose: Isometry3::translation(x, 0.0, 0.0),
        }
    }

    #[test]
    fn lookup_interpolates_and_flags() {
        let t = Trajectory::new(
            "map".into(),
            "base_link".into(),
            "/pose".into(),
            vec![
                at_x(300, 3.0),
                at_x(100, 1.0),
                at_x(200, 2.0),
                at_x(1000, 10.0),
            ],
        );
        assert_eq!(t.len(), 4);
        let PoseAt::Pose(p) = t.at(150, 150) else {
            panic!("expected a pose")
        };
        assert!((p.translation.vector - Vector3::new(1.5, 0.0, 0.0)).norm() < 1e-12);
        assert_eq!(
            t.at(100, 150),
            PoseAt::Pose(Isometry3::translation(1.0, 0.0, 0.0))
        );
        assert_eq!(
            t.at(1000, 0),
            PoseAt::Pose(Isometry3::translation(10.0, 0.0, 0.0))
        );
        assert_eq!(t.at(99, 150), PoseAt::BeforeStart);
        assert_eq!(t.at(1001, 150), PoseAt::AfterEnd);
        assert_eq!(t.at(500, 150), PoseAt::InGap { gap_ns: 700 });
    }
}
