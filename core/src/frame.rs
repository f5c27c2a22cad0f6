//! Frames: the camera images of a flight, each with its time, camera pose and
//! where to find its pixels in the recording.

use crate::kind::Named;
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

/// Where a message lives in the recording: how a frame finds its pixels
/// (and `ingest.json` the recorded map) without holding the flight in memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct MessageLocation {
    /// File offset of the chunk record holding the message, or `None` for a
    /// message record outside any chunk.
    pub chunk_offset: Option<u64>,
    /// Offset of the message record: within the chunk's uncompressed records
    /// when `chunk_offset` is set, else within the file.
    pub record_offset: u64,
}

/// Where a frame's pixels are: a message of a recording, or a photo file.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum ImageLocation {
    Message(MessageLocation),
    /// A photo of a photo folder, by its file name there.
    Photo(String),
}

crate::kind! {
    /// Whether and why a frame has a camera pose.
    pub enum PoseStatus("pose status") {
        /// Interpolated from the trajectory and the camera extrinsic.
        Ok = "ok",
        /// Taken before the first pose of the trajectory.
        BeforeTrajectory = "before_trajectory",
        /// Taken after the last pose of the trajectory.
        AfterTrajectory = "after_trajectory",
        /// The poses either side are further apart than the allowed gap.
        PoseGap = "pose_gap",
        /// No transform chain from the body to the image's frame.
        NoExtrinsic = "no_extrinsic",
    }
}

crate::kind! {
    /// Whether the frame's image header could be read.
    pub enum ImageStatus("image status") {
        Ok = "ok",
        /// The compressed data is not JPEG or PNG, or its header is damaged.
        Unreadable = "unreadable",
        /// A raw encoding postflight cannot decode.
        UnsupportedEncoding = "unsupported_encoding",
    }
}

/// How a frame's image is stored, as `frames.parquet` spells it: `jpeg`,
/// `png`, or a raw `sensor_msgs/Image` encoding (`rgb8`, `mono16`, ...).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ImageEncoding {
    Compressed(Compression),
    /// A raw encoding as its message names it; also a compressed image's
    /// `format` where its bytes are neither JPEG nor PNG.
    Raw(String),
}

crate::kind! {
    /// The container of a compressed image, from its magic bytes (a
    /// `CompressedImage`'s `format` is free text and often wrong).
    pub enum Compression("image container") {
        Jpeg = "jpeg",
        Png = "png",
    }
}

impl Compression {
    /// The container `data` starts as, if JPEG or PNG.
    pub fn sniff(data: &[u8]) -> Option<Self> {
        if data.starts_with(&[0xff, 0xd8, 0xff]) {
            Some(Self::Jpeg)
        } else if data.starts_with(b"\x89PNG\r\n\x1a\n") {
            Some(Self::Png)
        } else {
            None
        }
    }
}

impl ImageEncoding {
    pub fn as_str(&self) -> &str {
        match self {
            Self::Compressed(c) => c.as_str(),
            Self::Raw(raw) => raw,
        }
    }

    /// The encoding `name` spells.
    pub fn parse(name: &str) -> Self {
        Compression::named(name).map_or_else(|| Self::Raw(name.to_string()), Self::Compressed)
    }
}

impl PartialEq<&str> for ImageEncoding {
    fn eq(&self, name: &&str) -> bool {
        self.as_str() == *name
    }
}

impl crate::table::Cell for ImageEncoding {
    fn column(name: &str, values: &[&Self]) -> crate::table::Column {
        crate::table::Column::new(
            name.into(),
            values.iter().map(|v| v.as_str()).collect::<Vec<&str>>(),
        )
    }
    fn values(column: &crate::table::Column) -> crate::table::PolarsResult<Vec<Self>> {
        let texts = String::values(column)?;
        Ok(texts.iter().map(|t| Self::parse(t)).collect())
    }
}

/// One camera image of the flight.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Position in time order among all frames of the flight (of every
    /// recording), from 0.
    pub index: u32,
    /// The recording it is in: its place in `ingest.json`'s `recordings`.
    pub recording: u16,
    /// Capture time (`header.stamp`; the log time when the stamp is unset), ns.
    pub time_ns: i64,
    /// Time the recorder logged the message, ns.
    pub log_time_ns: i64,
    pub topic: String,
    /// Optical frame (`header.frame_id`).
    pub frame_id: String,
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub encoding: ImageEncoding,
    /// Pose of the camera's optical frame in the world (`T_world_camera`).
    pub camera_pose: Option<Isometry3<f64>>,
    pub pose_status: PoseStatus,
    pub image_status: ImageStatus,
    pub location: ImageLocation,
    /// Exposure time, seconds, when the recording has it (see
    /// [`EXPOSURE_TOPIC`]) or the photo's tags give it.
    pub exposure_s: Option<f64>,
    /// How far off the camera's position may be, metres (one standard
    /// deviation, 3-D), where the source says: a photo's RTK accuracy.
    pub position_std_m: Option<f64>,
}

/// Name (last path element) of a `std_msgs/msg/Float64` topic carrying each
/// image's exposure time in seconds, published beside the image topic (for
/// `/camera/image_raw/compressed`: `/camera/exposure_time`), with the
/// image's log time.
pub const EXPOSURE_TOPIC: &str = "exposure_time";

/// The namespace of a camera topic: `/cam/image_raw/compressed`,
/// `/cam/image_raw` and `/cam/camera_info` all live in `/cam`.
pub fn camera_namespace(topic: &str) -> &str {
    let topic = topic.strip_suffix("/compressed").unwrap_or(topic);
    topic.rsplit_once('/').map_or("", |(ns, _)| ns)
}
