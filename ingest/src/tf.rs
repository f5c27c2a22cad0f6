//! The ROS transform tree (`/tf_static` and `/tf`): resolves the chain
//! between two frames, such as the body and the camera's optical frame.

use std::collections::{BTreeSet, HashMap};

use nalgebra::Isometry3;

use crate::ros::msg::TransformStamped;
use postflight_core::pose::StampedPose;
use postflight_core::trajectory::{PoseAt, Trajectory, pose_at};

/// The edge from a child frame to its parent: `T_parent_child`, fixed or over time.
#[derive(Debug, Clone)]
enum Edge {
    Static(Isometry3<f64>),
    Dynamic(Vec<StampedPose>),
}

#[derive(Debug, Clone, Default)]
pub struct TransformTree {
    /// child frame -> (parent frame, transform)
    edges: HashMap<String, (String, Edge)>,
}

/// Why a transform could not be resolved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TfError {
    #[error("no transform chain connects {from:?} and {to:?}")]
    NotConnected { from: String, to: String },
    #[error("the transform {parent:?} -> {child:?} is not known at that time")]
    NoTimeCover { parent: String, child: String },
}

impl TransformTree {
    /// Add a transform from `/tf_static` (`is_static`) or `/tf`. Invalid
    /// rotations are ignored; returns whether the transform was kept.
    pub fn add(&mut self, t: &TransformStamped, is_static: bool) -> bool {
        let Some(pose) = crate::ros::pose(t.transform.translation, t.transform.rotation) else {
            return false;
        };
        let parent = strip_slash(&t.header.frame_id).to_string();
        let child = strip_slash(&t.child_frame_id).to_string();
        if parent.is_empty() || child.is_empty() || parent == child {
            return false;
        }
        let entry = self
            .edges
            .entry(child)
            .or_insert_with(|| (parent.clone(), Edge::Dynamic(Vec::new())));
        entry.0 = parent;
        match (&mut entry.1, is_static) {
            (edge, true) => *edge = Edge::Static(pose),
            (Edge::Dynamic(samples), false) => samples.push(StampedPose {
                time_ns: t.header.stamp.nanos(),
                pose,
            }),
            // A frame published as static stays static.
            (Edge::Static(_), false) => {}
        }
        true
    }

    /// All frames named by the tree.
    pub fn frames(&self) -> BTreeSet<&str> {
        self.edges
            .iter()
            .flat_map(|(c, (p, _))| [c.as_str(), p.as_str()])
            .collect()
    }

    pub fn is_empty(&self) -> bool {
        self.edges.is_empty()
    }

    /// `T_target_source` at `time_ns`: the pose of `source` in `target`.
    /// Time-varying links are interpolated, allowing gaps up to `max_gap_ns`.
    pub fn lookup(
        &self,
        target: &str,
        source: &str,
        time_ns: i64,
        max_gap_ns: i64,
    ) -> Result<Isometry3<f64>, TfError> {
        let target = strip_slash(target);
        let source = strip_slash(source);
        let up_target = self.chain_to_root(target);
        let up_source = self.chain_to_root(source);
        let common = up_source
            .iter()
            .find(|f| up_target.contains(f))
            .ok_or_else(|| TfError::NotConnected {
                from: target.into(),
                to: source.into(),
            })?;
        let t_common_source = self.pose_in_ancestor(source, common, time_ns, max_gap_ns)?;
        let t_common_target = self.pose_in_ancestor(target, common, time_ns, max_gap_ns)?;
        Ok(t_common_target.inverse() * t_common_source)
    }

    /// The body trajectory in `world` from the `/tf` chain `world -> ... -> body`,
    /// sampled at the times of its most frequent time-varying link.
    pub fn trajectory(&self, world: &str, body: &str, max_gap_ns: i64) -> Option<Trajectory> {
        let chain = self.chain_to_root(body);
        let world_at = chain.iter().position(|f| *f == strip_slash(world))?;
        let times: Vec<i64> = chain[..world_at]
            .iter()
            .filter_map(|child| match &self.edges.get(*child)?.1 {
                Edge::Dynamic(samples) => Some(samples),
                Edge::Static(_) => None,
            })
            .max_by_key(|samples| samples.len())?
            .iter()
            .map(|s| s.time_ns)
            .collect();
        let poses = times
            .into_iter()
            .filter_map(|time_ns| {
                let pose = self.lookup(world, body, time_ns, max_gap_ns).ok()?;
                Some(StampedPose { time_ns, pose })
            })
            .collect();
        Some(Trajectory::new(
            strip_slash(world).into(),
            strip_slash(body).into(),
            "/tf".into(),
            poses,
        ))
    }

    /// Frames that are parents but never children: the roots of the tree.
    pub fn roots(&self) -> BTreeSet<&str> {
        self.edges
            .values()
            .map(|(p, _)| p.as_str())
            .filter(|p| !self.edges.contains_key(*p))
            .collect()
    }

    /// The parent of a frame, if the tree links it.
    pub fn parent(&self, child: &str) -> Option<&str> {
        self.edges.get(strip_slash(child)).map(|(p, _)| p.as_str())
    }

    /// Whether the frame's link to its parent varies over time.
    pub fn is_dynamic(&self, child: &str) -> bool {
        matches!(
            self.edges.get(strip_slash(child)),
            Some((_, Edge::Dynamic(_)))
        )
    }

    /// `frame`, its parent, its grandparent, ... up to the root.
    fn chain_to_root<'a>(&'a self, frame: &'a str) -> Vec<&'a str> {
        let mut chain = vec![frame];
        let mut current = frame;
        while let Some((parent, _)) = self.edges.get(current) {
            if chain.contains(&parent.as_str()) {
                break; // a cycle in bad data; stop rather than loop
            }
            chain.push(parent);
            current = parent;
        }
        chain
    }

    fn pose_in_ancestor(
        &self,
        frame: &str,
        ancestor: &str,
        time_ns: i64,
        max_gap_ns: i64,
    ) -> Result<Isometry3<f64>, TfError> {
        let mut pose = Isometry3::identity();
        let mut current = frame;
        while current != ancestor {
            let (parent, edge) = &self.edges[current];
            let link = match edge {
                Edge::Static(p) => *p,
                Edge::Dynamic(samples) => {
                    edge_at(samples, time_ns, max_gap_ns).ok_or_else(|| TfError::NoTimeCover {
                        parent: parent.clone(),
                        child: current.to_string(),
                    })?
                }
            };
            pose = link * pose;
            current = parent;
        }
        Ok(pose)
    }

    /// Sort time-varying links by time; call once after the last `add`.
    pub fn finish(&mut self) {
        for (_, edge) in self.edges.values_mut() {
            if let Edge::Dynamic(samples) = edge {
                samples.sort_by_key(|s| s.time_ns);
            }
        }
    }
}

fn edge_at(samples: &[StampedPose], time_ns: i64, max_gap_ns: i64) -> Option<Isometry3<f64>> {
    // A link published once on /tf is treated as constant.
    if let [only] = samples {
        return Some(only.pose);
    }
    match pose_at(samples, time_ns, max_gap_ns) {
        PoseAt::Pose(p) => Some(p),
        _ => None,
    }
}

/// ROS 2 frame ids carry no leading slash; ROS 1 conversions often do.
fn strip_slash(frame: &str) -> &str {
    frame.strip_prefix('/').unwrap_or(frame)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros::msg::{Header, Quaternion, Time, Transform, Vector3};

    fn tf(parent: &str, child: &str, sec: i32, xyz: [f64; 3], yaw: f64) -> TransformStamped {
        let (s, c) = (yaw / 2.0).sin_cos();
        TransformStamped {
            header: Header {
                stamp: Time { sec, nanosec: 0 },
                frame_id: parent.into(),
            },
            child_frame_id: child.into(),
            transform: Transform {
                translation: Vector3 {
                    x: xyz[0],
                    y: xyz[1],
                    z: xyz[2],
                },
                rotation: Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: s,
                    w: c,
                },
            },
        }
    }

    #[test]
    fn resolves_static_chain_and_dynamic_trajectory() {
        let mut tree = TransformTree::default();
        tree.add(
            &tf("base_link", "camera_link", 0, [0.2, 0.0, -0.1], 0.0),
            true,
        );
        tree.add(
            &tf("camera_link", "/camera_optical", 0, [0.0, 0.0, 0.0], 0.5),
            true,
        );
        tree.add(&tf("map", "odom", 0, [1.0, 0.0, 0.0], 0.0), true);
        for sec in 0..=10 {
            tree.add(
                &tf("odom", "base_link", sec, [sec as f64, 0.0, 0.0], 0.0),
                false,
            );
        }
        tree.finish();
        let e = tree.lookup("base_link", "camera_optical", 0, 0).unwrap();
        assert!((e.translation.vector - nalgebra::Vector3::new(0.2, 0.0, -0.1)).norm() < 1e-12);
        assert!((e.rotation.angle() - 0.5).abs() < 1e-12);
        let inv = tree.lookup("camera_optical", "base_link", 0, 0).unwrap();
        assert!((inv * e).translation.vector.norm() < 1e-12);

        let traj = tree.trajectory("map", "base_link", 2_000_000_000).unwrap();
        assert_eq!(traj.len(), 11);
        let PoseAt::Pose(p) = traj.at(2_500_000_000, 2_000_000_000) else {
            panic!()
        };
        assert!((p.translation.x - 3.5).abs() < 1e-9);
        assert_eq!(tree.roots().into_iter().collect::<Vec<_>>(), vec!["map"]);
        assert!(matches!(
            tree.lookup("base_link", "nowhere", 0, 0),
            Err(TfError::NotConnected { .. })
        ));
    }
}
