//! The stage's settings, declared once: the `[ingest]` table of
//! `postflight.toml` and the flags of `postflight ingest`.

use std::path::PathBuf;

postflight_core::settings! {
    table = "ingest", keys = keys;
    /// `[ingest]`: which topics and frames of the recording to read.
    pub struct IngestSettings =>
    /// How an ingest reads the recording.
    struct IngestConfig {
        /// Image topic to use (repeatable) [default: every image topic].
        #[arg(long = "image-topic", value_name = "TOPIC")]
        image_topics: Vec<String> = Vec::new(),
        /// Pose topic (PoseStamped, PoseWithCovarianceStamped or Odometry)
        /// [default: the pose topic with most messages, else /tf].
        #[arg(long, value_name = "TOPIC")]
        pose_topic: String,
        /// CameraInfo topic [default: matched to each image topic by frame or namespace].
        #[arg(long, value_name = "TOPIC")]
        camera_info_topic: String,
        /// ROS camera-calibration YAML, used instead of recorded CameraInfo.
        #[arg(long = "camera-info", value_name = "FILE")]
        camera_info_file: PathBuf,
        /// PointCloud2 topic holding the SLAM map [default: found by schema].
        #[arg(long, value_name = "TOPIC")]
        map_topic: String,
        /// Body frame the poses describe [default: the odometry child frame,
        /// else base_link, else the root of the camera's transform chain].
        #[arg(long, value_name = "FRAME")]
        body_frame: String,
        /// World frame when poses come from /tf [default: the tree's root].
        #[arg(long, value_name = "FRAME")]
        world_frame: String,
        /// Largest gap between poses that frames are interpolated across, seconds.
        #[arg(long = "max-pose-gap", value_name = "SECONDS")]
        max_pose_gap_s: f64 = 0.25,
        /// Fail on a truncated recording instead of salvaging it.
        #[arg(long, num_args = 0..=1, default_missing_value = "true", value_name = "BOOL")]
        strict: bool = false,
    }
}
