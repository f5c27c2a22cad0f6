//! Frames and trajectories as Parquet tables (one row per frame or pose),
//! laid out for polars, pandas and DuckDB: flat columns, ROS quaternion
//! order, nanosecond times.

use nalgebra::Isometry3;
use polars::prelude::*;

use crate::frame::{Frame, ImageStatus, PoseStatus};
use crate::pose::{StampedPose, from_parts_xyzw, quaternion_xyzw};
use crate::recording::MessageLocation;
use crate::trajectory::Trajectory;

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

/// `frames.parquet`: one row per image. The pose columns are the camera's
/// optical frame in the world, null when `pose_status` is not `ok`.
pub fn frames_to_table(frames: &[Frame]) -> PolarsResult<DataFrame> {
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

pub fn frames_from_table(df: &DataFrame) -> PolarsResult<Vec<Frame>> {
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
    let missing = |c: &str| polars_err!(ComputeError: "frames table has a null {c}");
    (0..df.height())
        .map(|i| {
            Ok(Frame {
                index: index.get(i).ok_or_else(|| missing("frame"))?,
                time_ns: time.get(i).ok_or_else(|| missing("time_ns"))?,
                log_time_ns: log_time.get(i).ok_or_else(|| missing("log_time_ns"))?,
                topic: topic.get(i).ok_or_else(|| missing("topic"))?.to_string(),
                frame_id: frame_id.get(i).unwrap_or_default().to_string(),
                width: width.get(i),
                height: height.get(i),
                encoding: encoding.get(i).unwrap_or_default().to_string(),
                camera_pose: poses[i],
                pose_status: pose_status
                    .get(i)
                    .and_then(PoseStatus::parse)
                    .ok_or_else(|| missing("pose_status"))?,
                image_status: image_status
                    .get(i)
                    .and_then(ImageStatus::parse)
                    .ok_or_else(|| missing("image_status"))?,
                location: MessageLocation {
                    chunk_offset: chunk.get(i),
                    record_offset: record.get(i).ok_or_else(|| missing("record_offset"))?,
                },
                exposure_s: exposure.get(i),
            })
        })
        .collect()
}

/// `trajectory.parquet`: the body pose in the world frame over time.
pub fn trajectory_to_table(t: &Trajectory) -> PolarsResult<DataFrame> {
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

pub fn trajectory_from_table(df: &DataFrame) -> PolarsResult<Trajectory> {
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
