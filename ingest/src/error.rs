//! Errors of the ingest stage, worded for the person running postflight:
//! each names the problem and what to do about it.

use std::path::PathBuf;

use postflight_core::{Key, MessageLocation};

use crate::settings::keys;

#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    #[error(transparent)]
    Core(#[from] postflight_core::Error),

    #[error(transparent)]
    Setting(#[from] postflight_core::InvalidSetting),

    #[error(
        "{} is not a flight recording ({why}); pass an MCAP file (`ros2 bag record -s mcap`) or a ROS 1 bag (`rosbag record`)",
        path.display()
    )]
    NotRecording { path: PathBuf, why: String },

    #[error(
        "{} is truncated at byte {offset} ({strict}): {salvaged} complete messages are readable; drop {strict} to ingest them",
        path.display(),
        strict = keys::strict
    )]
    Truncated {
        path: PathBuf,
        offset: u64,
        salvaged: u64,
    },

    #[error(
        "{} is given twice; give each recording once",
        path.display()
    )]
    GivenTwice { path: PathBuf },

    #[error(
        "no flight recordings in {:?}: found no .mcap, .bag or .jpg file; pass a recording, several (--flight A --flight B), a directory of them, or a folder of photos",
        path.display().to_string()
    )]
    NoRecordingsIn { path: PathBuf },

    #[error(
        "{} cannot be used: {why}; fix or remove the photo, or drop {strict} to skip it",
        path.display(),
        strict = keys::strict
    )]
    UnusablePhoto { path: PathBuf, why: String },

    #[error(
        "no photo in {} can be posed{}; photos need EXIF GPS, a capture time, DJI's gimbal angles and a focal length",
        path.display(),
        first.as_ref().map(|f| format!(" (first: {f})")).unwrap_or_default()
    )]
    NoPosedPhotos {
        path: PathBuf,
        first: Option<String>,
    },

    #[error(
        "the reconstruction {} cannot pose the photos: {why}",
        path.display()
    )]
    Reconstruction { path: PathBuf, why: String },

    #[error("cannot read the photo {}: {why}; was it changed after ingest?", path.display())]
    PhotoUnreadable { path: PathBuf, why: String },

    #[error(
        "{recording} is in a SLAM frame of its own, and its map cannot be put on {reference}'s: {why}; record the sorties in one SLAM session (or relocalise in the first sortie's map), or process them as separate runs"
    )]
    Unregistered {
        recording: String,
        reference: String,
        why: String,
    },

    #[error(
        "no usable pose topic in {}: found no geometry_msgs/msg/PoseStamped, nav_msgs/msg/Odometry or /tf messages{hint}; record the SLAM pose or name its topic with {}",
        path.display(),
        keys::pose_topic
    )]
    NoPoses { path: PathBuf, hint: String },

    #[error(
        "no camera images in {}: found no sensor_msgs/msg/Image or sensor_msgs/msg/CompressedImage messages; record the camera or name its topic with {}",
        path.display(),
        keys::image_topics
    )]
    NoImages { path: PathBuf },

    #[error("{key} {topic:?} is not in the recording; its topics are: {available}")]
    TopicNotFound {
        key: Key,
        topic: String,
        available: String,
    },

    #[error("{key} {topic:?} has schema {schema}, expected {expected}")]
    TopicSchema {
        key: Key,
        topic: String,
        schema: String,
        expected: String,
    },

    #[error(
        "{} has no camera intrinsics for {topic} (no sensor_msgs/msg/CameraInfo for frame {frame_id:?}); pass a ROS calibration file (YAML) as {}",
        path.display(),
        keys::camera_info_file
    )]
    NoIntrinsics {
        path: PathBuf,
        topic: String,
        frame_id: String,
    },

    #[error("camera calibration file {}: {why}", path.display())]
    Calibration { path: PathBuf, why: String },

    #[error(
        "the flight has no SLAM map (no PointCloud2 topic was recorded); pass the map with {} (PLY, PCD or an OctoMap .bt/.ot, in the world frame of the poses)",
        postflight_core::setting::inputs::MAP
    )]
    NoMap,

    #[error("cannot read message at {location:?} of {}: {why}; was the recording changed after ingest?", path.display())]
    BadLocation {
        path: PathBuf,
        location: MessageLocation,
        why: String,
    },
}
