//! The ingest stage: one pass over a flight recording, then the frames,
//! trajectory, cameras and a summary written into the run directory.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use nalgebra::{Isometry3, Point3};

use postflight_core::frame::{EXPOSURE_TOPIC, camera_namespace};
use postflight_core::outputs::ingest::{
    self as outputs, FlightFile, IngestSummary, PoseSource, RecordedMap, TopicSummary, files,
};
use postflight_core::pose::StampedPose;
use postflight_core::time::rfc3339;
use postflight_core::{
    Camera, Frame, ImageStatus, MessageLocation, PoseAt, PoseStatus, RunDir, Trajectory,
};
use postflight_core::{InvalidSetting, Key};

use crate::calibration;
use crate::error::IngestError;
use crate::image::{Compression, RAW_ENCODINGS, compressed_size};
use crate::recording::{Channel, RecordedMessage, Recording, ScanEvent, ScanReport};
use crate::ros::{self, cdr, msg, pointcloud2, schema};
use crate::tf::TransformTree;

/// The stage's settings, by their key in `postflight.toml`'s `[ingest]`.
pub mod keys {
    use postflight_core::Key;

    pub const IMAGE_TOPICS: Key = Key::setting("ingest", "image_topics");
    pub const POSE_TOPIC: Key = Key::setting("ingest", "pose_topic");
    pub const CAMERA_INFO_TOPIC: Key = Key::setting("ingest", "camera_info_topic");
    pub const CAMERA_INFO_FILE: Key = Key::setting("ingest", "camera_info_file");
    pub const MAP_TOPIC: Key = Key::setting("ingest", "map_topic");
    pub const BODY_FRAME: Key = Key::setting("ingest", "body_frame");
    pub const WORLD_FRAME: Key = Key::setting("ingest", "world_frame");
    pub const MAX_POSE_GAP: Key = Key::setting("ingest", "max_pose_gap_s");
    pub const STRICT: Key = Key::setting("ingest", "strict");
}

/// What to ingest and how.
#[derive(Debug, Clone)]
pub struct IngestOptions {
    pub flight: PathBuf,
    pub out: PathBuf,
    /// Use only these image topics (default: every image topic).
    pub image_topics: Vec<String>,
    /// Pose topic (default: the pose topic with most messages, else `/tf`).
    pub pose_topic: Option<String>,
    /// CameraInfo topic (default: matched to each image topic by frame or namespace).
    pub camera_info_topic: Option<String>,
    /// ROS calibration YAML, used instead of recorded CameraInfo.
    pub camera_info_file: Option<PathBuf>,
    /// PointCloud2 topic holding the SLAM map (default: found by schema).
    pub map_topic: Option<String>,
    /// Body frame the pose describes (default: the odometry child frame,
    /// else `base_link`, else the root of the camera's transform chain).
    pub body_frame: Option<String>,
    /// World frame, when poses come from `/tf` (default: the root of the tree).
    pub world_frame: Option<String>,
    /// Largest gap between poses that frames may be interpolated across, seconds.
    pub max_pose_gap_s: f64,
    /// Treat a truncated recording as an error.
    pub strict: bool,
}

impl IngestOptions {
    pub const DEFAULT_MAX_POSE_GAP_S: f64 = 0.25;

    pub fn new(flight: PathBuf, out: PathBuf) -> Self {
        Self {
            flight,
            out,
            image_topics: Vec::new(),
            pose_topic: None,
            camera_info_topic: None,
            camera_info_file: None,
            map_topic: None,
            body_frame: None,
            world_frame: None,
            max_pose_gap_s: Self::DEFAULT_MAX_POSE_GAP_S,
            strict: false,
        }
    }
}

/// Progress of an ingest, for progress bars.
pub trait Progress {
    /// `done` of `total` bytes of the recording read.
    fn bytes(&mut self, done: u64, total: u64);
}

impl<F: FnMut(u64, u64)> Progress for F {
    fn bytes(&mut self, done: u64, total: u64) {
        self(done, total)
    }
}

/// What a message of a channel is to ingest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
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
    /// Recognised but not used (e.g. an image topic not selected).
    Ignored,
    Unknown,
}

/// A decode failure on a topic: how many, and the first reason.
#[derive(Default)]
struct DecodeFailures {
    count: u64,
    first: String,
}

/// A channel as ingest sees it.
struct ChannelState {
    topic: Arc<str>,
    /// Schema name, or a note of its absence.
    schema: String,
    kind: Kind,
    count: u64,
}

/// The poses of one pose topic, with the frames its messages name.
#[derive(Default)]
struct PoseTopic {
    /// `header.frame_id`: the world frame.
    frame_id: String,
    /// Odometry's `child_frame_id`: the body frame (empty for PoseStamped).
    child_frame_id: String,
    poses: Vec<StampedPose>,
}

/// Everything gathered in the single pass over the recording.
#[derive(Default)]
struct Scan {
    channels: HashMap<u16, ChannelState>,
    time_range: Option<(u64, u64)>,
    frames: Vec<Frame>,
    camera_infos: BTreeMap<String, msg::CameraInfo>,
    poses: BTreeMap<String, PoseTopic>,
    tf: TransformTree,
    clouds: BTreeMap<String, MessageLocation>,
    /// Exposure times by camera namespace and log time.
    exposures: HashMap<(String, i64), f64>,
    failures: BTreeMap<String, DecodeFailures>,
    unknown: BTreeSet<(String, String)>,
}

impl Scan {
    fn classify(&self, channel: &Channel, options: &IngestOptions) -> Kind {
        if channel.message_encoding != "cdr" {
            return Kind::Unknown;
        }
        let chosen = |flag: &Option<String>| flag.as_ref().is_none_or(|t| *t == channel.topic);
        match channel.schema.as_str() {
            schema::IMAGE | schema::COMPRESSED_IMAGE
                if !options.image_topics.is_empty()
                    && !options.image_topics.contains(&channel.topic) =>
            {
                Kind::Ignored
            }
            schema::IMAGE => Kind::Image,
            schema::COMPRESSED_IMAGE => Kind::CompressedImage,
            schema::CAMERA_INFO if chosen(&options.camera_info_topic) => Kind::CameraInfo,
            schema::POSE_STAMPED if chosen(&options.pose_topic) => Kind::PoseStamped,
            schema::POSE_WITH_COVARIANCE_STAMPED if chosen(&options.pose_topic) => {
                Kind::PoseWithCovariance
            }
            schema::ODOMETRY if chosen(&options.pose_topic) => Kind::Odometry,
            schema::TF_MESSAGE => Kind::Tf {
                is_static: channel.topic == "/tf_static",
            },
            schema::POINT_CLOUD2 if chosen(&options.map_topic) => Kind::PointCloud,
            schema::FLOAT64 if channel.topic.rsplit('/').next() == Some(EXPOSURE_TOPIC) => {
                Kind::Exposure
            }
            schema::CAMERA_INFO
            | schema::POSE_STAMPED
            | schema::POSE_WITH_COVARIANCE_STAMPED
            | schema::ODOMETRY
            | schema::POINT_CLOUD2 => Kind::Ignored,
            _ => Kind::Unknown,
        }
    }

    fn channel(&mut self, channel: &Channel, options: &IngestOptions) {
        let kind = self.classify(channel, options);
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
                count: 0,
            },
        );
    }

    fn message(&mut self, m: &RecordedMessage<'_>) {
        let Some(channel) = self.channels.get_mut(&m.channel_id) else {
            self.unknown.insert((
                format!("(channel {})", m.channel_id),
                "(no channel record)".into(),
            ));
            return;
        };
        channel.count += 1;
        let (topic, kind) = (channel.topic.clone(), channel.kind);
        self.time_range = Some(match self.time_range {
            None => (m.log_time, m.log_time),
            Some((lo, hi)) => (lo.min(m.log_time), hi.max(m.log_time)),
        });
        if let Err(e) = self.decode(&topic, kind, m) {
            let f = self.failures.entry(topic.to_string()).or_default();
            if f.count == 0 {
                f.first = e.to_string();
            }
            f.count += 1;
        }
    }

    /// Messages per topic (several channels may share a topic).
    fn topics(&self) -> BTreeMap<String, TopicSummary> {
        let mut topics: BTreeMap<String, TopicSummary> = BTreeMap::new();
        for c in self.channels.values() {
            topics
                .entry(c.topic.to_string())
                .or_insert_with(|| TopicSummary {
                    schema: c.schema.clone(),
                    count: 0,
                })
                .count += c.count;
        }
        topics
    }

    fn decode(
        &mut self,
        topic: &str,
        kind: Kind,
        m: &RecordedMessage<'_>,
    ) -> Result<(), cdr::CdrError> {
        let log_time_ns = m.log_time as i64;
        // A frame as its image header describes it; placed on the trajectory later.
        let frame =
            |header: &msg::Header, size: Option<(u32, u32)>, encoding, image_status| Frame {
                index: 0,
                time_ns: capture_time(header, log_time_ns),
                log_time_ns,
                topic: topic.to_string(),
                frame_id: header.frame_id.clone(),
                width: size.map(|s| s.0),
                height: size.map(|s| s.1),
                encoding,
                camera_pose: None,
                pose_status: PoseStatus::Ok,
                image_status,
                location: m.location,
                exposure_s: None,
            };
        match kind {
            Kind::CompressedImage => {
                let (head, mut tail) = cdr::decode_head::<msg::CompressedImageHead>(m.data)?;
                let data = tail.byte_sequence()?;
                let size = compressed_size(data);
                let encoding = Compression::sniff(data)
                    .map(|c| c.as_str().to_string())
                    .unwrap_or(head.format);
                let status = match size {
                    Some(_) => ImageStatus::Ok,
                    None => ImageStatus::Unreadable,
                };
                self.frames
                    .push(frame(&head.header, size, encoding, status));
            }
            Kind::Image => {
                let head: msg::ImageHead = cdr::decode_head(m.data)?.0;
                let status = if RAW_ENCODINGS.contains(&head.encoding.as_str()) {
                    ImageStatus::Ok
                } else {
                    ImageStatus::UnsupportedEncoding
                };
                let size = Some((head.width, head.height));
                self.frames
                    .push(frame(&head.header, size, head.encoding, status));
            }
            Kind::CameraInfo => {
                if !self.camera_infos.contains_key(topic) {
                    let info: msg::CameraInfo = cdr::decode(m.data)?;
                    self.camera_infos.insert(topic.to_string(), info);
                }
            }
            Kind::PoseStamped => {
                let p: msg::PoseStamped = cdr::decode(m.data)?;
                self.pose(topic, p.header, &p.pose, String::new(), log_time_ns);
            }
            Kind::PoseWithCovariance => {
                let p: msg::PoseWithCovarianceStamped = cdr::decode(m.data)?;
                self.pose(topic, p.header, &p.pose.pose, String::new(), log_time_ns);
            }
            Kind::Odometry => {
                let o: msg::Odometry = cdr::decode(m.data)?;
                self.pose(topic, o.header, &o.pose.pose, o.child_frame_id, log_time_ns);
            }
            Kind::Tf { is_static } => {
                let tf: msg::TfMessage = cdr::decode(m.data)?;
                for t in &tf.transforms {
                    self.tf.add(t, is_static);
                }
            }
            Kind::PointCloud => {
                // Maps are republished as they grow; the last one is the map.
                self.clouds.insert(topic.to_string(), m.location);
            }
            Kind::Exposure => {
                let e: msg::Float64 = cdr::decode(m.data)?;
                self.exposures
                    .insert((camera_namespace(topic).to_string(), log_time_ns), e.data);
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
fn capture_time(header: &msg::Header, log_time_ns: i64) -> i64 {
    match header.stamp.nanos() {
        0 => log_time_ns,
        t => t,
    }
}

/// Ingest a flight recording into a run directory.
pub fn ingest(
    options: &IngestOptions,
    progress: &mut dyn Progress,
) -> Result<IngestSummary, IngestError> {
    InvalidSetting::check(
        options.max_pose_gap_s.is_finite() && options.max_pose_gap_s > 0.0,
        keys::MAX_POSE_GAP,
        options.max_pose_gap_s,
        "a positive number of seconds",
    )?;
    let recording = Recording::open(&options.flight)?;
    let total = recording.len();
    let mut scan = Scan::default();
    let report = recording.scan(|event| match event {
        ScanEvent::Channel(c) => scan.channel(c, options),
        ScanEvent::Message(m) => scan.message(&m),
        ScanEvent::Progress { bytes } => progress.bytes(bytes, total),
    });
    scan.tf.finish();
    let path = options.flight.clone();
    let messages = scan.topics();
    let salvaged: u64 = messages.values().map(|t| t.count).sum();
    if report.truncated && options.strict {
        return Err(IngestError::Truncated {
            path,
            offset: report.truncated_at.unwrap_or(total),
            salvaged,
        });
    }
    check_topic_flags(options, &messages)?;

    let mut warnings = damage_warnings(&report, &scan, total);
    if scan.frames.is_empty() {
        return Err(IngestError::NoImages { path });
    }
    let max_gap_ns = (options.max_pose_gap_s * 1e9) as i64;
    let camera_frames: BTreeSet<String> = scan.frames.iter().map(|f| f.frame_id.clone()).collect();
    let trajectory = choose_trajectory(
        options,
        &mut scan,
        &camera_frames,
        max_gap_ns,
        &mut warnings,
    )?;
    let cameras = cameras(options, &scan, &trajectory, &mut warnings)?;
    let mut frames = std::mem::take(&mut scan.frames);
    for f in &mut frames {
        let key = (camera_namespace(&f.topic).to_string(), f.log_time_ns);
        f.exposure_s = scan.exposures.get(&key).copied();
    }
    frames.sort_by(|a, b| (a.time_ns, &a.topic).cmp(&(b.time_ns, &b.topic)));
    place_frames(&mut frames, &trajectory, &scan.tf, max_gap_ns);
    let map = recorded_map(&recording, &scan, &mut warnings);
    if let Some(m) = &map
        && !m.frame_id.is_empty()
        && m.frame_id != trajectory.frame_id
    {
        warnings.push(format!(
            "the map on {} is in frame {:?} but the poses are in {:?}; later stages assume they are the same frame",
            m.topic, m.frame_id, trajectory.frame_id
        ));
    }

    let mut by_status: BTreeMap<String, u64> = BTreeMap::new();
    for f in &frames {
        *by_status
            .entry(f.pose_status.as_str().to_string())
            .or_default() += 1;
    }
    let without_pose = frames.len() as u64 - by_status.get("ok").copied().unwrap_or(0);
    if without_pose > 0 {
        let detail: Vec<String> = by_status
            .iter()
            .filter(|(k, _)| *k != "ok")
            .map(|(k, v)| format!("{v} {k}"))
            .collect();
        warnings.push(format!(
            "{without_pose} of {} frames have no camera pose ({}); they are kept and flagged in frames.parquet",
            frames.len(),
            detail.join(", ")
        ));
    }
    let unreadable = frames
        .iter()
        .filter(|f| f.image_status != ImageStatus::Ok)
        .count();
    if unreadable > 0 {
        warnings.push(format!(
            "{unreadable} frames have unreadable or unsupported images (see image_status)"
        ));
    }

    let (start, end) = scan.time_range.unwrap_or((0, 0));
    let summary = IngestSummary {
        postflight_version: env!("CARGO_PKG_VERSION").to_string(),
        flight: FlightFile {
            path: std::path::absolute(&options.flight).unwrap_or_else(|_| options.flight.clone()),
            size_bytes: total,
        },
        messages,
        frames: frames.len() as u64,
        frames_with_pose: frames.iter().filter(|f| f.camera_pose.is_some()).count() as u64,
        frames_by_pose_status: by_status,
        image_topics: frames
            .iter()
            .map(|f| f.topic.clone())
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect(),
        poses: trajectory.len() as u64,
        pose_source: PoseSource {
            topic: trajectory.source.clone(),
            frame_id: trajectory.frame_id.clone(),
            child_frame_id: trajectory.child_frame_id.clone(),
        },
        duration_s: (end - start) as f64 * 1e-9,
        start_time: rfc3339(start as i64),
        end_time: rfc3339(end as i64),
        start_time_ns: start as i64,
        end_time_ns: end as i64,
        truncated: report.truncated,
        truncated_at_byte: report.truncated_at,
        corrupt_chunks: report.corrupt_chunks,
        map,
        max_pose_gap_s: options.max_pose_gap_s,
        warnings,
    };
    write_outputs(&options.out, &frames, &trajectory, &cameras, &summary)?;
    Ok(summary)
}

fn check_topic_flags(
    options: &IngestOptions,
    topics: &BTreeMap<String, TopicSummary>,
) -> Result<(), IngestError> {
    let available = || topics.keys().cloned().collect::<Vec<_>>().join(", ");
    let check = |key: Key, topic: &String, expected: &[&str]| -> Result<(), IngestError> {
        let Some(TopicSummary { schema, .. }) = topics.get(topic) else {
            return Err(IngestError::TopicNotFound {
                key,
                topic: topic.clone(),
                available: available(),
            });
        };
        if !expected.contains(&schema.as_str()) {
            return Err(IngestError::TopicSchema {
                key,
                topic: topic.clone(),
                schema: schema.clone(),
                expected: expected.join(" or "),
            });
        }
        Ok(())
    };
    for t in &options.image_topics {
        check(
            keys::IMAGE_TOPICS,
            t,
            &[schema::IMAGE, schema::COMPRESSED_IMAGE],
        )?;
    }
    if let Some(t) = &options.pose_topic {
        check(
            keys::POSE_TOPIC,
            t,
            &[
                schema::POSE_STAMPED,
                schema::POSE_WITH_COVARIANCE_STAMPED,
                schema::ODOMETRY,
            ],
        )?;
    }
    if let Some(t) = &options.camera_info_topic {
        check(keys::CAMERA_INFO_TOPIC, t, &[schema::CAMERA_INFO])?;
    }
    if let Some(t) = &options.map_topic {
        check(keys::MAP_TOPIC, t, &[schema::POINT_CLOUD2])?;
    }
    Ok(())
}

fn damage_warnings(report: &ScanReport, scan: &Scan, file_len: u64) -> Vec<String> {
    let mut warnings = Vec::new();
    if report.truncated {
        warnings.push(format!(
            "the recording is truncated (recording cut short?): it ends at byte {file_len} inside the record starting at byte {}; every complete message before the cut was ingested",
            report.truncated_at.unwrap_or(file_len)
        ));
    }
    if report.corrupt_chunks > 0 {
        warnings.push(format!(
            "{} corrupt chunks were skipped",
            report.corrupt_chunks
        ));
    }
    warnings.extend(report.problems.iter().cloned());
    for (topic, f) in &scan.failures {
        warnings.push(format!(
            "{topic}: {} messages could not be decoded (first: {})",
            f.count, f.first
        ));
    }
    if !scan.unknown.is_empty() {
        let list: Vec<String> = scan
            .unknown
            .iter()
            .map(|(t, s)| format!("{t} ({s})"))
            .collect();
        warnings.push(format!(
            "topics with schemas postflight does not use: {}",
            list.join(", ")
        ));
    }
    warnings
}

/// The body trajectory: from the chosen pose topic, else the `/tf` chain.
fn choose_trajectory(
    options: &IngestOptions,
    scan: &mut Scan,
    camera_frames: &BTreeSet<String>,
    max_gap_ns: i64,
    warnings: &mut Vec<String>,
) -> Result<Trajectory, IngestError> {
    let best = scan
        .poses
        .iter()
        .max_by_key(|(topic, t)| (t.poses.len(), std::cmp::Reverse(topic.as_str())))
        .map(|(t, _)| t.clone());
    if let Some(topic) = best {
        let others: Vec<&String> = scan.poses.keys().filter(|t| **t != topic).collect();
        if !others.is_empty() {
            warnings.push(format!(
                "several pose topics; using {topic} (most messages), not {}; choose with {}",
                others
                    .iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
                keys::POSE_TOPIC
            ));
        }
        let PoseTopic {
            frame_id,
            child_frame_id,
            poses,
        } = scan.poses.remove(&topic).unwrap_or_default();
        let world = Some(frame_id)
            .filter(|f| !f.is_empty())
            .unwrap_or_else(|| "map".into());
        let body = options
            .body_frame
            .clone()
            .or(Some(child_frame_id).filter(|f| !f.is_empty()))
            .or_else(|| infer_body_frame(&scan.tf, camera_frames))
            .unwrap_or_else(|| "base_link".into());
        return Ok(Trajectory::new(world, body, topic, poses));
    }
    // No pose topic: the transform tree may carry the pose (map -> odom -> base_link).
    let body = options
        .body_frame
        .clone()
        .or_else(|| infer_body_frame(&scan.tf, camera_frames));
    let roots = scan.tf.roots();
    let world = options
        .world_frame
        .clone()
        .or_else(|| {
            ["map", "world", "odom"]
                .iter()
                .find(|f| roots.contains(**f))
                .map(|s| s.to_string())
        })
        .or_else(|| roots.iter().next().map(|s| s.to_string()));
    if let (Some(body), Some(world)) = (body, world)
        && let Some(t) = scan.tf.trajectory(&world, &body, max_gap_ns)
        && !t.is_empty()
    {
        return Ok(t);
    }
    let hint = if scan.tf.is_empty() {
        String::new()
    } else {
        format!(
            " (/tf has frames {} but no time-varying chain from the world frame to the body; set {} and {})",
            scan.tf.frames().into_iter().collect::<Vec<_>>().join(", "),
            keys::WORLD_FRAME,
            keys::BODY_FRAME
        )
    };
    Err(IngestError::NoPoses {
        path: options.flight.clone(),
        hint,
    })
}

/// `base_link` when the tree has it, else the top of the camera's static chain.
fn infer_body_frame(tf: &TransformTree, camera_frames: &BTreeSet<String>) -> Option<String> {
    if tf.frames().contains("base_link") {
        return Some("base_link".into());
    }
    let camera = camera_frames.iter().next()?;
    let mut frame = camera.clone();
    // Climb while the link is fixed: the body is where the moving part starts.
    while !tf.is_dynamic(&frame) {
        match tf.parent(&frame) {
            Some(p) => frame = p.to_string(),
            None => break,
        }
    }
    Some(frame)
}

fn cameras(
    options: &IngestOptions,
    scan: &Scan,
    trajectory: &Trajectory,
    warnings: &mut Vec<String>,
) -> Result<Vec<Camera>, IngestError> {
    let file_intrinsics = options
        .camera_info_file
        .as_deref()
        .map(calibration::from_calibration_file)
        .transpose()?;
    let mut first_frame: BTreeMap<&str, &Frame> = BTreeMap::new();
    for f in &scan.frames {
        first_frame.entry(f.topic.as_str()).or_insert(f);
    }
    let mut frame_topics: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    for (topic, f) in &first_frame {
        frame_topics
            .entry(f.frame_id.as_str())
            .or_default()
            .push(topic);
    }
    for (frame, topics) in &frame_topics {
        if topics.len() > 1 {
            warnings.push(format!(
                "image topics {} share the camera frame {frame:?} (raw and compressed copies?); select one with {}",
                topics.join(", "),
                keys::IMAGE_TOPICS
            ));
        }
    }
    let t0 = trajectory.time_span().map(|s| s.0).unwrap_or_default();
    let mut cameras = Vec::new();
    for (topic, frame) in first_frame {
        let (intrinsics, source) = match (
            &file_intrinsics,
            match_camera_info(topic, &frame.frame_id, scan),
        ) {
            (Some(i), recorded) => {
                if let Some((t, _)) = recorded {
                    warnings.push(format!(
                        "{topic}: using intrinsics from {} instead of the recorded {t}",
                        options
                            .camera_info_file
                            .as_deref()
                            .unwrap_or(Path::new(""))
                            .display()
                    ));
                }
                let source = format!(
                    "file {}",
                    options
                        .camera_info_file
                        .as_deref()
                        .unwrap_or(Path::new(""))
                        .display()
                );
                (i.clone(), source)
            }
            (None, Some((t, info))) => {
                let i = calibration::from_camera_info(info).map_err(|why| {
                    IngestError::Calibration {
                        path: options.flight.clone(),
                        why: format!(
                            "CameraInfo on {t}: {why}; pass a calibration file as {}",
                            keys::CAMERA_INFO_FILE
                        ),
                    }
                })?;
                (i, format!("topic {t}"))
            }
            (None, None) => {
                return Err(IngestError::NoIntrinsics {
                    path: options.flight.clone(),
                    topic: topic.to_string(),
                    frame_id: frame.frame_id.clone(),
                });
            }
        };
        if let (Some(w), Some(h)) = (frame.width, frame.height)
            && (w, h) != (intrinsics.width, intrinsics.height)
        {
            warnings.push(format!(
                "{topic}: images are {w}x{h} but the intrinsics are for {}x{}",
                intrinsics.width, intrinsics.height
            ));
        }
        let extrinsic = extrinsic(&scan.tf, &trajectory.child_frame_id, &frame.frame_id, t0);
        if extrinsic.is_none() {
            warnings.push(format!(
                "{topic}: no transform from body frame {:?} to camera frame {:?} in /tf_static or /tf; its frames have no pose",
                trajectory.child_frame_id, frame.frame_id
            ));
        }
        cameras.push(Camera {
            topic: topic.to_string(),
            frame_id: frame.frame_id.clone(),
            intrinsics: Some(intrinsics),
            intrinsics_source: Some(source),
            extrinsic,
            body_frame: trajectory.child_frame_id.clone(),
        });
    }
    Ok(cameras)
}

/// The CameraInfo for an image topic: the same frame, else the same namespace,
/// else the only one recorded.
fn match_camera_info<'a>(
    topic: &str,
    frame_id: &str,
    scan: &'a Scan,
) -> Option<(&'a str, &'a msg::CameraInfo)> {
    let infos = &scan.camera_infos;
    infos
        .iter()
        .find(|(_, i)| !frame_id.is_empty() && i.header.frame_id == frame_id)
        .or_else(|| {
            let ns = camera_namespace(topic);
            infos.iter().find(|(t, _)| camera_namespace(t) == ns)
        })
        .or_else(|| (infos.len() == 1).then(|| infos.iter().next()).flatten())
        .map(|(t, i)| (t.as_str(), i))
}

fn extrinsic(tf: &TransformTree, body: &str, camera: &str, time_ns: i64) -> Option<Isometry3<f64>> {
    if body == camera {
        return Some(Isometry3::identity());
    }
    tf.lookup(body, camera, time_ns, i64::MAX).ok()
}

/// Give each frame its index and its camera pose, or the reason it has none.
fn place_frames(
    frames: &mut [Frame],
    trajectory: &Trajectory,
    tf: &TransformTree,
    max_gap_ns: i64,
) {
    let body = trajectory.child_frame_id.as_str();
    for (i, f) in frames.iter_mut().enumerate() {
        f.index = i as u32;
        let body_pose = match trajectory.at(f.time_ns, max_gap_ns) {
            PoseAt::Pose(p) => p,
            PoseAt::BeforeStart => {
                f.pose_status = PoseStatus::BeforeTrajectory;
                continue;
            }
            PoseAt::AfterEnd => {
                f.pose_status = PoseStatus::AfterTrajectory;
                continue;
            }
            PoseAt::InGap { .. } => {
                f.pose_status = PoseStatus::PoseGap;
                continue;
            }
        };
        // Looked up per frame so a moving gimbal on /tf is followed.
        match if body == f.frame_id {
            Some(Isometry3::identity())
        } else {
            tf.lookup(body, &f.frame_id, f.time_ns, max_gap_ns).ok()
        } {
            Some(e) => {
                f.camera_pose = Some(body_pose * e);
                f.pose_status = PoseStatus::Ok;
            }
            None => f.pose_status = PoseStatus::NoExtrinsic,
        }
    }
}

fn recorded_map(
    recording: &Recording,
    scan: &Scan,
    warnings: &mut Vec<String>,
) -> Option<RecordedMap> {
    let mut candidates: Vec<(&String, &MessageLocation)> = scan.clouds.iter().collect();
    // A topic named like a map wins over, say, a raw lidar scan.
    candidates.sort_by_key(|(t, _)| !t.contains("map"));
    let (topic, location) = candidates.first()?;
    let decoded = recording
        .read_message(**location)
        .map_err(|e| e.to_string())
        .and_then(|payload| cdr::decode::<msg::PointCloud2>(&payload).map_err(|e| e.to_string()))
        .and_then(|m| pointcloud2::decode(&m));
    match decoded {
        Ok(cloud) => {
            let (lo, hi) = cloud
                .bounds()
                .unwrap_or((Point3::origin(), Point3::origin()));
            Some(RecordedMap {
                topic: topic.to_string(),
                frame_id: cloud.frame_id.clone(),
                points: cloud.len() as u64,
                bounds: [[lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]],
                location: **location,
            })
        }
        Err(e) => {
            warnings.push(format!("map on {topic} could not be read: {e}"));
            None
        }
    }
}

fn write_outputs(
    out: &Path,
    frames: &[Frame],
    trajectory: &Trajectory,
    cameras: &[Camera],
    summary: &IngestSummary,
) -> Result<(), IngestError> {
    let run = RunDir::create(out)?;
    run.remove(files::SUMMARY)?;
    outputs::write_frames(&run, frames)?;
    outputs::write_trajectory(&run, trajectory)?;
    run.write_json(files::CAMERAS, &cameras)?;
    run.write_json(files::SUMMARY, summary)?;
    Ok(())
}
