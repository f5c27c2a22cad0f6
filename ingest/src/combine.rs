//! The recordings as one flight: frames in time order across recordings,
//! each recording's trajectory and cameras, one geo origin from every fix,
//! and the summary.

use std::collections::{BTreeMap, BTreeSet};

use postflight_core::outputs::ingest::{GnssFix, IngestSummary, RecordingSummary};
use postflight_core::time::rfc3339;
use postflight_core::{Camera, Frame, ImageStatus, PoseStatus, Trajectory};

use crate::earth::{geo_origin, photos_on_earth};
use crate::ingested::Ingested;
use crate::stage::IngestOptions;

/// What ingest writes, the recordings' together.
pub(crate) struct FlightTables {
    pub(crate) frames: Vec<Frame>,
    pub(crate) trajectories: Vec<Trajectory>,
    pub(crate) cameras: Vec<Camera>,
    pub(crate) fixes: Vec<GnssFix>,
}

/// The recordings as one flight: frames in time order across recordings,
/// each recording's trajectory and cameras, one geo origin from every fix,
/// and the summary.
pub(crate) fn combine(
    ingested: Vec<Ingested>,
    options: &IngestOptions,
    mut warnings: Vec<String>,
) -> (IngestSummary, FlightTables) {
    let several = ingested.len() > 1;
    // Photos alone are posed at their origin exactly; no fit needed.
    let photos_only = ingested
        .iter()
        .map(photos_on_earth)
        .collect::<Option<Vec<_>>>()
        .and_then(|all| all.into_iter().next());
    let mut tables = FlightTables {
        frames: Vec::new(),
        trajectories: Vec::new(),
        cameras: Vec::new(),
        fixes: Vec::new(),
    };
    let mut recordings = Vec::new();
    for one in ingested {
        let name = one.summary.name();
        // With several recordings, each warning names its own.
        warnings.extend(one.warnings.into_iter().map(|w| match several {
            true => format!("{name}: {w}"),
            false => w,
        }));
        tables.frames.extend(one.frames);
        tables.trajectories.push(one.trajectory);
        tables.cameras.extend(one.cameras);
        tables.fixes.extend(one.fixes);
        recordings.push(one.summary);
    }
    let frames = &mut tables.frames;
    frames.sort_by(|a, b| {
        (a.time_ns, a.recording, &a.topic).cmp(&(b.time_ns, b.recording, &b.topic))
    });
    for (i, f) in frames.iter_mut().enumerate() {
        f.index = i as u32;
    }
    let by_status = frames_by_pose_status(frames);
    warnings.extend(frame_warnings(frames, &by_status));
    tables.fixes.sort_by_key(|f| (f.time_ns, f.recording));
    let max_gap_ns = (options.settings.max_pose_gap_s * 1e9) as i64;
    let geo_origin = match photos_only {
        Some(origin) => Some(origin),
        None => geo_origin(
            &tables.fixes,
            &tables.trajectories,
            max_gap_ns,
            &mut warnings,
        ),
    };
    let start = recordings
        .iter()
        .map(|r| r.start_time_ns)
        .min()
        .unwrap_or(0);
    let end = recordings.iter().map(|r| r.end_time_ns).max().unwrap_or(0);
    let summary = IngestSummary {
        postflight_version: env!("CARGO_PKG_VERSION").to_string(),
        frames: frames.len() as u64,
        frames_with_pose: frames.iter().filter(|f| f.camera_pose.is_some()).count() as u64,
        frames_by_pose_status: by_status,
        image_topics: frames
            .iter()
            .map(|f| f.topic.clone())
            .collect::<BTreeSet<_>>()
            .into_iter()
            .collect(),
        poses: recordings.iter().map(|r| r.poses).sum(),
        duration_s: recordings.iter().map(RecordingSummary::duration_s).sum(),
        start_time: rfc3339(start),
        end_time: rfc3339(end),
        start_time_ns: start,
        end_time_ns: end,
        max_pose_gap_s: options.settings.max_pose_gap_s,
        geo_origin,
        reconstruction: None,
        warnings,
        recordings,
    };
    (summary, tables)
}

/// Frames per `pose_status`.
pub(crate) fn frames_by_pose_status(frames: &[Frame]) -> BTreeMap<PoseStatus, u64> {
    let mut by_status = BTreeMap::new();
    for f in frames {
        *by_status.entry(f.pose_status).or_default() += 1;
    }
    by_status
}

/// What the summary says of frames without a pose or a readable image.
pub(crate) fn frame_warnings(
    frames: &[Frame],
    by_status: &BTreeMap<PoseStatus, u64>,
) -> Vec<String> {
    let mut warnings = Vec::new();
    let without_pose = frames.len() as u64 - by_status.get(&PoseStatus::Ok).copied().unwrap_or(0);
    if without_pose > 0 {
        let detail: Vec<String> = by_status
            .iter()
            .filter(|(k, _)| **k != PoseStatus::Ok)
            .map(|(k, v)| format!("{v} {}", k.as_str()))
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
    warnings
}
