//! Writing the simulated flight as a ROS 2 MCAP recording, laid out as
//! rosbag2 records one: schemas with their `.msg` text, CDR messages.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use ingest::ros::{cdr, definitions, msg};
use nalgebra::{Isometry3, Point3};

use crate::SimError;

/// Topic names of the simulated recording.
pub const IMAGE_TOPIC: &str = "/camera/image_raw/compressed";
pub const CAMERA_INFO_TOPIC: &str = "/camera/camera_info";
/// Each image's exposure time (`std_msgs/msg/Float64`, seconds), logged with the image.
pub const EXPOSURE_TOPIC: &str = "/camera/exposure_time";
pub const POSE_TOPIC: &str = "/slam/pose";
pub const MAP_TOPIC: &str = "/map";
/// Transforms that move (a gimbal's camera link), beside `/tf_static`.
pub const TF_TOPIC: &str = "/tf";
/// GPS fixes, as a GNSS receiver driver publishes them.
pub const GPS_TOPIC: &str = "/gps/fix";

pub struct Recorder {
    path: PathBuf,
    writer: mcap::Writer<BufWriter<File>>,
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
}

pub fn header(ns: i64, frame_id: &str) -> msg::Header {
    msg::Header {
        stamp: msg::Time {
            sec: ns.div_euclid(1_000_000_000) as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        },
        frame_id: frame_id.into(),
    }
}

pub fn ros_pose(p: &Isometry3<f64>) -> msg::Pose {
    let t = p.translation.vector;
    let q = p.rotation.quaternion();
    msg::Pose {
        position: msg::Vector3 {
            x: t.x,
            y: t.y,
            z: t.z,
        },
        orientation: msg::Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        },
    }
}

impl Recorder {
    /// A recording at `path`; with `moving_tf`, a `/tf` channel too, and
    /// with `gps`, a GPS fix channel.
    pub fn create(path: &Path, moving_tf: bool, gps: bool) -> Result<Self, SimError> {
        let file = File::create(path).map_err(SimError::write(path))?;
        let failed = |cause| SimError::Record {
            path: path.to_owned(),
            cause,
        };
        let mut writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library("postflight-sim")
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(1 << 20))
            .create(BufWriter::new(file))
            .map_err(failed)?;
        let mut channels = BTreeMap::new();
        let moving = moving_tf.then(|| {
            (
                TF_TOPIC,
                "tf2_msgs/msg/TFMessage",
                definitions::tf_message(),
            )
        });
        for (topic, schema, text) in [
            (
                "/tf_static",
                "tf2_msgs/msg/TFMessage",
                definitions::tf_message(),
            ),
            (
                IMAGE_TOPIC,
                "sensor_msgs/msg/CompressedImage",
                definitions::compressed_image(),
            ),
            (
                CAMERA_INFO_TOPIC,
                "sensor_msgs/msg/CameraInfo",
                definitions::camera_info(),
            ),
            (
                EXPOSURE_TOPIC,
                "std_msgs/msg/Float64",
                definitions::float64(),
            ),
            (
                POSE_TOPIC,
                "geometry_msgs/msg/PoseStamped",
                definitions::pose_stamped(),
            ),
            (
                MAP_TOPIC,
                "sensor_msgs/msg/PointCloud2",
                definitions::point_cloud2(),
            ),
        ]
        .into_iter()
        .chain(moving)
        .chain(gps.then(|| {
            (
                GPS_TOPIC,
                "sensor_msgs/msg/NavSatFix",
                definitions::nav_sat_fix(),
            )
        })) {
            let schema_id = writer
                .add_schema(schema, "ros2msg", text.as_bytes())
                .map_err(failed)?;
            let id = writer
                .add_channel(schema_id, topic, "cdr", &BTreeMap::new())
                .map_err(failed)?;
            channels.insert(topic, id);
        }
        Ok(Self {
            path: path.to_owned(),
            writer,
            channels,
            sequence: 0,
        })
    }

    pub fn write<T: serde::Serialize>(
        &mut self,
        topic: &'static str,
        log_time_ns: i64,
        message: &T,
    ) -> Result<(), SimError> {
        self.sequence += 1;
        let header = mcap::records::MessageHeader {
            channel_id: self.channels[topic],
            sequence: self.sequence,
            log_time: log_time_ns as u64,
            publish_time: log_time_ns as u64,
        };
        self.writer
            .write_to_known_channel(&header, &cdr::encode(message))
            .map_err(|cause| self.failed(cause))
    }

    pub fn finish(mut self) -> Result<(), SimError> {
        self.writer.finish().map_err(|cause| self.failed(cause))?;
        Ok(())
    }

    fn failed(&self, cause: mcap::McapError) -> SimError {
        SimError::Record {
            path: self.path.clone(),
            cause,
        }
    }
}

/// The map as a `PointCloud2` of float32 x, y, z.
pub fn point_cloud(points: &[Point3<f64>], stamp_ns: i64) -> msg::PointCloud2 {
    let mut data = Vec::with_capacity(points.len() * 12);
    for p in points {
        for v in [p.x, p.y, p.z] {
            data.extend_from_slice(&(v as f32).to_le_bytes());
        }
    }
    let field = |name: &str, offset| msg::PointField {
        name: name.into(),
        offset,
        datatype: 7,
        count: 1,
    };
    msg::PointCloud2 {
        header: header(stamp_ns, "map"),
        height: 1,
        width: points.len() as u32,
        fields: vec![field("x", 0), field("y", 4), field("z", 8)],
        is_bigendian: false,
        point_step: 12,
        row_step: 12 * points.len() as u32,
        data,
        is_dense: true,
    }
}

/// The map as a binary little-endian PLY file.
pub fn write_ply(path: &Path, points: &[Point3<f64>]) -> Result<(), SimError> {
    let mut out = format!(
        "ply\nformat binary_little_endian 1.0\ncomment postflight-sim SLAM map\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
        points.len()
    )
    .into_bytes();
    for p in points {
        for v in [p.x, p.y, p.z] {
            out.extend_from_slice(&(v as f32).to_le_bytes());
        }
    }
    std::fs::write(path, out).map_err(SimError::write(path))
}
