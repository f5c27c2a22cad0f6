//! What the ingest stage writes: `frames.parquet` and `trajectory.parquet`
//! (one row per frame or pose, laid out for polars, pandas and DuckDB: flat
//! columns, ROS quaternion order, nanosecond times), `cameras.json` and its
//! summary `ingest.json`.

use std::collections::BTreeMap;
use std::path::PathBuf;

use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::frame::{Frame, ImageEncoding, ImageLocation, ImageStatus, MessageLocation, PoseStatus};
use crate::geo::{GeoAlignment, GeoOrigin, Geodetic};
use crate::pose::{StampedPose, from_parts_xyzw, quaternion_xyzw};
use crate::run_dir::RunDir;
use crate::similarity::Similarity;
use crate::trajectory::Trajectory;

/// Files of the ingest stage.
pub mod files {
    pub const FRAMES: &str = "frames.parquet";
    pub const TRAJECTORY: &str = "trajectory.parquet";
    pub const CAMERAS: &str = "cameras.json";
    pub const GNSS: &str = "gnss.parquet";
    pub const SUMMARY: &str = "ingest.json";
}

/// Messages on one topic.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct TopicSummary {
    pub schema: String,
    pub count: u64,
    /// How its messages are serialised: `cdr` (ROS 2) or `ros1`.
    #[serde(default = "cdr")]
    pub encoding: String,
    /// The ROS 1 message definition of topics later stages read again
    /// (images, the map): decoding them needs it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub definition: Option<String>,
}

fn cdr() -> String {
    "cdr".to_string()
}

/// Where the poses came from.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PoseSource {
    /// Topic, or `/tf`.
    pub topic: String,
    pub frame_id: String,
    pub child_frame_id: String,
}

impl PoseSource {
    /// Where `trajectory`'s poses came from.
    pub fn of(trajectory: &crate::Trajectory) -> Self {
        Self {
            topic: trajectory.source.clone(),
            frame_id: trajectory.frame_id.clone(),
            child_frame_id: trajectory.child_frame_id.clone(),
        }
    }
}

/// The SLAM map found in the recording.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RecordedMap {
    pub topic: String,
    pub frame_id: String,
    pub points: u64,
    /// Axis-aligned bounds `[min, max]`.
    pub bounds: [[f64; 3]; 2],
    /// The (last) map message, for loading it again.
    pub location: MessageLocation,
}

/// One recording of the flight (a sortie's MCAP or bag, or one drone's):
/// what it held and where its messages are.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RecordingSummary {
    pub path: PathBuf,
    pub size_bytes: u64,
    /// Messages per topic.
    pub messages: BTreeMap<String, TopicSummary>,
    pub frames: u64,
    pub poses: u64,
    pub pose_source: PoseSource,
    /// Span of its messages (log time).
    pub start_time_ns: i64,
    pub end_time_ns: i64,
    pub truncated: bool,
    pub truncated_at_byte: Option<u64>,
    pub corrupt_chunks: u64,
    /// The SLAM map recorded in it, if any (in its own SLAM frame).
    pub map: Option<RecordedMap>,
    /// Where its SLAM frame is in the run's map frame.
    #[serde(default)]
    pub placement: Placement,
    /// Read from the run directory's copy of an earlier ingest of the same
    /// file with the same settings, not from the file again.
    #[serde(default)]
    pub reused: bool,
    /// A photo folder's photos (none for a recording).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub photos: Option<PhotoFolderSummary>,
}

/// A photo folder as a recording: its photos, those it skipped, and the
/// frame they are posed in.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PhotoFolderSummary {
    /// JPEG files in the folder.
    pub photos: u64,
    /// Photos placed by a fixed RTK solution (DJI's `RtkFlag` 50).
    pub rtk_fixed: u64,
    /// Photos posed by the reconstruction (the others by their tags).
    #[serde(default)]
    pub reconstructed: u64,
    /// Photos that could not be posed, each with why.
    pub skipped: Vec<SkippedPhoto>,
    /// The east-north-up frame the photos are posed in.
    pub origin: GeoOrigin,
}

/// A photogrammetry reconstruction that posed the photos.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ReconstructionSummary {
    pub path: PathBuf,
    pub format: ReconstructionFormat,
    /// Its registered images.
    pub images: u64,
    /// The run's photos it posed (matched by file name).
    pub posed: u64,
    pub points: u64,
    /// Where its frame is in the run's map frame.
    pub similarity: Similarity,
    pub placed_by: ReconstructionPlacedBy,
}

/// Which software wrote a reconstruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReconstructionFormat {
    /// COLMAP's `cameras`, `images`, `points3D` (`.txt` or `.bin`).
    Colmap,
    /// OpenSfM's (and OpenDroneMap's) `reconstruction.json`.
    #[serde(rename = "opensfm")]
    OpenSfm,
}

/// How a reconstruction's frame was put into the run's map frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum ReconstructionPlacedBy {
    /// Its own reference on the Earth (OpenSfM's `reference_lla`).
    Reference,
    /// The similarity putting its cameras on the photos' GPS positions.
    GpsFit {
        /// Photos fitted.
        photos: usize,
        /// RMS distance of its cameras from the photos' positions, metres.
        rms_m: f64,
    },
}

/// A photo left out of the flight.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SkippedPhoto {
    pub photo: String,
    pub why: String,
}

/// Where a recording's SLAM frame is in the run's map frame (the frame of
/// the first recording with a map), and how that was found. Its poses and
/// frames in the run's tables are already moved there; its map is moved
/// when read ([`Placement::transform`]).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Placement {
    /// `T_run_recording`: a point `p` of the recording's SLAM frame is at
    /// `transform * p` in the run's map frame.
    #[serde(with = "crate::serde_pose")]
    pub transform: Isometry3<f64>,
    pub by: PlacedBy,
}

impl Default for Placement {
    fn default() -> Self {
        Self {
            transform: Isometry3::identity(),
            by: PlacedBy::Reference,
        }
    }
}

/// How a recording's SLAM frame was put into the run's map frame.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum PlacedBy {
    /// Its map frame is the run's: the first recording with a map (or the
    /// first recording, when none has one).
    Reference,
    /// In the reference's SLAM frame: it has no map of its own, or its map
    /// already lies on the reference's (one SLAM session across
    /// batteries).
    SharedFrame,
    /// Its map registered onto the reference's (a SLAM session of its own).
    Registered {
        /// Point-to-plane residual of the registration, RMS, metres.
        rms_m: f64,
        /// Share of its map on the reference's.
        overlap: f64,
    },
    /// Where the settings put it (`[ingest] recording_frame`).
    Given,
    /// By its GPS fixes and the reference's: each recording's frame fitted
    /// to the Earth, one placed on the other (a drone with a camera and
    /// odometry but no map).
    Gps {
        /// The two fits' RMS distances from their fixes, metres, added.
        rms_m: f64,
        /// Its fixes used.
        fixes: usize,
    },
}

impl RecordingSummary {
    /// Span of its messages, seconds.
    pub fn duration_s(&self) -> f64 {
        (self.end_time_ns - self.start_time_ns) as f64 * 1e-9
    }

    /// Its file name, as the report and warnings name it.
    pub fn name(&self) -> String {
        self.path.file_name().map_or_else(
            || self.path.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        )
    }
}

/// `ingest.json`: what the recordings held and what ingest made of them.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct IngestSummary {
    pub postflight_version: String,
    /// The flight's recordings, in the order given; frames, cameras and
    /// poses name theirs by its place here.
    pub recordings: Vec<RecordingSummary>,
    pub frames: u64,
    pub frames_with_pose: u64,
    /// Frames per `pose_status`.
    pub frames_by_pose_status: BTreeMap<PoseStatus, u64>,
    pub image_topics: Vec<String>,
    pub poses: u64,
    /// Time flown: the recordings' spans added up, seconds (battery
    /// changes between sorties do not count).
    pub duration_s: f64,
    /// From the first recording's start to the last one's end.
    pub start_time: String,
    pub end_time: String,
    pub start_time_ns: i64,
    pub end_time_ns: i64,
    pub max_pose_gap_s: f64,
    /// The map frame on the Earth, from the GPS fixes aligned to the
    /// trajectory (none without fixes).
    #[serde(default)]
    pub geo_origin: Option<GeoAlignment>,
    /// The reconstruction that posed the photos, if one was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reconstruction: Option<ReconstructionSummary>,
    pub warnings: Vec<String>,
}

impl IngestSummary {
    /// Whether any recording was cut short.
    pub fn truncated(&self) -> bool {
        self.recordings.iter().any(|r| r.truncated)
    }

    /// The recordings' file names, comma-separated.
    pub fn recording_names(&self) -> String {
        let names: Vec<String> = self.recordings.iter().map(RecordingSummary::name).collect();
        names.join(", ")
    }
}

crate::table! {
    /// A pose's columns: position, then ROS quaternion order; null for no pose.
    pub struct PoseColumns {
        x: Option<f64>,
        y: Option<f64>,
        z: Option<f64>,
        qx: Option<f64>,
        qy: Option<f64>,
        qz: Option<f64>,
        qw: Option<f64>,
    }
}

impl PoseColumns {
    fn of(pose: Option<&Isometry3<f64>>) -> Self {
        let [x, y, z, qx, qy, qz, qw] = pose.map_or([None; 7], |p| {
            let t = p.translation.vector;
            let q = quaternion_xyzw(p);
            [t.x, t.y, t.z, q[0], q[1], q[2], q[3]].map(Some)
        });
        Self {
            x,
            y,
            z,
            qx,
            qy,
            qz,
            qw,
        }
    }

    fn pose(&self) -> Option<Isometry3<f64>> {
        from_parts_xyzw(
            [self.x?, self.y?, self.z?],
            [self.qx?, self.qy?, self.qz?, self.qw?],
        )
    }
}

/// A satellite navigation fix as recorded (`sensor_msgs/NavSatFix`: GPS,
/// as DJI's SDK publishes it), for placing the map frame on the Earth.
#[derive(Debug, Clone, PartialEq)]
pub struct GnssFix {
    /// The recording it is in.
    pub recording: u16,
    /// `header.stamp` (else the log time).
    pub time_ns: i64,
    pub topic: String,
    /// Where: altitude above the WGS 84 ellipsoid.
    pub position: Geodetic,
    /// The fix status: -1 no fix, 0 fix, 1 SBAS, 2 GBAS (RTK).
    pub status: i8,
}

crate::table! {
    /// One row of `gnss.parquet`: a fix.
    pub struct GnssRow {
        recording: u16,
        time_ns: i64,
        topic: String,
        latitude_deg: f64,
        longitude_deg: f64,
        altitude_m: f64,
        status: i8,
    }
}

/// Write `gnss.parquet`: every fix, in time order (no rows without GPS).
pub fn write_gnss(run: &RunDir, fixes: &[GnssFix]) -> Result<(), Error> {
    let rows: Vec<GnssRow> = fixes
        .iter()
        .map(|f| GnssRow {
            recording: f.recording,
            time_ns: f.time_ns,
            topic: f.topic.clone(),
            latitude_deg: f.position.latitude_deg,
            longitude_deg: f.position.longitude_deg,
            altitude_m: f.position.altitude_m,
            status: f.status,
        })
        .collect();
    run.write_rows(files::GNSS, &rows)
}

/// Read `gnss.parquet`.
pub fn read_gnss(run: &RunDir) -> Result<Vec<GnssFix>, Error> {
    let rows: Vec<GnssRow> = run.read_rows(files::GNSS)?;
    Ok(rows
        .into_iter()
        .map(|r| GnssFix {
            recording: r.recording,
            time_ns: r.time_ns,
            topic: r.topic,
            position: Geodetic {
                latitude_deg: r.latitude_deg,
                longitude_deg: r.longitude_deg,
                altitude_m: r.altitude_m,
            },
            status: r.status,
        })
        .collect())
}

crate::table! {
    /// One row of `frames.parquet`: an image. The pose is the camera's
    /// optical frame in the world, null when `pose_status` is not `ok`.
    pub struct FrameRow {
        frame: u32,
        recording: u16,
        time_ns: i64,
        log_time_ns: i64,
        topic: String,
        frame_id: String,
        width: Option<u32>,
        height: Option<u32>,
        encoding: ImageEncoding,
        has_pose: bool,
        pose_status: PoseStatus,
        image_status: ImageStatus,
        pose: PoseColumns,
        exposure_s: Option<f64>,
        /// How far off the camera's position may be, metres (a photo's RTK
        /// accuracy); null where the source does not say.
        position_std_m: Option<f64>,
        /// Where its message is in the recording (null for a photo).
        chunk_offset: Option<u64>,
        record_offset: Option<u64>,
        /// The photo's file name in its folder (null for a message).
        photo: Option<String>,
    }
}

impl FrameRow {
    fn of(f: &Frame) -> Self {
        let (chunk_offset, record_offset, photo) = match &f.location {
            ImageLocation::Message(m) => (m.chunk_offset, Some(m.record_offset), None),
            ImageLocation::Photo(name) => (None, None, Some(name.clone())),
        };
        Self {
            frame: f.index,
            recording: f.recording,
            time_ns: f.time_ns,
            log_time_ns: f.log_time_ns,
            topic: f.topic.clone(),
            frame_id: f.frame_id.clone(),
            width: f.width,
            height: f.height,
            encoding: f.encoding.clone(),
            has_pose: f.camera_pose.is_some(),
            pose_status: f.pose_status,
            image_status: f.image_status,
            pose: PoseColumns::of(f.camera_pose.as_ref()),
            exposure_s: f.exposure_s,
            position_std_m: f.position_std_m,
            chunk_offset,
            record_offset,
            photo,
        }
    }

    fn frame(self) -> Frame {
        Frame {
            index: self.frame,
            recording: self.recording,
            time_ns: self.time_ns,
            log_time_ns: self.log_time_ns,
            camera_pose: self.pose.pose(),
            topic: self.topic,
            frame_id: self.frame_id,
            width: self.width,
            height: self.height,
            encoding: self.encoding,
            pose_status: self.pose_status,
            image_status: self.image_status,
            location: match self.photo {
                Some(name) => ImageLocation::Photo(name),
                None => ImageLocation::Message(MessageLocation {
                    chunk_offset: self.chunk_offset,
                    record_offset: self.record_offset.unwrap_or_default(),
                }),
            },
            exposure_s: self.exposure_s,
            position_std_m: self.position_std_m,
        }
    }
}

crate::table! {
    /// One row of `trajectory.parquet`: a body's pose in the world frame
    /// (the body of the drone that flew the recording).
    pub struct TrajectoryRow {
        recording: u16,
        time_ns: i64,
        pose: PoseColumns,
        frame_id: String,
        child_frame_id: String,
        /// Where the poses came from: a topic, or `/tf`.
        source: String,
    }
}

/// Write `frames.parquet`.
pub fn write_frames(run: &RunDir, frames: &[Frame]) -> Result<(), Error> {
    let rows: Vec<FrameRow> = frames.iter().map(FrameRow::of).collect();
    run.write_rows(files::FRAMES, &rows)
}

/// Read `frames.parquet`.
pub fn read_frames(run: &RunDir) -> Result<Vec<Frame>, Error> {
    let rows: Vec<FrameRow> = run.read_rows(files::FRAMES)?;
    Ok(rows.into_iter().map(FrameRow::frame).collect())
}

/// Write `trajectory.parquet`: each recording's trajectory (one per
/// recording, in its order), in time order.
pub fn write_trajectories(run: &RunDir, trajectories: &[Trajectory]) -> Result<(), Error> {
    let mut rows = Vec::new();
    for (recording, t) in (0u16..).zip(trajectories) {
        rows.extend(t.poses().iter().map(|p| TrajectoryRow {
            recording,
            time_ns: p.time_ns,
            pose: PoseColumns::of(Some(&p.pose)),
            frame_id: t.frame_id.clone(),
            child_frame_id: t.child_frame_id.clone(),
            source: t.source.clone(),
        }));
    }
    run.write_rows(files::TRAJECTORY, &rows)
}

/// Read `trajectory.parquet`: one trajectory per recording of the flight
/// (`recordings` of them; empty for a recording without poses).
pub fn read_trajectories(run: &RunDir, recordings: usize) -> Result<Vec<Trajectory>, Error> {
    let rows: Vec<TrajectoryRow> = run.read_rows(files::TRAJECTORY)?;
    let mut by_recording: Vec<Vec<TrajectoryRow>> = (0..recordings).map(|_| Vec::new()).collect();
    for row in rows {
        let Some(list) = by_recording.get_mut(usize::from(row.recording)) else {
            return Err(Error::RunDir {
                path: run.path().join(files::TRAJECTORY),
                why: format!(
                    "a pose names recording {}, but ingest.json lists {recordings}; rerun `postflight ingest`",
                    row.recording
                ),
            });
        };
        list.push(row);
    }
    Ok(by_recording
        .into_iter()
        .map(|rows| trajectory(&rows))
        .collect())
}

/// A recording's rows as its trajectory.
fn trajectory(rows: &[TrajectoryRow]) -> Trajectory {
    let first =
        |get: fn(&TrajectoryRow) -> &String| rows.first().map(get).cloned().unwrap_or_default();
    let names = (
        first(|r| &r.frame_id),
        first(|r| &r.child_frame_id),
        first(|r| &r.source),
    );
    let poses = rows
        .iter()
        .filter_map(|r| {
            Some(StampedPose {
                time_ns: r.time_ns,
                pose: r.pose.pose()?,
            })
        })
        .collect();
    Trajectory::new(names.0, names.1, names.2, poses)
}
