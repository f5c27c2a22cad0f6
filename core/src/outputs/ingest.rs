//! What the ingest stage writes: `frames.parquet` and `trajectory.parquet`
//! (one row per frame or pose, laid out for polars, pandas and DuckDB: flat
//! columns, ROS quaternion order, nanosecond times), `cameras.json` and its
//! summary `ingest.json`.

use std::collections::BTreeMap;
use std::path::PathBuf;

use nalgebra::Isometry3;
use polars::prelude::*;
use serde::{Deserialize, Serialize};

use super::{parsed, required};
use crate::error::Error;
use crate::frame::{Frame, ImageStatus, MessageLocation, PoseStatus};
use crate::geo::{GeoAlignment, Geodetic};
use crate::pose::{StampedPose, from_parts_xyzw, quaternion_xyzw};
use crate::run_dir::RunDir;
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

/// The flight recording ingested.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FlightFile {
    pub path: PathBuf,
    pub size_bytes: u64,
}

/// `ingest.json`: what the recording held and what ingest made of it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct IngestSummary {
    pub postflight_version: String,
    pub flight: FlightFile,
    /// Messages per topic.
    pub messages: BTreeMap<String, TopicSummary>,
    pub frames: u64,
    pub frames_with_pose: u64,
    /// Frames per `pose_status`.
    pub frames_by_pose_status: BTreeMap<String, u64>,
    pub image_topics: Vec<String>,
    pub poses: u64,
    pub pose_source: PoseSource,
    /// Span of the recorded messages (log time), seconds.
    pub duration_s: f64,
    pub start_time: String,
    pub end_time: String,
    pub start_time_ns: i64,
    pub end_time_ns: i64,
    pub truncated: bool,
    pub truncated_at_byte: Option<u64>,
    pub corrupt_chunks: u64,
    pub map: Option<RecordedMap>,
    pub max_pose_gap_s: f64,
    /// The map frame on the Earth, from the GPS fixes aligned to the
    /// trajectory (none without fixes).
    #[serde(default)]
    pub geo_origin: Option<GeoAlignment>,
    pub warnings: Vec<String>,
}

const POSE_COLUMNS: [&str; 7] = ["x", "y", "z", "qx", "qy", "qz", "qw"];

fn pose_columns<'a>(poses: impl Iterator<Item = Option<&'a Isometry3<f64>>>) -> Vec<Column> {
    let mut values: [Vec<Option<f64>>; 7] = Default::default();
    for pose in poses {
        let row = pose.map(|p| {
            let t = p.translation.vector;
            let q = quaternion_xyzw(p);
            [t.x, t.y, t.z, q[0], q[1], q[2], q[3]]
        });
        for (k, column) in values.iter_mut().enumerate() {
            column.push(row.map(|r| r[k]));
        }
    }
    POSE_COLUMNS
        .iter()
        .zip(values)
        .map(|(name, v)| Column::new((*name).into(), v))
        .collect()
}

fn read_poses(df: &DataFrame) -> PolarsResult<Vec<Option<Isometry3<f64>>>> {
    let cols: Vec<&Float64Chunked> = POSE_COLUMNS
        .iter()
        .map(|n| df.column(n).and_then(|c| c.f64()))
        .collect::<PolarsResult<_>>()?;
    Ok((0..df.height())
        .map(|i| {
            let v: Option<Vec<f64>> = cols.iter().map(|c| c.get(i)).collect();
            let v = v?;
            from_parts_xyzw([v[0], v[1], v[2]], [v[3], v[4], v[5], v[6]])
        })
        .collect())
}

/// A satellite navigation fix as recorded (`sensor_msgs/NavSatFix`: GPS,
/// as DJI's SDK publishes it), for placing the map frame on the Earth.
#[derive(Debug, Clone, PartialEq)]
pub struct GnssFix {
    /// `header.stamp` (else the log time).
    pub time_ns: i64,
    pub topic: String,
    /// Where: altitude above the WGS 84 ellipsoid.
    pub position: Geodetic,
    /// The fix status: -1 no fix, 0 fix, 1 SBAS, 2 GBAS (RTK).
    pub status: i8,
}

/// Write `gnss.parquet`: every fix, in time order (no rows without GPS).
pub fn write_gnss(run: &RunDir, fixes: &[GnssFix]) -> Result<(), Error> {
    run.write_table(files::GNSS, gnss_table(fixes))
}

/// Read `gnss.parquet`.
pub fn read_gnss(run: &RunDir) -> Result<Vec<GnssFix>, Error> {
    run.read_table(files::GNSS, gnss_from)
}

fn gnss_table(fixes: &[GnssFix]) -> PolarsResult<DataFrame> {
    let f64s = |name: &str, get: fn(&GnssFix) -> f64| {
        Column::new(name.into(), fixes.iter().map(get).collect::<Vec<f64>>())
    };
    let columns = vec![
        Column::new(
            "time_ns".into(),
            fixes.iter().map(|f| f.time_ns).collect::<Vec<i64>>(),
        ),
        Column::new(
            "topic".into(),
            fixes
                .iter()
                .map(|f| f.topic.as_str())
                .collect::<Vec<&str>>(),
        ),
        f64s("latitude_deg", |f| f.position.latitude_deg),
        f64s("longitude_deg", |f| f.position.longitude_deg),
        f64s("altitude_m", |f| f.position.altitude_m),
        Column::new(
            "status".into(),
            // Int32: the fewest polars features (the status is an int8).
            fixes
                .iter()
                .map(|f| i32::from(f.status))
                .collect::<Vec<i32>>(),
        ),
    ];
    DataFrame::new(fixes.len(), columns)
}

fn gnss_from(df: &DataFrame) -> PolarsResult<Vec<GnssFix>> {
    let time = df.column("time_ns")?.i64()?;
    let topic = df.column("topic")?.str()?;
    let f64s = |name: &str| df.column(name).and_then(|c| c.f64().cloned());
    let (lat, lon, alt) = (
        f64s("latitude_deg")?,
        f64s("longitude_deg")?,
        f64s("altitude_m")?,
    );
    let status = df.column("status")?.i32()?;
    (0..df.height())
        .map(|i| {
            Ok(GnssFix {
                time_ns: required(time, i)?,
                topic: required(topic, i)?.to_string(),
                position: Geodetic {
                    latitude_deg: required(&lat, i)?,
                    longitude_deg: required(&lon, i)?,
                    altitude_m: required(&alt, i)?,
                },
                status: i8::try_from(required(status, i)?)
                    .map_err(|_| polars_err!(ComputeError: "status in row {i} is not an int8"))?,
            })
        })
        .collect()
}

/// Write `frames.parquet`.
pub fn write_frames(run: &RunDir, frames: &[Frame]) -> Result<(), Error> {
    run.write_table(files::FRAMES, frames_table(frames))
}

/// Read `frames.parquet`.
pub fn read_frames(run: &RunDir) -> Result<Vec<Frame>, Error> {
    run.read_table(files::FRAMES, frames_from)
}

/// Write `trajectory.parquet`.
pub fn write_trajectory(run: &RunDir, trajectory: &Trajectory) -> Result<(), Error> {
    run.write_table(files::TRAJECTORY, trajectory_table(trajectory))
}

/// Read `trajectory.parquet`.
pub fn read_trajectory(run: &RunDir) -> Result<Trajectory, Error> {
    run.read_table(files::TRAJECTORY, trajectory_from)
}

/// `frames.parquet`: one row per image. The pose columns are the camera's
/// optical frame in the world, null when `pose_status` is not `ok`.
fn frames_table(frames: &[Frame]) -> PolarsResult<DataFrame> {
    let mut columns = vec![
        Column::new(
            "frame".into(),
            frames.iter().map(|f| f.index).collect::<Vec<u32>>(),
        ),
        Column::new(
            "time_ns".into(),
            frames.iter().map(|f| f.time_ns).collect::<Vec<i64>>(),
        ),
        Column::new(
            "log_time_ns".into(),
            frames.iter().map(|f| f.log_time_ns).collect::<Vec<i64>>(),
        ),
        Column::new(
            "topic".into(),
            frames
                .iter()
                .map(|f| f.topic.as_str())
                .collect::<Vec<&str>>(),
        ),
        Column::new(
            "frame_id".into(),
            frames
                .iter()
                .map(|f| f.frame_id.as_str())
                .collect::<Vec<&str>>(),
        ),
        Column::new(
            "width".into(),
            frames.iter().map(|f| f.width).collect::<Vec<Option<u32>>>(),
        ),
        Column::new(
            "height".into(),
            frames
                .iter()
                .map(|f| f.height)
                .collect::<Vec<Option<u32>>>(),
        ),
        Column::new(
            "encoding".into(),
            frames
                .iter()
                .map(|f| f.encoding.as_str())
                .collect::<Vec<&str>>(),
        ),
        Column::new(
            "has_pose".into(),
            frames
                .iter()
                .map(|f| f.camera_pose.is_some())
                .collect::<Vec<bool>>(),
        ),
        Column::new(
            "pose_status".into(),
            frames
                .iter()
                .map(|f| f.pose_status.as_str())
                .collect::<Vec<&str>>(),
        ),
        Column::new(
            "image_status".into(),
            frames
                .iter()
                .map(|f| f.image_status.as_str())
                .collect::<Vec<&str>>(),
        ),
    ];
    columns.extend(pose_columns(frames.iter().map(|f| f.camera_pose.as_ref())));
    columns.push(Column::new(
        "exposure_s".into(),
        frames
            .iter()
            .map(|f| f.exposure_s)
            .collect::<Vec<Option<f64>>>(),
    ));
    columns.push(Column::new(
        "chunk_offset".into(),
        frames
            .iter()
            .map(|f| f.location.chunk_offset)
            .collect::<Vec<Option<u64>>>(),
    ));
    columns.push(Column::new(
        "record_offset".into(),
        frames
            .iter()
            .map(|f| f.location.record_offset)
            .collect::<Vec<u64>>(),
    ));
    DataFrame::new(frames.len(), columns)
}

fn frames_from(df: &DataFrame) -> PolarsResult<Vec<Frame>> {
    let index = df.column("frame")?.u32()?;
    let time = df.column("time_ns")?.i64()?;
    let log_time = df.column("log_time_ns")?.i64()?;
    let topic = df.column("topic")?.str()?;
    let frame_id = df.column("frame_id")?.str()?;
    let width = df.column("width")?.u32()?;
    let height = df.column("height")?.u32()?;
    let encoding = df.column("encoding")?.str()?;
    let pose_status = df.column("pose_status")?.str()?;
    let image_status = df.column("image_status")?.str()?;
    let chunk = df.column("chunk_offset")?.u64()?;
    let record = df.column("record_offset")?.u64()?;
    let exposure = df.column("exposure_s")?.f64()?;
    let poses = read_poses(df)?;
    (0..df.height())
        .map(|i| {
            Ok(Frame {
                index: required(index, i)?,
                time_ns: required(time, i)?,
                log_time_ns: required(log_time, i)?,
                topic: required(topic, i)?.to_string(),
                frame_id: frame_id.get(i).unwrap_or_default().to_string(),
                width: width.get(i),
                height: height.get(i),
                encoding: encoding.get(i).unwrap_or_default().to_string(),
                camera_pose: poses[i],
                pose_status: parsed(pose_status, i, PoseStatus::parse)?,
                image_status: parsed(image_status, i, ImageStatus::parse)?,
                location: MessageLocation {
                    chunk_offset: chunk.get(i),
                    record_offset: required(record, i)?,
                },
                exposure_s: exposure.get(i),
            })
        })
        .collect()
}

/// `trajectory.parquet`: the body pose in the world frame over time.
fn trajectory_table(t: &Trajectory) -> PolarsResult<DataFrame> {
    let poses = t.poses();
    let mut columns = vec![Column::new(
        "time_ns".into(),
        poses.iter().map(|p| p.time_ns).collect::<Vec<i64>>(),
    )];
    columns.extend(pose_columns(poses.iter().map(|p| Some(&p.pose))));
    columns.push(Column::new(
        "frame_id".into(),
        vec![t.frame_id.as_str(); poses.len()],
    ));
    columns.push(Column::new(
        "child_frame_id".into(),
        vec![t.child_frame_id.as_str(); poses.len()],
    ));
    columns.push(Column::new(
        "source".into(),
        vec![t.source.as_str(); poses.len()],
    ));
    DataFrame::new(poses.len(), columns)
}

fn trajectory_from(df: &DataFrame) -> PolarsResult<Trajectory> {
    let time = df.column("time_ns")?.i64()?;
    let first = |c: &str| -> PolarsResult<String> {
        Ok(df.column(c)?.str()?.get(0).unwrap_or_default().to_string())
    };
    let poses = read_poses(df)?
        .into_iter()
        .zip((0..df.height()).map(|i| time.get(i)))
        .filter_map(|(pose, time_ns)| {
            Some(StampedPose {
                time_ns: time_ns?,
                pose: pose?,
            })
        })
        .collect();
    Ok(Trajectory::new(
        first("frame_id")?,
        first("child_frame_id")?,
        first("source")?,
        poses,
    ))
}
