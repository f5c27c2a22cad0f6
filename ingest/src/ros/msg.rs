//! ROS 2 message definitions postflight reads, as serde structs laid out
//! field-for-field like their `.msg` files so the `cdr` crate can decode them.
//!
//! Image messages come twice: whole ([`Image`], [`CompressedImage`]) for
//! writing, and as heads ([`ImageHead`], [`CompressedImageHead`]) that stop
//! before the pixel data, so metadata ingest never copies image bytes.

use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize, PartialEq, Eq)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    /// Nanoseconds since the epoch of the recording's clock.
    pub fn nanos(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

/// `geometry_msgs/msg/Point` and `geometry_msgs/msg/Vector3` (same layout).
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
pub struct Pose {
    pub position: Vector3,
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct PoseStamped {
    pub header: Header,
    pub pose: Pose,
}

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct PoseWithCovariance {
    pub pose: Pose,
    /// Row-major 6x6 (CDR lays a fixed array out flat, as nested arrays).
    pub covariance: [[f64; 6]; 6],
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct PoseWithCovarianceStamped {
    pub header: Header,
    pub pose: PoseWithCovariance,
}

/// `geometry_msgs/msg/Twist`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
pub struct Twist {
    pub linear: Vector3,
    pub angular: Vector3,
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct TwistWithCovariance {
    pub twist: Twist,
    /// Row-major 6x6 (CDR lays a fixed array out flat, as nested arrays).
    pub covariance: [[f64; 6]; 6],
}

/// `nav_msgs/msg/Odometry`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct Odometry {
    pub header: Header,
    pub child_frame_id: String,
    pub pose: PoseWithCovariance,
    pub twist: TwistWithCovariance,
}

/// `geometry_msgs/msg/Transform`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
pub struct Transform {
    pub translation: Vector3,
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`: pose of `child_frame_id` in `header.frame_id`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct TfMessage {
    pub transforms: Vec<TransformStamped>,
}

/// `sensor_msgs/msg/RegionOfInterest`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
pub struct RegionOfInterest {
    pub x_offset: u32,
    pub y_offset: u32,
    pub height: u32,
    pub width: u32,
    pub do_rectify: bool,
}

/// `sensor_msgs/msg/CameraInfo`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct CameraInfo {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub distortion_model: String,
    /// ROS 1 names the matrices in capitals (`D`, `K`, `R`, `P`).
    #[serde(alias = "D")]
    pub d: Vec<f64>,
    #[serde(alias = "K")]
    pub k: [f64; 9],
    #[serde(alias = "R")]
    pub r: [f64; 9],
    #[serde(alias = "P")]
    pub p: [f64; 12],
    pub binning_x: u32,
    pub binning_y: u32,
    pub roi: RegionOfInterest,
}

/// `sensor_msgs/msg/Image` up to, not including, its `data` field.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct ImageHead {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub encoding: String,
    pub is_bigendian: u8,
    pub step: u32,
}

/// `sensor_msgs/msg/CompressedImage` up to, not including, its `data` field.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct CompressedImageHead {
    pub header: Header,
    pub format: String,
}

/// `sensor_msgs/msg/PointField`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct PointField {
    pub name: String,
    pub offset: u32,
    pub datatype: u8,
    pub count: u32,
}

/// `sensor_msgs/msg/PointCloud2`, with its point buffer as bytes.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct PointCloud2 {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub fields: Vec<PointField>,
    pub is_bigendian: bool,
    pub point_step: u32,
    pub row_step: u32,
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
    pub is_dense: bool,
}

/// `std_msgs/msg/Float64`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
pub struct Float64 {
    pub data: f64,
}

/// `sensor_msgs/msg/Image`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct Image {
    pub header: Header,
    pub height: u32,
    pub width: u32,
    pub encoding: String,
    pub is_bigendian: u8,
    pub step: u32,
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// `sensor_msgs/msg/CompressedImage`.
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct CompressedImage {
    pub header: Header,
    pub format: String,
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// `sensor_msgs/msg/NavSatStatus`.
#[derive(Debug, Clone, Copy, Deserialize, Serialize)]
pub struct NavSatStatus {
    pub status: i8,
    pub service: u16,
}

/// `sensor_msgs/msg/NavSatFix`: a satellite navigation fix (WGS 84).
#[derive(Debug, Clone, Deserialize, Serialize)]
pub struct NavSatFix {
    pub header: Header,
    pub status: NavSatStatus,
    pub latitude: f64,
    pub longitude: f64,
    pub altitude: f64,
    pub position_covariance: [[f64; 3]; 3],
    pub position_covariance_type: u8,
}
