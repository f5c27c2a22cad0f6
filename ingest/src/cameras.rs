//! The flight's cameras: for each image topic, its intrinsics (a
//! calibration file, else the CameraInfo matched to it by frame, namespace,
//! or as the only one) and its mounting on the body from `/tf_static` or
//! `/tf`.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Isometry3;
use postflight_core::frame::camera_namespace;
use postflight_core::{Camera, Frame, Trajectory};

use crate::calibration;
use crate::error::IngestError;
use crate::ros::msg;
use crate::scan::Scan;
use crate::settings::keys;
use crate::stage::IngestOptions;
use crate::tf::TransformTree;

pub(crate) fn cameras(
    options: &IngestOptions,
    path: &Path,
    scan: &Scan,
    trajectory: &Trajectory,
    warnings: &mut Vec<String>,
) -> Result<Vec<Camera>, IngestError> {
    let file = options.settings.camera_info_file.as_deref();
    let file_intrinsics = file
        .map(|path| calibration::from_calibration_file(path, &keys::camera_info_file))
        .transpose()?;
    let first_frame = first_frames(scan);
    warnings.extend(shared_frame_warnings(&first_frame));
    let t0 = trajectory.time_span().map(|s| s.0).unwrap_or_default();
    let mut cameras = Vec::new();
    for (topic, frame) in first_frame {
        let recorded = match_camera_info(topic, &frame.frame_id, scan);
        let (intrinsics, source) = match (&file_intrinsics, recorded) {
            (Some(i), recorded) => {
                let file = file.unwrap_or(Path::new("")).display();
                if let Some((t, _)) = recorded {
                    warnings.push(format!(
                        "{topic}: using intrinsics from {file} instead of the recorded {t}"
                    ));
                }
                (i.clone(), format!("file {file}"))
            }
            (None, Some((t, info))) => {
                let i = calibration::from_camera_info(info).map_err(|why| {
                    IngestError::Calibration {
                        path: path.to_owned(),
                        why: format!(
                            "CameraInfo on {t}: {why}; pass a calibration file as {}",
                            keys::camera_info_file
                        ),
                    }
                })?;
                (i, format!("topic {t}"))
            }
            (None, None) => {
                return Err(IngestError::NoIntrinsics {
                    path: path.to_owned(),
                    topic: topic.to_string(),
                    frame_id: frame.frame_id.clone(),
                });
            }
        };
        if let (Some(w), Some(h)) = (frame.width, frame.height)
            && (w, h) != (intrinsics.width, intrinsics.height)
        {
            warnings.push(format!(
                "{topic}: images are {w}x{h} but the intrinsics are for {}x{}",
                intrinsics.width, intrinsics.height
            ));
        }
        let extrinsic = extrinsic(&scan.tf, &trajectory.child_frame_id, &frame.frame_id, t0);
        if extrinsic.is_none() {
            warnings.push(format!(
                "{topic}: no transform from body frame {:?} to camera frame {:?} in /tf_static or /tf; its frames have no pose",
                trajectory.child_frame_id, frame.frame_id
            ));
        }
        cameras.push(Camera {
            recording: frame.recording,
            topic: topic.to_string(),
            frame_id: frame.frame_id.clone(),
            intrinsics: Some(intrinsics),
            intrinsics_source: Some(source),
            extrinsic,
            body_frame: trajectory.child_frame_id.clone(),
        });
    }
    Ok(cameras)
}

/// Each image topic's first frame, by topic.
fn first_frames(scan: &Scan) -> BTreeMap<&str, &Frame> {
    let mut first_frame: BTreeMap<&str, &Frame> = BTreeMap::new();
    for f in &scan.frames {
        first_frame.entry(f.topic.as_str()).or_insert(f);
    }
    first_frame
}

/// A warning for each camera frame several image topics share (raw and
/// compressed copies of one camera, most likely).
fn shared_frame_warnings(first_frame: &BTreeMap<&str, &Frame>) -> Vec<String> {
    let mut frame_topics: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for (topic, f) in first_frame {
        frame_topics
            .entry(f.frame_id.as_str())
            .or_default()
            .push(topic);
    }
    frame_topics
        .into_iter()
        .filter(|(_, topics)| topics.len() > 1)
        .map(|(frame, topics)| {
            format!(
                "image topics {} share the camera frame {frame:?} (raw and compressed copies?); select one with {}",
                topics.join(", "),
                keys::image_topics
            )
        })
        .collect()
}

/// The CameraInfo for an image topic: the same frame, else the same namespace,
/// else the only one recorded.
pub(crate) fn match_camera_info<'a>(
    topic: &str,
    frame_id: &str,
    scan: &'a Scan,
) -> Option<(&'a str, &'a msg::CameraInfo)> {
    let infos = &scan.camera_infos;
    infos
        .iter()
        .find(|(_, i)| !frame_id.is_empty() && i.header.frame_id == frame_id)
        .or_else(|| {
            let ns = camera_namespace(topic);
            infos.iter().find(|(t, _)| camera_namespace(t) == ns)
        })
        .or_else(|| (infos.len() == 1).then(|| infos.iter().next()).flatten())
        .map(|(t, i)| (t.as_str(), i))
}

pub(crate) fn extrinsic(
    tf: &TransformTree,
    body: &str,
    camera: &str,
    time_ns: i64,
) -> Option<Isometry3<f64>> {
    if body == camera {
        return Some(Isometry3::identity());
    }
    tf.lookup(body, camera, time_ns, i64::MAX).ok()
}
