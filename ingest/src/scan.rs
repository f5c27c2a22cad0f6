//! The single pass over a recording: each channel classified by its schema
//! (and the topics the options choose), each message decoded into what
//! ingest needs: frames (their image headers only), CameraInfo, poses,
//! `/tf`, where the map clouds are, exposure times; decode failures and
//! unknown schemas counted for the warnings.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc;

use postflight_core::frame::{EXPOSURE_TOPIC, ImageEncoding, camera_namespace};
use postflight_core::geo::Geodetic;
use postflight_core::outputs::ingest::{GnssFix, TopicSummary};
use postflight_core::pose::StampedPose;
use postflight_core::{Frame, ImageLocation, ImageStatus, MessageLocation, PoseStatus};

use crate::image::{Compression, RAW_ENCODINGS, compressed_size};
use crate::recording::{Channel, RecordedMessage};
use crate::ros::{self, DecodeError, Wire, msg, schema};
use crate::stage::IngestOptions;
use crate::tf::TransformTree;

/// What a message of a channel is to ingest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Image,
    CompressedImage,
    CameraInfo,
    PoseStamped,
    PoseWithCovariance,
    Odometry,
    Tf {
        is_static: bool,
    },
    PointCloud,
    /// Exposure times of a camera's images.
    Exposure,
    /// GPS fixes.
    NavSatFix,
    /// Recognised but not used (e.g. an image topic not selected).
    Ignored,
    Unknown,
}

/// A decode failure on a topic: how many, and the first reason.
#[derive(Default)]
pub(crate) struct DecodeFailures {
    pub(crate) count: u64,
    pub(crate) first: String,
}

/// A channel as ingest sees it.
pub(crate) struct ChannelState {
    topic: Arc<str>,
    /// Schema name, or a note of its absence.
    schema: String,
    kind: Kind,
    /// How its messages decode, or why they cannot.
    wire: Result<Wire, DecodeError>,
    /// The ROS 1 definition, kept for the topics later stages read again.
    definition: Option<String>,
    count: u64,
}

/// The poses of one pose topic, with the frames its messages name.
#[derive(Default)]
pub(crate) struct PoseTopic {
    /// `header.frame_id`: the world frame.
    pub(crate) frame_id: String,
    /// Odometry's `child_frame_id`: the body frame (empty for PoseStamped).
    pub(crate) child_frame_id: String,
    pub(crate) poses: Vec<StampedPose>,
}

/// Everything gathered in the single pass over the recording.
#[derive(Default)]
pub(crate) struct Scan {
    pub(crate) channels: HashMap<u16, ChannelState>,
    pub(crate) time_range: Option<(u64, u64)>,
    pub(crate) frames: Vec<Frame>,
    pub(crate) camera_infos: BTreeMap<String, msg::CameraInfo>,
    pub(crate) poses: BTreeMap<String, PoseTopic>,
    pub(crate) tf: TransformTree,
    pub(crate) clouds: BTreeMap<String, MessageLocation>,
    /// Exposure times by camera namespace and log time.
    pub(crate) exposures: HashMap<(String, i64), f64>,
    /// GPS fixes, in the order recorded.
    pub(crate) fixes: Vec<GnssFix>,
    pub(crate) failures: BTreeMap<String, DecodeFailures>,
    pub(crate) unknown: BTreeSet<(String, String)>,
}

/// A frame as its image header describes it; placed on the trajectory
/// later.
fn image_frame(
    topic: &str,
    kind: Kind,
    wire: &Wire,
    m: &RecordedMessage<'_>,
) -> Result<Frame, DecodeError> {
    let (header, size, encoding, image_status) = match kind {
        Kind::CompressedImage => {
            let (head, data) = wire.compressed_image(m.data)?;
            let size = compressed_size(data);
            let encoding = Compression::sniff(data).map_or_else(
                || ImageEncoding::parse(&head.format),
                ImageEncoding::Compressed,
            );
            let status = match size {
                Some(_) => ImageStatus::Ok,
                None => ImageStatus::Unreadable,
            };
            (head.header, size, encoding, status)
        }
        _ => {
            let head = wire.image(m.data)?.0;
            let status = if RAW_ENCODINGS.contains(&head.encoding.as_str()) {
                ImageStatus::Ok
            } else {
                ImageStatus::UnsupportedEncoding
            };
            let size = Some((head.width, head.height));
            (head.header, size, ImageEncoding::Raw(head.encoding), status)
        }
    };
    let log_time_ns = m.log_time as i64;
    Ok(Frame {
        index: 0,
        recording: 0,
        time_ns: capture_time(&header, log_time_ns),
        log_time_ns,
        topic: topic.to_string(),
        frame_id: header.frame_id,
        width: size.map(|s| s.0),
        height: size.map(|s| s.1),
        encoding,
        camera_pose: None,
        pose_status: PoseStatus::Ok,
        image_status,
        location: ImageLocation::Message(m.location),
        exposure_s: None,
        position_std_m: None,
    })
}

/// A GPS fix of `topic`, stamped by its header (or logged at `log_time_ns`).
fn gnss_fix(topic: &str, fix: msg::NavSatFix, log_time_ns: i64) -> GnssFix {
    GnssFix {
        recording: 0,
        time_ns: capture_time(&fix.header, log_time_ns),
        topic: topic.to_string(),
        position: Geodetic {
            latitude_deg: fix.latitude,
            longitude_deg: fix.longitude,
            altitude_m: fix.altitude,
        },
        status: fix.status.status,
    }
}

impl Scan {
    fn classify(&self, channel: &Channel, options: &IngestOptions) -> Kind {
        let chosen = |flag: &Option<String>| flag.as_ref().is_none_or(|t| *t == channel.topic);
        match schema::ros2_name(&channel.schema).as_ref() {
            schema::IMAGE | schema::COMPRESSED_IMAGE
                if !options.settings.image_topics.is_empty()
                    && !options.settings.image_topics.contains(&channel.topic) =>
            {
                Kind::Ignored
            }
            schema::IMAGE => Kind::Image,
            schema::COMPRESSED_IMAGE => Kind::CompressedImage,
            schema::CAMERA_INFO if chosen(&options.settings.camera_info_topic) => Kind::CameraInfo,
            schema::POSE_STAMPED if chosen(&options.settings.pose_topic) => Kind::PoseStamped,
            schema::POSE_WITH_COVARIANCE_STAMPED if chosen(&options.settings.pose_topic) => {
                Kind::PoseWithCovariance
            }
            schema::ODOMETRY if chosen(&options.settings.pose_topic) => Kind::Odometry,
            schema::TF_MESSAGE => Kind::Tf {
                is_static: channel.topic == "/tf_static",
            },
            schema::POINT_CLOUD2 if chosen(&options.settings.map_topic) => Kind::PointCloud,
            schema::FLOAT64 if channel.topic.rsplit('/').next() == Some(EXPOSURE_TOPIC) => {
                Kind::Exposure
            }
            schema::NAV_SAT_FIX => Kind::NavSatFix,
            schema::CAMERA_INFO
            | schema::POSE_STAMPED
            | schema::POSE_WITH_COVARIANCE_STAMPED
            | schema::ODOMETRY
            | schema::POINT_CLOUD2 => Kind::Ignored,
            _ => Kind::Unknown,
        }
    }

    pub(crate) fn channel(&mut self, channel: &Channel, options: &IngestOptions) {
        let wire = Wire::of(
            &channel.message_encoding,
            &channel.schema,
            &channel.definition,
        );
        let kind = match wire {
            Err(DecodeError::Encoding(_)) => Kind::Unknown,
            _ => self.classify(channel, options),
        };
        let reread = matches!(kind, Kind::Image | Kind::CompressedImage | Kind::PointCloud);
        let definition =
            (reread && matches!(wire, Ok(Wire::Ros1(_)))).then(|| channel.definition.clone());
        let schema = if channel.schema.is_empty() {
            format!("(no schema, {})", channel.message_encoding)
        } else {
            channel.schema.clone()
        };
        if kind == Kind::Unknown {
            self.unknown.insert((channel.topic.clone(), schema.clone()));
        }
        self.channels.insert(
            channel.id,
            ChannelState {
                topic: channel.topic.as_str().into(),
                schema,
                kind,
                wire,
                definition,
                count: 0,
            },
        );
    }

    pub(crate) fn message(&mut self, m: &RecordedMessage<'_>) {
        let Some(channel) = self.channels.get_mut(&m.channel_id) else {
            self.unknown.insert((
                format!("(channel {})", m.channel_id),
                "(no channel record)".into(),
            ));
            return;
        };
        channel.count += 1;
        let (topic, kind) = (channel.topic.clone(), channel.kind);
        let wire = match &channel.wire {
            Ok(wire) => wire.clone(),
            Err(e) => {
                let e = e.clone();
                return self.failed(&topic, kind, &e);
            }
        };
        self.time_range = Some(match self.time_range {
            None => (m.log_time, m.log_time),
            Some((lo, hi)) => (lo.min(m.log_time), hi.max(m.log_time)),
        });
        if let Err(e) = self.decode(&topic, kind, &wire, m) {
            self.failed(&topic, kind, &e);
        }
    }

    /// Count a message of `topic` that could not be decoded.
    fn failed(&mut self, topic: &str, kind: Kind, e: &DecodeError) {
        if matches!(kind, Kind::Ignored | Kind::Unknown) {
            return;
        }
        let f = self.failures.entry(topic.to_string()).or_default();
        if f.count == 0 {
            f.first = e.to_string();
        }
        f.count += 1;
    }

    /// Messages per topic (several channels may share a topic).
    pub(crate) fn topics(&self) -> BTreeMap<String, TopicSummary> {
        let mut topics: BTreeMap<String, TopicSummary> = BTreeMap::new();
        for c in self.channels.values() {
            topics
                .entry(c.topic.to_string())
                .or_insert_with(|| TopicSummary {
                    schema: c.schema.clone(),
                    count: 0,
                    encoding: c.wire.as_ref().map_or("", Wire::encoding).to_string(),
                    definition: c.definition.clone(),
                })
                .count += c.count;
        }
        topics
    }

    /// How the messages of `topic` decode (ROS 2 CDR when it is unknown).
    pub(crate) fn wire(&self, topic: &str) -> Wire {
        self.channels
            .values()
            .filter(|c| *c.topic == *topic)
            .find_map(|c| c.wire.as_ref().ok().cloned())
            .unwrap_or(Wire::Cdr)
    }

    fn decode(
        &mut self,
        topic: &str,
        kind: Kind,
        wire: &Wire,
        m: &RecordedMessage<'_>,
    ) -> Result<(), DecodeError> {
        let log_time_ns = m.log_time as i64;
        match kind {
            Kind::CompressedImage | Kind::Image => {
                let frame = image_frame(topic, kind, wire, m)?;
                self.frames.push(frame);
            }
            Kind::CameraInfo => {
                if !self.camera_infos.contains_key(topic) {
                    let info: msg::CameraInfo = wire.decode(m.data)?;
                    self.camera_infos.insert(topic.to_string(), info);
                }
            }
            Kind::PoseStamped => {
                let p: msg::PoseStamped = wire.decode(m.data)?;
                self.pose(topic, p.header, &p.pose, String::new(), log_time_ns);
            }
            Kind::PoseWithCovariance => {
                let p: msg::PoseWithCovarianceStamped = wire.decode(m.data)?;
                self.pose(topic, p.header, &p.pose.pose, String::new(), log_time_ns);
            }
            Kind::Odometry => {
                let o: msg::Odometry = wire.decode(m.data)?;
                self.pose(topic, o.header, &o.pose.pose, o.child_frame_id, log_time_ns);
            }
            Kind::Tf { is_static } => {
                let tf: msg::TfMessage = wire.decode(m.data)?;
                for t in &tf.transforms {
                    self.tf.add(t, is_static);
                }
            }
            Kind::PointCloud => {
                // Maps are republished as they grow; the last one is the map.
                self.clouds.insert(topic.to_string(), m.location);
            }
            Kind::Exposure => {
                let e: msg::Float64 = wire.decode(m.data)?;
                self.exposures
                    .insert((camera_namespace(topic).to_string(), log_time_ns), e.data);
            }
            Kind::NavSatFix => {
                let fix: msg::NavSatFix = wire.decode(m.data)?;
                self.fixes.push(gnss_fix(topic, fix, log_time_ns));
            }
            Kind::Ignored | Kind::Unknown => {}
        }
        Ok(())
    }

    /// A pose of `topic`, stamped by `header` (or logged at `log_time_ns`).
    fn pose(
        &mut self,
        topic: &str,
        header: msg::Header,
        p: &msg::Pose,
        child: String,
        log_time_ns: i64,
    ) {
        let time_ns = capture_time(&header, log_time_ns);
        let frame = header.frame_id;
        let Some(pose) = ros::pose(p.position, p.orientation) else {
            return;
        };
        let entry = self.poses.entry(topic.to_string()).or_default();
        if entry.frame_id.is_empty() {
            entry.frame_id = frame;
        }
        if entry.child_frame_id.is_empty() {
            entry.child_frame_id = child;
        }
        entry.poses.push(StampedPose { time_ns, pose });
    }
}

/// A message's capture time: its `header.stamp`, or the time it was logged
/// when the stamp is unset (drivers without a clock leave it at zero).
pub(crate) fn capture_time(header: &msg::Header, log_time_ns: i64) -> i64 {
    match header.stamp.nanos() {
        0 => log_time_ns,
        t => t,
    }
}
