//! The localise stage: every detection of a run placed on the SLAM map,
//! views fused into defect candidates, written as `observations.parquet`,
//! `defects.parquet`, `defects.json`, a JPEG crop per candidate and
//! `localise.json`.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::PathBuf;
use std::time::Instant;

use detect::FrameDetection;
use ingest::map::{DEFAULT_RESOLUTION, PointCloud, SlamMap, VoxelGrid, VoxelIndex};
use ingest::{Flight, Frame, InspectionPlan};
use nalgebra::Point3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::crop::write_crop;
use crate::error::LocaliseError;
use crate::fusion::{DefectCandidate, FusionOptions, fuse};
use crate::observation::{Observation, Outcome, Scene};
use crate::records::{DefectRecord, defects_table, observations_table};
use crate::trace::trace;

/// Files of the localise stage.
pub mod files {
    pub const OBSERVATIONS: &str = "observations.parquet";
    pub const DEFECTS: &str = "defects.parquet";
    pub const DEFECTS_JSON: &str = "defects.json";
    /// Directory of candidate crops, `<id>.jpg`.
    pub const CROPS: &str = "defects";
    pub const SUMMARY: &str = "localise.json";
}

#[derive(Debug, Clone)]
pub struct LocaliseOptions {
    pub run: PathBuf,
    /// Map (PLY or PCD) to use instead of the one recorded in the flight.
    pub map: Option<PathBuf>,
    /// Plan whose target voxels are the structure (and whose voxel grid is
    /// used); without it every mapped surface counts as structure.
    pub plan: Option<PathBuf>,
    /// Rays end here, metres.
    pub max_range_m: f64,
    pub fusion: FusionOptions,
}

impl LocaliseOptions {
    pub const DEFAULT_MAX_RANGE_M: f64 = 30.0;

    pub fn new(run: PathBuf) -> Self {
        Self {
            run,
            map: None,
            plan: None,
            max_range_m: Self::DEFAULT_MAX_RANGE_M,
            fusion: FusionOptions::default(),
        }
    }

    fn check(&self) -> Result<(), LocaliseError> {
        let bad = |why: &str| Err(LocaliseError::Option(why.into()));
        if !(self.max_range_m > 0.0 && self.max_range_m <= 1000.0) {
            return bad("--max-range must be between 0 and 1000 metres");
        }
        if !(0.0..=5.0).contains(&self.fusion.link_distance) {
            return bad("--link-distance must be between 0 and 5 metres");
        }
        if !(0.0..=90.0).contains(&self.fusion.max_normal_angle_deg) {
            return bad("--max-normal-angle must be between 0 and 90 degrees");
        }
        Ok(())
    }
}

/// Detections of each outcome.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Outcomes {
    pub placed: u64,
    pub no_pose: u64,
    pub no_intrinsics: u64,
    pub no_surface: u64,
    pub obstacle: u64,
}

/// `localise.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LocaliseSummary {
    /// The map file, or the recorded topic.
    pub map: String,
    pub map_points: usize,
    pub map_voxels: usize,
    pub voxel_size_m: f64,
    /// The plan whose target voxels are the structure, if one was given.
    pub plan: Option<PathBuf>,
    pub max_range_m: f64,
    pub link_distance_m: f64,
    pub detections: u64,
    pub outcomes: Outcomes,
    /// Detections placed by their traced centre line (the rest by their box).
    pub traced: u64,
    /// Share of cast detections (pose and intrinsics known) whose rays met the map.
    pub hit_share: f64,
    pub defects: u64,
    pub seconds: f64,
    pub warnings: Vec<String>,
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
    let detections = detect::read_detections(&options.run)?;
    // A failed rerun must not leave the last run's results looking current.
    flight.run.remove(files::SUMMARY)?;
    let plan = options
        .plan
        .as_deref()
        .map(InspectionPlan::load)
        .transpose()?;
    let grid = plan.as_ref().map_or(
        VoxelGrid::new(DEFAULT_RESOLUTION, Point3::origin()),
        InspectionPlan::grid,
    );
    let (cloud, map_name) = match &options.map {
        Some(path) => (PointCloud::load(path)?, path.display().to_string()),
        None => {
            let cloud = flight.recorded_map()?.ok_or(LocaliseError::NoMap)?;
            let topic = flight.summary.map.as_ref().map(|m| m.topic.clone());
            (cloud, format!("recorded {}", topic.unwrap_or_default()))
        }
    };
    let map = SlamMap::on_grid(cloud, grid).ok_or_else(|| {
        LocaliseError::Option(format!(
            "the map ({map_name}) has no points; pass a map with --map"
        ))
    })?;
    let structure: Option<HashSet<VoxelIndex>> = plan
        .as_ref()
        .map(|p| p.target_voxels.iter().copied().collect());
    let scene = Scene {
        map: &map,
        structure: structure.as_ref(),
        max_range: options.max_range_m,
    };

    let frames: HashMap<u32, &Frame> = flight.frames.iter().map(|f| (f.index, f)).collect();
    let mut by_frame: BTreeMap<u32, Vec<FrameDetection>> = BTreeMap::new();
    for d in detections {
        if !frames.contains_key(&d.frame) {
            return Err(LocaliseError::Option(format!(
                "detections.parquet names frame {} which the ingest has no record of; rerun `postflight detect` after `postflight ingest`",
                d.frame
            )));
        }
        by_frame.entry(d.frame).or_default().push(d);
    }
    let total = by_frame.values().map(Vec::len).sum::<usize>() as u64;
    let groups: Vec<(u32, Vec<FrameDetection>)> = by_frame.into_iter().collect();
    let mut observations = Vec::new();
    let mut warnings = Vec::new();
    progress(0, total);
    for chunk in groups.chunks(CHUNK) {
        let placed: Vec<(Vec<Observation>, Option<String>)> = chunk
            .par_iter()
            .map(|(index, dets)| place_frame(&flight, frames[index], dets, &scene))
            .collect();
        for (obs, warning) in placed {
            observations.extend(obs);
            warnings.extend(warning);
        }
        progress(observations.len() as u64, total);
    }

    let mut outcomes = Outcomes::default();
    for o in &observations {
        *match o.outcome {
            Outcome::Placed => &mut outcomes.placed,
            Outcome::NoPose => &mut outcomes.no_pose,
            Outcome::NoIntrinsics => &mut outcomes.no_intrinsics,
            Outcome::NoSurface => &mut outcomes.no_surface,
            Outcome::Obstacle => &mut outcomes.obstacle,
        } += 1;
    }
    let cast = (outcomes.placed + outcomes.no_surface + outcomes.obstacle) as usize;
    let hit = (outcomes.placed + outcomes.obstacle) as usize;
    if outcomes.no_pose > 0 && outcomes.no_pose == total {
        return Err(LocaliseError::NoPoses { detections: total });
    }
    check_overlap(&flight, &map, options.max_range_m, hit, cast)?;
    if outcomes.no_pose > 0 {
        warnings.push(format!(
            "{} detections are in frames without a pose and were not placed (see outcome = no_pose in {})",
            outcomes.no_pose,
            files::OBSERVATIONS
        ));
    }
    if outcomes.no_intrinsics > 0 {
        warnings.push(format!(
            "{} detections are from a camera without intrinsics; give them with `postflight ingest --camera-info`",
            outcomes.no_intrinsics
        ));
    }

    let candidates = fuse(&observations, &options.fusion);
    let traced = observations.iter().filter(|o| o.traced_px > 0).count() as u64;
    let summary = LocaliseSummary {
        map: map_name,
        map_points: map.cloud.len(),
        map_voxels: map.voxels.len(),
        voxel_size_m: map.voxels.grid.resolution,
        plan: options.plan.clone(),
        max_range_m: options.max_range_m,
        link_distance_m: options.fusion.link_distance,
        detections: total,
        outcomes,
        traced,
        hit_share: if cast == 0 {
            0.0
        } else {
            hit as f64 / cast as f64
        },
        defects: candidates.len() as u64,
        seconds: start.elapsed().as_secs_f64(),
        warnings,
    };
    write_outputs(&flight, &frames, &observations, &candidates, &summary)?;
    Ok(summary)
}

/// Place one frame's detections, decoding its image once for their traces.
fn place_frame(
    flight: &Flight,
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
    let (gray, warning) = match flight.image(frame) {
        Ok(img) => (Some(img.to_luma8()), None),
        Err(e) => (
            None,
            Some(format!(
                "frame {}: {e}; its detections were placed by their boxes",
                frame.index
            )),
        ),
    };
    let observations = detections
        .iter()
        .map(|d| {
            let b = d.detection.bbox;
            let crack = gray
                .as_ref()
                .and_then(|g| trace(g, [b.x0, b.y0, b.x1, b.y1]));
            scene.place(d.clone(), &pose, k, crack.as_ref())
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

fn write_outputs(
    flight: &Flight,
    frames: &HashMap<u32, &Frame>,
    observations: &[Observation],
    candidates: &[DefectCandidate],
    summary: &LocaliseSummary,
) -> Result<(), LocaliseError> {
    let run = &flight.run;
    let write_error = |name: &str| {
        let path = run.file(name);
        move |e: String| LocaliseError::Write { path, why: e }
    };
    let crops = run.file(files::CROPS);
    if crops.exists() {
        std::fs::remove_dir_all(&crops).map_err(|e| write_error(files::CROPS)(e.to_string()))?;
    }
    std::fs::create_dir_all(&crops).map_err(|e| write_error(files::CROPS)(e.to_string()))?;
    let records: Vec<DefectRecord> = candidates
        .par_iter()
        .map(|c| {
            let name = format!("{}/{}.jpg", files::CROPS, c.id);
            let best = &observations[c.best];
            let frame = frames[&best.detection.frame];
            let written =
                write_crop(flight, frame, best, &run.file(&name)).map_err(write_error(&name))?;
            Ok(DefectRecord::new(c, observations, written.then_some(name)))
        })
        .collect::<Result<_, LocaliseError>>()?;
    let mut defect_of: Vec<Option<String>> = vec![None; observations.len()];
    for c in candidates {
        for i in &c.observations {
            defect_of[*i] = Some(c.id.clone());
        }
    }
    let mut table = observations_table(observations, &defect_of)
        .map_err(|e| write_error(files::OBSERVATIONS)(e.to_string()))?;
    run.write_table(files::OBSERVATIONS, &mut table)?;
    let mut table =
        defects_table(&records).map_err(|e| write_error(files::DEFECTS)(e.to_string()))?;
    run.write_table(files::DEFECTS, &mut table)?;
    run.write_json(
        files::DEFECTS_JSON,
        &serde_json::json!({ "defects": records }),
    )?;
    run.write_json(files::SUMMARY, summary)?;
    Ok(())
}
