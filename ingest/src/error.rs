//! Errors of the ingest stage, worded for the person running postflight:
//! each names the problem and what to do about it.

use std::path::PathBuf;

use crate::recording::MessageLocation;

#[derive(Debug, thiserror::Error)]
pub enum IngestError {
    #[error("{0}")]
    Option(String),

    #[error("cannot open {}: {source}; check the path", path.display())]
    Open {
        path: PathBuf,
        source: std::io::Error,
    },

    #[error(
        "{} is not an MCAP recording ({why}); record with `ros2 bag record -s mcap` or convert the bag with `ros2 bag convert`",
        path.display()
    )]
    NotMcap { path: PathBuf, why: String },

    #[error(
        "{} is truncated at byte {offset} (--strict): {salvaged} complete messages are readable; drop --strict to ingest them",
        path.display()
    )]
    Truncated {
        path: PathBuf,
        offset: u64,
        salvaged: u64,
    },

    #[error(
        "no usable pose topic in {}: found no geometry_msgs/msg/PoseStamped, nav_msgs/msg/Odometry or /tf messages{hint}; record the SLAM pose or name its topic with --pose-topic",
        path.display()
    )]
    NoPoses { path: PathBuf, hint: String },

    #[error(
        "no camera images in {}: found no sensor_msgs/msg/Image or sensor_msgs/msg/CompressedImage messages; record the camera or name its topic with --image-topic",
        path.display()
    )]
    NoImages { path: PathBuf },

    #[error("{flag} {topic:?} is not in the recording; its topics are: {available}")]
    TopicNotFound {
        flag: &'static str,
        topic: String,
        available: String,
    },

    #[error("{flag} {topic:?} has schema {schema}, expected {expected}")]
    TopicSchema {
        flag: &'static str,
        topic: String,
        schema: String,
        expected: String,
    },

    #[error(
        "{} has no camera intrinsics for {topic} (no sensor_msgs/msg/CameraInfo for frame {frame_id:?}); pass a ROS calibration file with --camera-info FILE.yaml",
        path.display()
    )]
    NoIntrinsics {
        path: PathBuf,
        topic: String,
        frame_id: String,
    },

    #[error("camera calibration file {}: {why}", path.display())]
    Calibration { path: PathBuf, why: String },

    #[error("map {}: {why}", path.display())]
    Map { path: PathBuf, why: String },

    #[error("plan {}: {why}", path.display())]
    Plan { path: PathBuf, why: String },

    #[error("cannot read message at {location:?} of {}: {why}; was the recording changed after ingest?", path.display())]
    BadLocation {
        path: PathBuf,
        location: MessageLocation,
        why: String,
    },

    #[error("run directory {}: {why}", path.display())]
    RunDir { path: PathBuf, why: String },

    #[error("cannot write {}: {source}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },

    #[error("table {}: {source}", path.display())]
    Table {
        path: PathBuf,
        source: polars::error::PolarsError,
    },
}
