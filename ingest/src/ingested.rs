//! One recording ingested: one pass over it, its frames placed on its own
//! trajectory, its cameras, fixes and recorded map, and what the pass
//! found damaged.

use std::collections::BTreeSet;

use nalgebra::{Isometry3, Point3};
use postflight_core::frame::camera_namespace;
use postflight_core::outputs::ingest::{
    GnssFix, Placement, PoseSource, RecordedMap, RecordingSummary,
};
use postflight_core::{Camera, Frame, MessageLocation, Trajectory};

use crate::cameras::cameras;
use crate::error::IngestError;
use crate::placement::{choose_trajectory, place_frames};
use crate::recording::{Recording, ScanEvent, ScanReport};
use crate::ros::{msg, pointcloud2};
use crate::scan::Scan;
use crate::stage::{IngestOptions, Progress};

/// One recording, ingested: its summary, its frames placed on its own
/// trajectory, its cameras and fixes.
pub(crate) struct Ingested {
    pub(crate) summary: RecordingSummary,
    pub(crate) frames: Vec<Frame>,
    pub(crate) trajectory: Trajectory,
    pub(crate) cameras: Vec<Camera>,
    pub(crate) fixes: Vec<GnssFix>,
    pub(crate) warnings: Vec<String>,
}

impl Ingested {
    /// Move its poses into the run's map frame.
    pub(crate) fn place(&mut self, placement: Placement) {
        let t = placement.transform;
        if t != Isometry3::identity() {
            for f in &mut self.frames {
                f.camera_pose = f.camera_pose.map(|p| t * p);
            }
            self.trajectory = std::mem::take(&mut self.trajectory).moved(&t);
        }
        self.summary.placement = placement;
    }
}

/// One pass over one recording, and its frames placed on its own
/// trajectory (a pose never comes from another sortie or drone).
pub(crate) fn ingest_one(
    index: u16,
    recording: &Recording,
    options: &IngestOptions,
    progress: &mut dyn Progress,
) -> Result<Ingested, IngestError> {
    let total = recording.len();
    let mut scan = Scan::default();
    let report = recording.scan(|event| match event {
        ScanEvent::Channel(c) => scan.channel(c, options),
        ScanEvent::Message(m) => scan.message(&m),
        ScanEvent::Progress { bytes } => progress.bytes(bytes, total),
    });
    scan.tf.finish();
    for f in &mut scan.frames {
        f.recording = index;
    }
    for f in &mut scan.fixes {
        f.recording = index;
    }
    let path = recording.path().to_owned();
    let messages = scan.topics();
    if report.truncated && options.settings.strict {
        return Err(IngestError::Truncated {
            path,
            offset: report.truncated_at.unwrap_or(total),
            salvaged: messages.values().map(|t| t.count).sum(),
        });
    }
    let mut warnings = damage_warnings(&report, &scan, total);
    let max_gap_ns = (options.settings.max_pose_gap_s * 1e9) as i64;
    let camera_frames: BTreeSet<String> = scan.frames.iter().map(|f| f.frame_id.clone()).collect();
    let trajectory = choose_trajectory(
        options,
        &path,
        &mut scan,
        &camera_frames,
        max_gap_ns,
        &mut warnings,
    );
    let (trajectory, cameras) = if scan.frames.is_empty() {
        // A recording without images (a mapping drone's) counts for its map.
        warnings.push("no camera images; read for its map and GPS only".to_string());
        (trajectory.unwrap_or_default(), Vec::new())
    } else {
        let trajectory = trajectory?;
        let cameras = cameras(options, &path, &scan, &trajectory, &mut warnings)?;
        (trajectory, cameras)
    };
    let mut frames = std::mem::take(&mut scan.frames);
    for f in &mut frames {
        let key = (camera_namespace(&f.topic).to_string(), f.log_time_ns);
        f.exposure_s = scan.exposures.get(&key).copied();
    }
    place_frames(&mut frames, &trajectory, &scan.tf, max_gap_ns);
    let map = recorded_map(recording, &scan, &mut warnings);
    if let Some(m) = &map
        && !m.frame_id.is_empty()
        && !trajectory.frame_id.is_empty()
        && m.frame_id != trajectory.frame_id
    {
        warnings.push(format!(
            "the map on {} is in frame {:?} but the poses are in {:?}; later stages assume they are the same frame",
            m.topic, m.frame_id, trajectory.frame_id
        ));
    }
    let fixes = std::mem::take(&mut scan.fixes);
    let (start, end) = scan.time_range.unwrap_or((0, 0));
    let summary = RecordingSummary {
        path: std::path::absolute(&path).unwrap_or(path),
        size_bytes: total,
        messages,
        frames: frames.len() as u64,
        poses: trajectory.len() as u64,
        pose_source: PoseSource::of(&trajectory),
        start_time_ns: start as i64,
        end_time_ns: end as i64,
        truncated: report.truncated,
        truncated_at_byte: report.truncated_at,
        corrupt_chunks: report.corrupt_chunks,
        map,
        placement: Placement::default(),
        reused: false,
        photos: None,
    };
    Ok(Ingested {
        summary,
        frames,
        trajectory,
        cameras,
        fixes,
        warnings,
    })
}

pub(crate) fn damage_warnings(report: &ScanReport, scan: &Scan, file_len: u64) -> Vec<String> {
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

/// Where the map recorded in a recording is, and what it holds.
pub(crate) fn recorded_map(
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
        .and_then(|payload| {
            scan.wire(topic)
                .decode::<msg::PointCloud2>(&payload)
                .map_err(|e| e.to_string())
        })
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
