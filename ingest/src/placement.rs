//! Where the frames were taken: the body trajectory (the chosen pose topic,
//! else the `/tf` chain from the world to the body) and each frame's camera
//! pose, interpolated at its capture time and composed with the camera's
//! mounting, or the reason it has none.

use std::collections::BTreeSet;
use std::path::Path;

use nalgebra::Isometry3;
use postflight_core::{Frame, PoseAt, PoseStatus, Trajectory};

use crate::error::IngestError;
use crate::scan::{PoseTopic, Scan};
use crate::settings::keys;
use crate::stage::IngestOptions;
use crate::tf::TransformTree;

/// The body trajectory: from the chosen pose topic, else the `/tf` chain.
pub(crate) fn choose_trajectory(
    options: &IngestOptions,
    path: &Path,
    scan: &mut Scan,
    camera_frames: &BTreeSet<String>,
    max_gap_ns: i64,
    warnings: &mut Vec<String>,
) -> Result<Trajectory, IngestError> {
    let best = scan
        .poses
        .iter()
        .max_by_key(|(topic, t)| (t.poses.len(), std::cmp::Reverse(topic.as_str())))
        .map(|(t, _)| t.clone());
    if let Some(topic) = best {
        let others: Vec<&String> = scan.poses.keys().filter(|t| **t != topic).collect();
        if !others.is_empty() {
            warnings.push(format!(
                "several pose topics; using {topic} (most messages), not {}; choose with {}",
                others
                    .iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
                keys::pose_topic
            ));
        }
        let PoseTopic {
            frame_id,
            child_frame_id,
            poses,
        } = scan.poses.remove(&topic).unwrap_or_default();
        let world = Some(frame_id)
            .filter(|f| !f.is_empty())
            .unwrap_or_else(|| "map".into());
        let body = options
            .settings
            .body_frame
            .clone()
            .or(Some(child_frame_id).filter(|f| !f.is_empty()))
            .or_else(|| infer_body_frame(&scan.tf, camera_frames))
            .unwrap_or_else(|| "base_link".into());
        return Ok(Trajectory::new(world, body, topic, poses));
    }
    // No pose topic: the transform tree may carry the pose (map -> odom -> base_link).
    let body = options
        .settings
        .body_frame
        .clone()
        .or_else(|| infer_body_frame(&scan.tf, camera_frames));
    let roots = scan.tf.roots();
    let world = options
        .settings
        .world_frame
        .clone()
        .or_else(|| {
            ["map", "world", "odom"]
                .iter()
                .find(|f| roots.contains(**f))
                .map(|s| s.to_string())
        })
        .or_else(|| roots.iter().next().map(|s| s.to_string()));
    if let (Some(body), Some(world)) = (body, world)
        && let Some(t) = scan.tf.trajectory(&world, &body, max_gap_ns)
        && !t.is_empty()
    {
        return Ok(t);
    }
    let hint = if scan.tf.is_empty() {
        String::new()
    } else {
        format!(
            " (/tf has frames {} but no time-varying chain from the world frame to the body; set {} and {})",
            scan.tf.frames().into_iter().collect::<Vec<_>>().join(", "),
            keys::world_frame,
            keys::body_frame
        )
    };
    Err(IngestError::NoPoses {
        path: path.to_owned(),
        hint,
    })
}

/// `base_link` when the tree has it, else the top of the camera's static chain.
pub(crate) fn infer_body_frame(
    tf: &TransformTree,
    camera_frames: &BTreeSet<String>,
) -> Option<String> {
    if tf.frames().contains("base_link") {
        return Some("base_link".into());
    }
    let camera = camera_frames.iter().next()?;
    let mut frame = camera.clone();
    // Climb while the link is fixed: the body is where the moving part starts.
    while !tf.is_dynamic(&frame) {
        match tf.parent(&frame) {
            Some(p) => frame = p.to_string(),
            None => break,
        }
    }
    Some(frame)
}

/// Give each frame its camera pose, or the reason it has none.
pub(crate) fn place_frames(
    frames: &mut [Frame],
    trajectory: &Trajectory,
    tf: &TransformTree,
    max_gap_ns: i64,
) {
    let body = trajectory.child_frame_id.as_str();
    for f in frames.iter_mut() {
        let body_pose = match trajectory.at(f.time_ns, max_gap_ns) {
            PoseAt::Pose(p) => p,
            PoseAt::BeforeStart => {
                f.pose_status = PoseStatus::BeforeTrajectory;
                continue;
            }
            PoseAt::AfterEnd => {
                f.pose_status = PoseStatus::AfterTrajectory;
                continue;
            }
            PoseAt::InGap { .. } => {
                f.pose_status = PoseStatus::PoseGap;
                continue;
            }
        };
        // Looked up per frame so a moving gimbal on /tf is followed.
        match if body == f.frame_id {
            Some(Isometry3::identity())
        } else {
            tf.lookup(body, &f.frame_id, f.time_ns, max_gap_ns).ok()
        } {
            Some(e) => {
                f.camera_pose = Some(body_pose * e);
                f.pose_status = PoseStatus::Ok;
            }
            None => f.pose_status = PoseStatus::NoExtrinsic,
        }
    }
}
