//! ROS wire formats: message structs, and decoding them from ROS 2 CDR or
//! ROS 1 serialisation ([`Wire`]).

pub mod cdr;
pub mod definitions;
pub mod msg;
pub mod pointcloud2;
pub mod ros1;
pub mod wire;

pub use wire::{DecodeError, Wire};

use nalgebra::Isometry3;

/// A pose from a ROS position and quaternion; `None` for a zero or
/// non-finite quaternion (drivers' "unset").
pub fn pose(position: msg::Vector3, q: msg::Quaternion) -> Option<Isometry3<f64>> {
    postflight_core::pose::from_parts_xyzw(
        [position.x, position.y, position.z],
        [q.x, q.y, q.z, q.w],
    )
}

/// Schema names postflight understands, in ROS 2's spelling as they appear
/// in MCAP schema records (ROS 1 names are spelled so by [`schema::ros2_name`]).
pub mod schema {
    pub const IMAGE: &str = "sensor_msgs/msg/Image";
    pub const COMPRESSED_IMAGE: &str = "sensor_msgs/msg/CompressedImage";
    pub const CAMERA_INFO: &str = "sensor_msgs/msg/CameraInfo";
    pub const POINT_CLOUD2: &str = "sensor_msgs/msg/PointCloud2";
    pub const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";
    pub const POSE_WITH_COVARIANCE_STAMPED: &str = "geometry_msgs/msg/PoseWithCovarianceStamped";
    pub const ODOMETRY: &str = "nav_msgs/msg/Odometry";
    pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
    pub const FLOAT64: &str = "std_msgs/msg/Float64";
    pub const NAV_SAT_FIX: &str = "sensor_msgs/msg/NavSatFix";

    /// A type name in ROS 2's spelling: ROS 1's `sensor_msgs/Image` is
    /// `sensor_msgs/msg/Image`.
    pub fn ros2_name(name: &str) -> std::borrow::Cow<'_, str> {
        match name.split_once('/') {
            Some((package, ty)) if !ty.contains('/') => format!("{package}/msg/{ty}").into(),
            _ => name.into(),
        }
    }
}
