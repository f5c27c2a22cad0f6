//! Camera intrinsics as ROS records them: a `sensor_msgs/CameraInfo`
//! message, or a camera-calibration YAML file (as `camera_calibration` and
//! `camera_info_manager` write it).

use std::path::Path;

use postflight_core::Intrinsics;
use serde::Deserialize;

use crate::error::IngestError;
use crate::ros::msg::CameraInfo;

/// Intrinsics from a `CameraInfo` message.
pub fn from_camera_info(info: &CameraInfo) -> Result<Intrinsics, String> {
    Intrinsics::from_ros(
        info.width,
        info.height,
        &info.k,
        &info.distortion_model,
        &info.d,
    )
}

/// Intrinsics from a ROS camera-calibration YAML file, `given_as` the
/// setting or flag that named it (for the error).
pub fn from_calibration_file(
    path: &Path,
    given_as: &dyn std::fmt::Display,
) -> Result<Intrinsics, IngestError> {
    let error = |why: String| IngestError::Calibration {
        path: path.to_owned(),
        why,
    };
    let text = postflight_core::user_file::read_to_string(path)
        .map_err(|e| error(format!("{e}; check the path given as {given_as}")))?;
    let file: CalibrationFile = serde_yaml_ng::from_str(&text).map_err(|e| {
        // The parser's message quotes what it met, which for a file that
        // is not YAML can be all of it: its first line, shortened.
        let why = e.to_string();
        let why = why.lines().next().unwrap_or_default();
        let why: String = match why.char_indices().nth(120) {
            Some((cut, _)) => format!("{}...", &why[..cut]),
            None => why.to_string(),
        };
        error(format!(
            "not a ROS camera calibration file ({why}); expected image_width, image_height, camera_matrix, distortion_model, distortion_coefficients (given as {given_as})"
        ))
    })?;
    Intrinsics::from_ros(
        file.image_width,
        file.image_height,
        &file.camera_matrix.data,
        &file.distortion_model,
        &file
            .distortion_coefficients
            .map(|m| m.data)
            .unwrap_or_default(),
    )
    .map_err(error)
}

#[derive(Deserialize)]
struct CalibrationFile {
    image_width: u32,
    image_height: u32,
    camera_matrix: YamlMatrix,
    #[serde(default)]
    distortion_model: String,
    distortion_coefficients: Option<YamlMatrix>,
}

#[derive(Deserialize)]
struct YamlMatrix {
    data: Vec<f64>,
}
