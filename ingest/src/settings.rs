//! The stage's settings, declared once: the `[ingest]` table of
//! `postflight.toml` and the flags of `postflight ingest`.

use std::path::PathBuf;

/// Where a recording's own frame (its SLAM or odometry frame) is in the
/// run's map frame, as the settings give it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordingFrame {
    /// The recording's file name (`drone-2.mcap`).
    pub recording: String,
    /// Its frame's origin in the map frame (x, y, z, metres) and the yaw of
    /// its x axis from the map's (degrees, counter-clockwise).
    pub origin: [f64; 4],
}

postflight_core::inline_table_setting!(
    RecordingFrame,
    "a recording's frame {recording = \"FILE\", origin = [x, y, z, yaw_deg]}"
);

impl RecordingFrame {
    /// The frame as a rigid motion: a point of the recording's frame to the
    /// map frame.
    pub fn isometry(&self) -> nalgebra::Isometry3<f64> {
        let [x, y, z, yaw] = self.origin;
        nalgebra::Isometry3::new(
            nalgebra::Vector3::new(x, y, z),
            nalgebra::Vector3::z() * yaw.to_radians(),
        )
    }
}

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
        /// Where recordings without a map of their own are in the map frame
        /// (a camera-only drone's odometry frame), each by its file name;
        /// otherwise such a recording is placed by its GPS fixes when they
        /// put it away from the first recording's frame, or taken to share
        /// it. `[[ingest.recording_frame]]` tables, or the flag once per
        /// recording as a TOML inline table.
        #[arg(long = "recording-frame", value_name = "FRAME")]
        recording_frame: Vec<RecordingFrame> = Vec::new(),
        /// Where photo folders are posed: the origin (latitude, longitude in
        /// degrees, altitude in metres above the WGS 84 ellipsoid) of the
        /// east-north-up map frame, and the heading of its x axis from
        /// east, counter-clockwise (degrees, default 0) [default: the
        /// first photo's position, the frame east-north-up].
        #[arg(long, value_name = "LAT,LON,ALT[,YAW_DEG]", allow_hyphen_values = true)]
        #[serde(with = "postflight_core::geo::geo_origin_values")]
        photo_origin: postflight_core::geo::GeoOrigin,
        /// A photogrammetry reconstruction of the photos: a COLMAP sparse
        /// model's folder (cameras, images, points3D; binary or text) or
        /// OpenSfM's / OpenDroneMap's `reconstruction.json`. Its refined
        /// poses and lenses replace the photos' tags, matched by file name;
        /// without a reference on the Earth it is fitted to the photos'
        /// GPS; its points are the map where none is given.
        #[arg(long, value_name = "MODEL")]
        reconstruction: PathBuf,
        /// Fail on a truncated recording, or a photo that cannot be posed,
        /// instead of salvaging or skipping it.
        #[arg(long, num_args = 0..=1, default_missing_value = "true", value_name = "BOOL")]
        strict: bool = false,
    }
}
