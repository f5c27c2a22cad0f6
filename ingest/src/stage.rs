//! The ingest stage: one pass over each of a flight's recordings (one, or
//! one per sortie or drone), then the frames, trajectories, cameras and a
//! summary written into the run directory.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3};
use postflight_core::frame::camera_namespace;
use postflight_core::geo::{GeoAlignment, GeoOrigin, Geodetic};
use postflight_core::outputs::ingest::{
    self as outputs, GnssFix, IngestSummary, Placement, PoseSource, RecordedMap, RecordingSummary,
    TopicSummary, files,
};
use postflight_core::time::rfc3339;
use postflight_core::{
    Camera, Frame, ImageStatus, InvalidSetting, Key, MessageLocation, PoseAt, PoseStatus, RunDir,
    Trajectory,
};

use crate::cameras::cameras;
use crate::error::IngestError;
use crate::placement::{choose_trajectory, place_frames};
use crate::reconstruction::{Placed, Reconstruction};
use crate::recording::{Recording, ScanEvent, ScanReport};
use crate::reopen::recorded_map_of;
use crate::reuse;
use crate::ros::{msg, pointcloud2, schema};
use crate::scan::Scan;
use crate::settings::{IngestConfig, RecordingFrame, keys};
use crate::slam_frames::{self, RecordedFrame};
use crate::source::Source;
use postflight_core::map::PointCloud;

/// What to ingest and how. Serialised, it is what the stage's result
/// depends on besides its input files (`postflight run`'s fingerprint): the
/// settings, not the paths.
#[derive(Debug, Clone, serde::Serialize)]
pub struct IngestOptions {
    /// The flight's sources: recordings or photo folders, one or one per
    /// sortie or drone (see [`crate::source::sources_in`]).
    #[serde(skip)]
    pub flights: Vec<PathBuf>,
    #[serde(skip)]
    pub out: PathBuf,
    pub settings: IngestConfig,
}

impl IngestOptions {
    /// `flights` into `out` with the default settings.
    pub fn new(flights: Vec<PathBuf>, out: PathBuf) -> Self {
        Self {
            flights,
            out,
            settings: IngestConfig::default(),
        }
    }
}

/// Progress of an ingest, for progress bars.
pub trait Progress {
    /// `done` of `total` bytes of the recordings read.
    fn bytes(&mut self, done: u64, total: u64);
}

impl<F: FnMut(u64, u64)> Progress for F {
    fn bytes(&mut self, done: u64, total: u64) {
        self(done, total)
    }
}

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
    fn place(&mut self, placement: Placement) {
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

/// Ingest a flight's recordings into a run directory.
pub fn ingest(
    options: &IngestOptions,
    progress: &mut dyn Progress,
) -> Result<IngestSummary, IngestError> {
    InvalidSetting::check(
        options.settings.max_pose_gap_s.is_finite() && options.settings.max_pose_gap_s > 0.0,
        keys::max_pose_gap_s,
        options.settings.max_pose_gap_s,
        "a positive number of seconds",
    )?;
    // A failed rerun must not leave the last ingest looking current (the
    // folder is created only once the flight reads).
    if options.out.is_dir() {
        RunDir::create(&options.out)?.remove(files::SUMMARY)?;
    }
    let mut sources = open_all(&options.flights)?;
    let origin = photo_origin(options, &sources)?;
    let reconstruction = reconstruction(options, &sources, origin.as_ref(), progress)?;
    let photos = origin.as_ref().map(|origin| PhotoFrame {
        origin,
        reconstruction: reconstruction.as_ref(),
    });
    let mut ingested = ingest_each(&sources, photos.as_ref(), options, progress)?;
    check_topic_flags(options, &every_topic(&ingested))?;
    if ingested.iter().all(|i| i.frames.is_empty()) {
        return Err(IngestError::NoImages {
            path: options.flights[0].clone(),
        });
    }
    let warnings = place_recordings(&mut ingested, &mut sources, options)?;
    let (mut summary, flight) = combine(ingested, options, warnings);
    summary.reconstruction = reconstruction.map(|r| {
        let posed = summary.recordings.iter().filter_map(|s| s.photos.as_ref());
        r.summary(posed.map(|p| p.reconstructed).sum())
    });
    write_outputs(&options.out, &flight, &summary)?;
    Ok(summary)
}

/// The east-north-up frame photo folders are posed in: as set, else at the
/// first photo of the first photo folder; none without photo folders.
fn photo_origin(
    options: &IngestOptions,
    sources: &[Source],
) -> Result<Option<GeoOrigin>, IngestError> {
    let mut folders = sources.iter().filter_map(|s| match s {
        Source::Photos(folder) => Some(folder),
        Source::Recording(_) => None,
    });
    let Some(first) = folders.next() else {
        return Ok(None);
    };
    if let Some(origin) = options.settings.photo_origin {
        return Ok(Some(origin));
    }
    let position = first
        .first_position()
        .map_err(|why| IngestError::NoPosedPhotos {
            path: first.path().to_owned(),
            first: Some(why),
        })?;
    Ok(Some(GeoOrigin {
        position,
        yaw_deg: 0.0,
    }))
}

/// Where the run's photo folders are posed.
struct PhotoFrame<'a> {
    /// The east-north-up frame's origin.
    origin: &'a GeoOrigin,
    reconstruction: Option<&'a Placed>,
}

/// The reconstruction the settings give, read and placed in the photos'
/// frame (by its reference, else fitted to every photo folder's GPS).
fn reconstruction(
    options: &IngestOptions,
    sources: &[Source],
    origin: Option<&GeoOrigin>,
    progress: &mut dyn Progress,
) -> Result<Option<Placed>, IngestError> {
    let Some(path) = &options.settings.reconstruction else {
        return Ok(None);
    };
    let unusable = |why: String| IngestError::Reconstruction {
        path: path.clone(),
        why,
    };
    let origin = origin.ok_or_else(|| {
        unusable(
            "it poses photos, and the flight has no photo folder; give the photos with --photos"
                .into(),
        )
    })?;
    let reconstruction = Reconstruction::load(path).map_err(unusable)?;
    let mut positions = BTreeMap::new();
    for source in sources {
        if let Source::Photos(folder) = source {
            positions.extend(folder.positions(origin, progress));
        }
    }
    reconstruction
        .place(origin, &positions)
        .map(Some)
        .map_err(unusable)
}

/// Each source ingested, or read back from the run directory when it was
/// ingested before with the same settings ([`reuse`]; photo folders posed
/// by a reconstruction are posed afresh, as the fit takes every folder).
fn ingest_each(
    sources: &[Source],
    photos: Option<&PhotoFrame>,
    options: &IngestOptions,
    progress: &mut dyn Progress,
) -> Result<Vec<Ingested>, IngestError> {
    let total: u64 = sources.iter().map(Source::len).sum();
    let mut done = 0;
    let mut ingested = Vec::new();
    let mut kept = Vec::new();
    for (index, source) in (0u16..).zip(sources) {
        let place = reuse::place_of(source.path(), photos.map(|p| p.origin), options);
        let reconstructed = photos.is_some_and(|p| p.reconstruction.is_some());
        let earlier = match (source, reconstructed) {
            (Source::Photos(_), true) => None,
            _ => reuse::load(&place, index),
        };
        let one = match earlier {
            Some(one) => one,
            None => {
                let mut progress = |bytes, _| progress.bytes(done + bytes, total);
                let one = match (source, photos) {
                    (Source::Recording(r), _) => ingest_one(index, r, options, &mut progress)?,
                    (Source::Photos(folder), Some(p)) => {
                        let strict = options.settings.strict;
                        folder.ingest(index, p.origin, p.reconstruction, strict, &mut progress)?
                    }
                    (Source::Photos(_), None) => unreachable!("photo folders have an origin"),
                };
                reuse::keep(&place, &one)?;
                one
            }
        };
        done += source.len();
        progress.bytes(done, total);
        ingested.push(one);
        kept.push(place);
    }
    reuse::forget_all_but(&options.out, &kept)?;
    Ok(ingested)
}

/// Messages per topic, over every recording.
fn every_topic(ingested: &[Ingested]) -> BTreeMap<String, TopicSummary> {
    let mut all = BTreeMap::new();
    for one in ingested {
        let topics = one.summary.messages.iter();
        all.extend(topics.map(|(t, s)| (t.clone(), s.clone())));
    }
    all
}

/// The sources, opened.
fn open_all(paths: &[PathBuf]) -> Result<Vec<Source>, IngestError> {
    check_recordings(paths)?;
    paths.iter().map(|p| Source::open(p)).collect()
}

/// A flight's recordings are at least one, each given once.
pub fn check_recordings(paths: &[PathBuf]) -> Result<(), IngestError> {
    let mut seen = BTreeSet::new();
    for p in paths {
        let key = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        if !seen.insert(key) {
            return Err(IngestError::GivenTwice { path: p.clone() });
        }
    }
    if paths.is_empty() {
        return Err(IngestError::NoRecordingsIn {
            path: PathBuf::new(),
        });
    }
    Ok(())
}

/// One pass over one recording, and its frames placed on its own
/// trajectory (a pose never comes from another sortie or drone).
fn ingest_one(
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
        pose_source: PoseSource {
            topic: trajectory.source.clone(),
            frame_id: trajectory.frame_id.clone(),
            child_frame_id: trajectory.child_frame_id.clone(),
        },
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

/// Every recording's poses in the run's map frame ([`slam_frames`], by
/// the maps recorded in them); the warnings that gives.
fn place_recordings(
    ingested: &mut [Ingested],
    sources: &mut [Source],
    options: &IngestOptions,
) -> Result<Vec<String>, IngestError> {
    let mut maps = Vec::new();
    for (one, source) in ingested.iter().zip(sources) {
        maps.push(match source {
            Source::Recording(recording) => recorded_map_of(recording, &one.summary)?,
            Source::Photos(_) => None,
        });
    }
    let names: Vec<String> = ingested.iter().map(|i| i.summary.name()).collect();
    let given = given_frames(&options.settings.recording_frame, &names, &maps)?;
    let max_gap_ns = (options.settings.max_pose_gap_s * 1e9) as i64;
    let frames: Vec<RecordedFrame> = ingested
        .iter()
        .zip(&maps)
        .zip(given)
        .map(|((i, map), given)| RecordedFrame {
            name: i.summary.name(),
            map: map.as_ref().filter(|c| !c.is_empty()),
            given,
            on_earth: photos_on_earth(i).or_else(|| {
                fixes_on(&i.fixes, |_| Some(&i.trajectory), max_gap_ns)
                    .and_then(|(local, geodetic)| GeoAlignment::fit(&local, &geodetic).ok())
            }),
        })
        .collect();
    let (placements, warnings) = slam_frames::place(&frames)?;
    for (one, placement) in ingested.iter_mut().zip(placements) {
        one.place(placement);
    }
    Ok(warnings)
}

/// A photo folder's frame on the Earth: exactly its origin (its photos are
/// posed there); `None` for a recording.
fn photos_on_earth(ingested: &Ingested) -> Option<GeoAlignment> {
    let photos = ingested.summary.photos.as_ref()?;
    let local: Vec<Point3<f64>> = ingested
        .fixes
        .iter()
        .map(|f| photos.origin.to_local(&f.position))
        .collect();
    let centre = local
        .iter()
        .map(|p| p.coords)
        .sum::<nalgebra::Vector3<f64>>()
        / local.len() as f64;
    Some(GeoAlignment {
        origin: photos.origin,
        fixes: local.len(),
        rms_m: 0.0,
        spread_m: local
            .iter()
            .map(|p| (p.coords - centre).xy().norm())
            .fold(0.0, f64::max),
    })
}

/// Each recording's frame as the settings give it (by file name); refused
/// when one names no recording of the flight, or the reference recording
/// (the first with a map), whose frame is the map frame.
fn given_frames(
    given: &[RecordingFrame],
    names: &[String],
    maps: &[Option<PointCloud>],
) -> Result<Vec<Option<Isometry3<f64>>>, IngestError> {
    let reference = maps
        .iter()
        .position(|m| m.as_ref().is_some_and(|c| !c.is_empty()))
        .unwrap_or(0);
    let mut out = vec![None; names.len()];
    for frame in given {
        let expected = match names.iter().position(|n| *n == frame.recording) {
            None => format!("a recording of the flight ({})", names.join(", ")),
            Some(i) if i == reference => format!(
                "a recording other than {}, the reference, whose frame is the map frame",
                names[i]
            ),
            Some(i) => {
                out[i] = Some(frame.isometry());
                continue;
            }
        };
        return Err(InvalidSetting::new(keys::recording_frame, &frame.recording, expected).into());
    }
    Ok(out)
}

/// What ingest writes, the recordings' together.
struct FlightTables {
    frames: Vec<Frame>,
    trajectories: Vec<Trajectory>,
    cameras: Vec<Camera>,
    fixes: Vec<GnssFix>,
}

/// The recordings as one flight: frames in time order across recordings,
/// each recording's trajectory and cameras, one geo origin from every fix,
/// and the summary.
fn combine(
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

/// The map frame on the Earth from the GPS fixes (those with a fix, at
/// times the trajectory has a pose); a warning when they cannot tell.
fn geo_origin(
    fixes: &[GnssFix],
    trajectories: &[Trajectory],
    max_gap_ns: i64,
    warnings: &mut Vec<String>,
) -> Option<GeoAlignment> {
    let (local, geodetic) = fixes_on(
        fixes,
        |f| trajectories.get(usize::from(f.recording)),
        max_gap_ns,
    )?;
    GeoAlignment::fit(&local, &geodetic)
        .map_err(|why| {
            warnings.push(format!(
                "the GPS fixes do not place the map on the Earth: {why}; give `postflight replan` the map's origin (--geo-origin, or geo_origin in postflight.toml's [replan])"
            ));
        })
        .ok()
}

/// The fixes with a fix status and a pose at their time (on the trajectory
/// `trajectory_of` gives each): the pose's position and the fix's; `None`
/// without fixes.
fn fixes_on<'a>(
    fixes: &[GnssFix],
    trajectory_of: impl Fn(&GnssFix) -> Option<&'a Trajectory>,
    max_gap_ns: i64,
) -> Option<(Vec<Point3<f64>>, Vec<Geodetic>)> {
    if fixes.is_empty() {
        return None;
    }
    Some(
        fixes
            .iter()
            .filter(|f| f.status >= 0)
            .filter_map(|f| match trajectory_of(f)?.at(f.time_ns, max_gap_ns) {
                PoseAt::Pose(pose) => Some((Point3::from(pose.translation.vector), f.position)),
                _ => None,
            })
            .unzip(),
    )
}

/// Frames per `pose_status`.
fn frames_by_pose_status(frames: &[Frame]) -> BTreeMap<PoseStatus, u64> {
    let mut by_status = BTreeMap::new();
    for f in frames {
        *by_status.entry(f.pose_status).or_default() += 1;
    }
    by_status
}

/// What the summary says of frames without a pose or a readable image.
fn frame_warnings(frames: &[Frame], by_status: &BTreeMap<PoseStatus, u64>) -> Vec<String> {
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
        if !expected.contains(&schema::ros2_name(schema).as_ref()) {
            return Err(IngestError::TopicSchema {
                key,
                topic: topic.clone(),
                schema: schema.clone(),
                expected: expected.join(" or "),
            });
        }
        Ok(())
    };
    for t in &options.settings.image_topics {
        check(
            keys::image_topics,
            t,
            &[schema::IMAGE, schema::COMPRESSED_IMAGE],
        )?;
    }
    if let Some(t) = &options.settings.pose_topic {
        check(
            keys::pose_topic,
            t,
            &[
                schema::POSE_STAMPED,
                schema::POSE_WITH_COVARIANCE_STAMPED,
                schema::ODOMETRY,
            ],
        )?;
    }
    if let Some(t) = &options.settings.camera_info_topic {
        check(keys::camera_info_topic, t, &[schema::CAMERA_INFO])?;
    }
    if let Some(t) = &options.settings.map_topic {
        check(keys::map_topic, t, &[schema::POINT_CLOUD2])?;
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

/// Where the map recorded in a recording is, and what it holds.
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

fn write_outputs(
    out: &Path,
    flight: &FlightTables,
    summary: &IngestSummary,
) -> Result<(), IngestError> {
    let run = RunDir::create(out)?;
    run.remove(files::SUMMARY)?;
    outputs::write_frames(&run, &flight.frames)?;
    outputs::write_trajectories(&run, &flight.trajectories)?;
    outputs::write_gnss(&run, &flight.fixes)?;
    run.write_json(files::CAMERAS, &flight.cameras)?;
    run.write_json(files::SUMMARY, summary)?;
    Ok(())
}
