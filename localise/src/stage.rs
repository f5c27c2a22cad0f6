//! The localise stage: every detection of a run placed on the SLAM map,
//! views fused into defect candidates, written as `observations.parquet`,
//! `defects.parquet`, `defects.json`, a JPEG crop per candidate and
//! `localise.json`.

use std::collections::{BTreeMap, HashSet};
use std::path::PathBuf;
use std::time::Instant;

use ingest::Recordings;
use nalgebra::Point3;
use postflight_core::condition::{ConditionSettings, CrackLimits};
use postflight_core::defect_kind::DefectKind;
use postflight_core::detection::FrameDetection;
use postflight_core::map::{SlamMap, VoxelIndex};
use postflight_core::motion::frame_blur_px;
use postflight_core::outputs::detect::read_detections;
use postflight_core::outputs::localise::{
    self as outputs, LocaliseSummary, Outcome, Outcomes, SetAside, SetAsideReason, files,
};
use postflight_core::{
    Flight, FlownPlan, Frame, InvalidSetting, PlanFile, RunDir, Stage, ViewSettings,
};
use rayon::prelude::*;

use crate::crop::write_crop;
use crate::crossing::{adjacency, crossings};
use crate::error::LocaliseError;
use crate::flight_widths;
use crate::fusion::{DefectCandidate, fuse};
use crate::joint;
use crate::observation::{Observation, Scene};
use crate::records::{defect_record, observation_record};
use crate::settings::{LocaliseConfig, keys};
use crate::trace::{trace, trace_mask};
use postflight_core::structure::ElementMap;
use targets::{Found, Targets};

/// What localise runs on and how. Serialised, it is what the stage's
/// result depends on besides its input files (`postflight run`'s
/// fingerprint): the settings, not the paths.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LocaliseOptions {
    #[serde(skip)]
    pub run: PathBuf,
    /// Map (PLY, PCD, `.bt`, `.ot`) to use instead of the one recorded in the flight.
    #[serde(skip)]
    pub map: Option<PathBuf>,
    /// Plan whose target voxels are the structure (and whose voxel grid is
    /// used); without it every mapped surface counts as structure.
    #[serde(skip)]
    pub plan: Option<PlanFile>,
    /// The structure whose elements name each candidate's place: the plan's
    /// target voxels, or a targets file's (as coverage takes them).
    pub targets: Targets,
    pub settings: LocaliseConfig,
    /// The View model each view is judged by, over the plan's (or the
    /// defaults): the same settings coverage takes.
    pub view: ViewSettings,
    /// The width limits that put each candidate in a condition state.
    pub condition: ConditionSettings,
}

impl LocaliseOptions {
    /// Localise `run` with the default settings.
    pub fn new(run: PathBuf) -> Self {
        Self {
            run,
            map: None,
            plan: None,
            targets: Targets::Plan,
            settings: LocaliseConfig::default(),
            view: ViewSettings::default(),
            condition: ConditionSettings::default(),
        }
    }

    /// Refuse settings that cannot work.
    fn check(&self) -> Result<(), InvalidSetting> {
        InvalidSetting::check(
            self.settings.max_range_m > 0.0 && self.settings.max_range_m <= 1000.0,
            keys::max_range_m,
            self.settings.max_range_m,
            "between 0 and 1000 metres",
        )?;
        InvalidSetting::check(
            (0.0..=5.0).contains(&self.settings.link_distance_m),
            keys::link_distance_m,
            self.settings.link_distance_m,
            "between 0 and 5 metres",
        )?;
        InvalidSetting::check(
            (0.0..=90.0).contains(&self.settings.max_normal_angle_deg),
            keys::max_normal_angle_deg,
            self.settings.max_normal_angle_deg,
            "between 0 and 90 degrees",
        )?;
        if let Some(blur) = self.settings.camera_blur_px {
            InvalidSetting::check(
                blur > 0.0 && blur <= 20.0,
                keys::camera_blur_px,
                blur,
                "between 0 and 20 pixels",
            )?;
        }
        self.condition.resolve().check()
    }
}

/// Below this share of rays meeting the map, the map is not the flight's.
const MIN_HIT_SHARE: f64 = 0.25;
/// Fewest cast detections the hit share is judged on; below, frame axes are.
const MIN_CAST: usize = 5;
/// Frames per progress step (each step runs in parallel).
const CHUNK: usize = 64;

/// Place every detection of the run and fuse them into defect candidates.
pub fn localise(
    options: &LocaliseOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<LocaliseSummary, LocaliseError> {
    options.check()?;
    let start = Instant::now();
    let flight = Flight::load(&options.run)?;
    // Cracks are traced and measured here; area defects are not lines.
    let mut detections = read_detections(&RunDir::open(&options.run, Stage::Detect)?)?;
    detections.retain(|d| d.detection.kind == DefectKind::Crack);
    // A failed rerun must not leave the last run's results looking current.
    flight.run.remove(files::SUMMARY)?;
    let plan = options.plan.as_ref().map(PlanFile::load).transpose()?;
    let grid = plan.as_ref().and_then(FlownPlan::grid);
    let (map, map_name) = ingest::load_map(&flight, options.map.as_deref(), grid)?;
    let structure: Option<HashSet<VoxelIndex>> = plan
        .as_ref()
        .and_then(FlownPlan::target_voxels)
        .map(|targets| targets.iter().copied().collect());
    let view = options
        .view
        .apply(plan.as_ref().and_then(FlownPlan::view).unwrap_or_default());
    view.check()?;
    let scene = Scene {
        map: &map,
        structure: structure.as_ref(),
        max_range: options.settings.max_range_m,
        view: &view,
    };
    let recording = Recordings::reopen(&flight)?;

    let by_frame = detections_by_frame(&flight, detections)?;
    let (mut observations, mut warnings) = place(&flight, &recording, by_frame, &scene, progress);
    let widths = flight_widths::measure(&mut observations, &options.settings);
    let outcomes: Outcomes = observations.iter().map(|o| o.outcome).collect();
    let total = observations.len() as u64;
    let count = |outcome| outcomes.get(outcome);
    let hit = (count(Outcome::Placed) + count(Outcome::Obstacle)) as usize;
    let cast = hit + count(Outcome::NoSurface) as usize;
    if count(Outcome::NoPose) > 0 && count(Outcome::NoPose) == total {
        return Err(LocaliseError::NoPoses { detections: total });
    }
    check_overlap(&flight, &map, options.settings.max_range_m, hit, cast)?;
    warnings.extend(unplaced_warnings(&outcomes));
    warnings.extend(map.cloud.coarsened());

    let (candidates, joints): (Vec<_>, Vec<_>) = fuse(&observations, &options.settings)
        .into_iter()
        .partition(|c| !joint::is_joint(c, &observations));
    let elements = elements(options, plan.as_ref(), &map)?;
    let traced = observations.iter().filter(|o| o.traced_px > 0).count() as u64;
    let summary = LocaliseSummary {
        map: map_name,
        map_points: map.cloud.len(),
        map_voxels: map.voxels.len(),
        voxel_size_m: map.voxels.grid.resolution,
        plan: options.plan.as_ref().map(|p| p.path.clone()),
        max_range_m: options.settings.max_range_m,
        link_distance_m: options.settings.link_distance_m,
        detections: total,
        outcomes,
        traced,
        hit_share: if cast == 0 {
            0.0
        } else {
            hit as f64 / cast as f64
        },
        defects: candidates.len() as u64,
        set_aside: joints.iter().map(set_aside_joint).collect(),
        widths: Some(widths),
        seconds: start.elapsed().as_secs_f64(),
        warnings,
    };
    let written = Written {
        observations: &observations,
        candidates: &candidates,
        elements: elements.as_ref(),
        limits: options.condition.resolve().limits(),
    };
    write_outputs(&flight, &recording, &written, &summary)?;
    Ok(summary)
}

fn set_aside_joint(c: &DefectCandidate) -> SetAside {
    SetAside {
        reason: SetAsideReason::Joint,
        id: c.id.clone(),
        position: c.position.into(),
        frames: c.frames,
        trace: c.trace.clone(),
    }
}

/// The detections grouped by frame, in frame order; an error for a frame
/// the ingest does not know.
fn detections_by_frame(
    flight: &Flight,
    detections: Vec<FrameDetection>,
) -> Result<Vec<(u32, Vec<FrameDetection>)>, LocaliseError> {
    let mut by_frame: BTreeMap<u32, Vec<FrameDetection>> = BTreeMap::new();
    for d in detections {
        if flight.frame(d.frame).is_none() {
            return Err(LocaliseError::UnknownFrame { frame: d.frame });
        }
        by_frame.entry(d.frame).or_default().push(d);
    }
    Ok(by_frame.into_iter().collect())
}

/// Every detection placed (or why not), frame by frame in parallel; with a
/// warning for each frame whose image could not be decoded.
fn place(
    flight: &Flight,
    recording: &Recordings,
    by_frame: Vec<(u32, Vec<FrameDetection>)>,
    scene: &Scene,
    progress: &mut dyn FnMut(u64, u64),
) -> (Vec<Observation>, Vec<String>) {
    let total = by_frame.iter().map(|(_, d)| d.len()).sum::<usize>() as u64;
    let mut observations = Vec::new();
    let mut warnings = Vec::new();
    progress(0, total);
    for chunk in by_frame.chunks(CHUNK) {
        let placed: Vec<(Vec<Observation>, Option<String>)> = chunk
            .par_iter()
            .map(|(index, dets)| {
                let frame = flight.frame(*index).expect("frames were checked");
                place_frame(flight, recording, frame, dets, scene)
            })
            .collect();
        for (obs, warning) in placed {
            observations.extend(obs);
            warnings.extend(warning);
        }
        progress(observations.len() as u64, total);
    }
    (observations, warnings)
}

/// What the summary says of detections that could not be placed.
fn unplaced_warnings(outcomes: &Outcomes) -> Vec<String> {
    let mut warnings = Vec::new();
    let no_pose = outcomes.get(Outcome::NoPose);
    if no_pose > 0 {
        warnings.push(format!(
            "{no_pose} detections are in frames without a pose and were not placed (see outcome = {} in {})",
            Outcome::NoPose.as_str(),
            files::OBSERVATIONS
        ));
    }
    let no_intrinsics = outcomes.get(Outcome::NoIntrinsics);
    if no_intrinsics > 0 {
        warnings.push(format!(
            "{no_intrinsics} detections are from a camera without intrinsics; give them to `postflight ingest` as {}",
            ingest::settings::keys::camera_info_file
        ));
    }
    warnings
}

/// Place one frame's detections, decoding its image once for their traces.
fn place_frame(
    flight: &Flight,
    recording: &Recordings,
    frame: &Frame,
    detections: &[FrameDetection],
    scene: &Scene,
) -> (Vec<Observation>, Option<String>) {
    let unplaced = |outcome: Outcome| {
        detections
            .iter()
            .map(|d| Observation {
                detection: d.clone(),
                outcome,
                placement: None,
                traced_px: 0,
                clipped: false,
            })
            .collect()
    };
    let Some(pose) = frame.camera_pose else {
        return (unplaced(Outcome::NoPose), None);
    };
    let Some(k) = flight.camera(frame).and_then(|c| c.intrinsics.as_ref()) else {
        return (unplaced(Outcome::NoIntrinsics), None);
    };
    let (gray, warning) = match recording.image(frame) {
        Ok(img) => (Some(img.to_luma8()), None),
        Err(e) => (
            None,
            Some(format!(
                "frame {}: {e}; its detections were placed by their boxes",
                frame.index
            )),
        ),
    };
    // Unknown without an exposure time: the view's blur is then not judged.
    let blur_px = frame
        .exposure_s
        .and_then(|e| frame_blur_px(flight, frame, k, e, &scene.map.voxels));
    let observations = detections
        .iter()
        .map(|d| {
            let b = d.detection.bbox;
            // The darkest thin line in the box, followed by hysteresis
            // along its faint stretches; else the centre line of the
            // model's crack pixels, where it segments. (A mask thresholded
            // at one half loses those faint stretches: with the reference
            // detector's map, lengths from masks came out a third short.)
            let crack = gray
                .as_ref()
                .and_then(|g| trace(g, [b.x0, b.y0, b.x1, b.y1]))
                .or_else(|| d.detection.mask.as_ref().and_then(trace_mask));
            let crossings = match (&gray, &crack) {
                (Some(g), Some(t)) => crossings(
                    g,
                    d.detection.mask.as_ref(),
                    &t.pixels,
                    &adjacency(t.pixels.len(), &t.edges),
                ),
                _ => Vec::new(),
            };
            let mut placed = scene.place(d.clone(), &pose, k, crack.as_ref(), crossings, blur_px);
            // Placing does not use the camera's accuracy; its candidate's
            // uncertainty does.
            if let Some(p) = &mut placed.placement {
                p.camera_std_m = frame.position_std_m;
            }
            placed
        })
        .collect();
    (observations, warning)
}

/// Fail when the map cannot be the flight's: almost no detection ray meets
/// it, or (with few detections) almost no camera axis does.
fn check_overlap(
    flight: &Flight,
    map: &SlamMap,
    max_range: f64,
    mut hit: usize,
    mut cast: usize,
) -> Result<(), LocaliseError> {
    let posed: Vec<&Frame> = flight
        .frames
        .iter()
        .filter(|f| f.camera_pose.is_some())
        .collect();
    if cast < MIN_CAST {
        let step = (posed.len() / 200).max(1);
        let axes: Vec<bool> = posed
            .iter()
            .step_by(step)
            .map(|f| {
                let pose = f.camera_pose.expect("posed");
                let origin = Point3::from(pose.translation.vector);
                map.voxels
                    .cast(
                        &origin,
                        &(pose.rotation * nalgebra::Vector3::z()),
                        max_range,
                    )
                    .is_some()
            })
            .collect();
        hit = axes.iter().filter(|h| **h).count();
        cast = axes.len();
    }
    if cast == 0 || hit as f64 >= MIN_HIT_SHARE * cast as f64 {
        return Ok(());
    }
    let span = |points: &mut dyn Iterator<Item = Point3<f64>>| {
        let (lo, hi) = points.fold(
            (Point3::from([f64::MAX; 3]), Point3::from([f64::MIN; 3])),
            |(lo, hi), p| (lo.inf(&p), hi.sup(&p)),
        );
        format!(
            "x {:.1}..{:.1}, y {:.1}..{:.1}, z {:.1}..{:.1} m",
            lo.x, hi.x, lo.y, hi.y, lo.z, hi.z
        )
    };
    Err(LocaliseError::MapMismatch {
        hit,
        cast,
        map: span(&mut map.cloud.points.iter().copied()),
        cameras: span(
            &mut posed
                .iter()
                .map(|f| Point3::from(f.camera_pose.expect("posed").translation.vector)),
        ),
    })
}

/// The structure's elements, found from the map and the targets as
/// coverage finds them; none without targets (no plan naming them, no
/// targets file).
fn elements(
    options: &LocaliseOptions,
    plan: Option<&FlownPlan>,
    map: &SlamMap,
) -> Result<Option<ElementMap>, LocaliseError> {
    let named =
        options.targets != Targets::Plan || plan.is_some_and(|p| p.target_voxels().is_some());
    if !named {
        return Ok(None);
    }
    let found = Found::find(&options.targets, plan, map)?;
    Ok(Some(found.element_map(map)))
}

/// What localise found, to write.
struct Written<'a> {
    observations: &'a [Observation],
    candidates: &'a [DefectCandidate],
    /// The structure's elements, when there are targets to find them in.
    elements: Option<&'a ElementMap>,
    /// What puts a candidate in a condition state.
    limits: CrackLimits,
}

fn write_outputs(
    flight: &Flight,
    recording: &Recordings,
    written: &Written,
    summary: &LocaliseSummary,
) -> Result<(), LocaliseError> {
    let Written {
        observations,
        candidates,
        elements,
        limits,
    } = *written;
    let run = &flight.run;
    let crop_files: Vec<String> = candidates.iter().map(|c| files::crop(&c.id)).collect();
    run.refill(files::CROPS, Stage::Localise, &crop_files)?;
    let defects = candidates
        .par_iter()
        .map(|c| {
            let name = format!("{}/{}", files::CROPS, files::crop(&c.id));
            let best = &observations[c.best];
            let frame = flight
                .frame(best.detection.frame)
                .expect("detections are of known frames");
            let written = write_crop(recording, frame, best, &run.file(&name))?;
            let place = elements.and_then(|e| e.place(&c.position, &c.normal));
            Ok(defect_record(
                c,
                observations,
                written.then_some(name),
                place,
                &limits,
            ))
        })
        .collect::<Result<Vec<_>, postflight_core::Error>>()?;
    let mut defect_of: Vec<Option<String>> = vec![None; observations.len()];
    for c in candidates {
        for i in &c.observations {
            defect_of[*i] = Some(c.id.clone());
        }
    }
    let records: Vec<_> = observations
        .iter()
        .zip(defect_of)
        .map(|(o, defect)| observation_record(o, defect))
        .collect();
    outputs::write_observations(run, &records)?;
    outputs::write_defects(run, &defects)?;
    run.write_json(files::SUMMARY, summary)?;
    Ok(())
}
