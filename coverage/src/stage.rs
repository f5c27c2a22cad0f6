//! The coverage stage: `postflight coverage --run RUN_DIR`. Judges every
//! exposed face of the target voxels against every usable frame of the
//! flight (and against the plan's viewpoints, for what was planned), and
//! writes `coverage.parquet` (one row per target voxel) and `coverage.json`.

use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use ingest::map::{DEFAULT_RESOLUTION, PointCloud, SlamMap, VoxelGrid, VoxelIndex};
use ingest::{Flight, InspectionPlan, Intrinsics, PoseAt, ViewModel, Viewpoint};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cover::{FaceCover, Shot, cover};
use crate::error::CoverageError;
use crate::face::exposed_faces;
use crate::motion::{blur_px, velocity};
use crate::reach::inspectable;
use crate::records::{coverage_table, voxel_records};
use crate::settings::{CoverageSettings, ViewSettings};
use crate::targets;
use crate::view::Miss;

/// Files this stage writes in the run directory.
pub mod files {
    pub const TABLE: &str = "coverage.parquet";
    pub const SUMMARY: &str = "coverage.json";
    /// With `--viewpoints`: a plan checked before flying it.
    pub const VIEWPOINTS_TABLE: &str = "coverage-viewpoints.parquet";
    pub const VIEWPOINTS_SUMMARY: &str = "coverage-viewpoints.json";
}

/// Where the target voxels come from.
#[derive(Debug, Clone, PartialEq)]
pub enum Targets {
    /// The plan's target voxels (needs a plan).
    Plan,
    /// Occupied map voxels inside axis-aligned boxes (JSON file).
    Boxes(PathBuf),
    /// Voxels of a segmented infrastructure cloud (PLY or PCD).
    Cloud(PathBuf),
}

#[derive(Debug, Clone)]
pub struct CoverageOptions {
    pub run: PathBuf,
    pub plan: Option<PathBuf>,
    /// Judge this plan's viewpoints instead of the flight's frames.
    pub viewpoints: Option<PathBuf>,
    pub map: Option<PathBuf>,
    pub targets: Targets,
    /// View model settings over the plan's (unset: the plan's, else defaults).
    pub view: ViewSettings,
    pub settings: CoverageSettings,
}

impl CoverageOptions {
    pub const DEFAULT_DEFECT_RADIUS_M: f64 = 1.0;

    pub fn new(run: PathBuf) -> Self {
        Self {
            run,
            plan: None,
            viewpoints: None,
            map: None,
            targets: Targets::Plan,
            view: ViewSettings::default(),
            settings: CoverageSettings::default(),
        }
    }
}

/// Voxel counts by reason for not being inspected.
pub type ReasonCounts = BTreeMap<String, usize>;

/// `coverage.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CoverageSummary {
    pub run: PathBuf,
    /// `flight`, or the viewpoints file judged instead.
    pub shots: String,
    pub view: ViewModel,
    pub resolution_m: f64,
    /// World position of the corner of voxel `[0, 0, 0]`.
    pub grid_origin: [f64; 3],
    /// The map judged against: a file, or `None` for the flight's recorded map.
    pub map: Option<PathBuf>,
    pub targets: String,
    pub target_voxels: usize,
    pub planned_voxels: Option<usize>,
    pub inspected_voxels: usize,
    pub inspected_pct: f64,
    /// Of the planned voxels, the share inspected.
    pub planned_inspected_pct: Option<f64>,
    /// Planned voxels not inspected.
    pub planned_missed_voxels: Option<usize>,
    /// Target voxels not inspected that a follow-up flight could inspect.
    pub gap_voxels: usize,
    /// Target voxels no free standpoint can inspect under the View model.
    pub uninspectable_voxels: usize,
    pub exposed_faces: usize,
    pub inspected_faces: usize,
    pub face_area_coverage_pct: f64,
    /// Occupied map voxels that are not targets (GATSBI's V_O).
    pub obstacle_voxels: usize,
    /// Not-inspected voxels by the furthest rule any frame reached.
    pub reasons: ReasonCounts,
    pub shots_total: usize,
    pub shots_usable: usize,
    pub shots_blurred: usize,
    pub frames_without_pose: usize,
    pub frames_without_exposure: usize,
    pub faces_needing_more_views: usize,
    pub seconds: f64,
    pub warnings: Vec<String>,
}

/// Camera pose for a plan viewpoint: the body at the viewpoint, the camera
/// mounted by `extrinsic` turned about the body's y axis to the viewpoint's
/// gimbal pitch.
pub fn viewpoint_camera(v: &Viewpoint, extrinsic: &Isometry3<f64>) -> Isometry3<f64> {
    let axis = extrinsic.rotation * Vector3::z();
    let mount_pitch = (-axis.z).clamp(-1.0, 1.0).asin();
    let body = Isometry3::from_parts(
        Translation3::from(Vector3::from(v.position)),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), v.yaw),
    );
    let gimbal = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), v.gimbal_pitch - mount_pitch),
    );
    body * gimbal * extrinsic
}

/// How the flight's first camera is mounted on the body (plan viewpoints
/// are shots of it). Without a recorded mounting, a camera at the body
/// origin looking forward (optical z along body x, y down).
pub fn camera_mount(flight: &Flight) -> Isometry3<f64> {
    flight
        .cameras
        .first()
        .and_then(|c| c.extrinsic)
        .unwrap_or_else(|| {
            Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.5, -0.5, 0.5, -0.5)),
            )
        })
}

/// Faces per progress step.
const CHUNK: usize = 4096;
/// Below this share of target voxels holding map points, the map is not
/// the targets' (another frame or unit).
const MIN_MAPPED_SHARE: f64 = 0.25;

/// `[x, y, z]..[x, y, z]`, the bounding box of some points, for messages.
fn span(points: impl Iterator<Item = Point3<f64>>) -> String {
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for p in points {
        lo = lo.inf(&p.coords);
        hi = hi.sup(&p.coords);
    }
    format!(
        "[{:.1}, {:.1}, {:.1}]..[{:.1}, {:.1}, {:.1}]",
        lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
    )
}

pub fn coverage(
    options: &CoverageOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<CoverageSummary, CoverageError> {
    let start = Instant::now();
    let flight = Flight::load(&options.run)?;
    let checking_plan = options.viewpoints.is_some();
    let (table_name, summary_name) = if checking_plan {
        (files::VIEWPOINTS_TABLE, files::VIEWPOINTS_SUMMARY)
    } else {
        (files::TABLE, files::SUMMARY)
    };
    // A failed rerun must not leave the last run's results looking current.
    flight.run.remove(summary_name)?;
    let plan = options
        .plan
        .as_deref()
        .map(InspectionPlan::load)
        .transpose()?;
    let view = options
        .view
        .apply(plan.as_ref().map_or_else(ViewModel::default, |p| p.view));
    check_view(&view)?;
    let grid = plan.as_ref().map_or(
        VoxelGrid::new(DEFAULT_RESOLUTION, Point3::origin()),
        InspectionPlan::grid,
    );
    let cloud = match &options.map {
        Some(path) => PointCloud::load(path)?,
        None => flight.recorded_map()?.ok_or(CoverageError::NoMap)?,
    };
    let map = SlamMap::on_grid(cloud, grid).ok_or_else(|| {
        CoverageError::Option("the map has no points; pass a map with --map".into())
    })?;

    let (targets, targets_name) = load_targets(&options.targets, plan.as_ref(), &map)?;
    let target_set: HashSet<VoxelIndex> = targets.iter().copied().collect();
    let faces = exposed_faces(&grid, &targets, &target_set);

    let mut warnings = Vec::new();
    if flight.cameras.is_empty() {
        return Err(CoverageError::Option(
            "the flight has no camera (no image topic was ingested); check `postflight ingest`'s image topics".into(),
        ));
    }
    let lenses: Vec<Intrinsics> = flight
        .cameras
        .iter()
        .map(|c| c.intrinsics.clone())
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| {
            CoverageError::Option(
                "a camera of the flight has no intrinsics; rerun `postflight ingest` with --camera-info FILE".into(),
            )
        })?;

    // The shots: the flight's frames, or the viewpoints of a plan to check.
    let extrinsic = camera_mount(&flight);
    let FlightShots {
        shots,
        without_pose: frames_without_pose,
        without_exposure: frames_without_exposure,
    } = match &options.viewpoints {
        Some(path) => FlightShots {
            shots: viewpoint_shots(&InspectionPlan::load(path)?, &extrinsic),
            without_pose: 0,
            without_exposure: 0,
        },
        None => flight_shots(&flight, &lenses, &map, options.settings.exposure_s),
    };
    if frames_without_pose > 0 {
        warnings.push(format!(
            "{frames_without_pose} frames have no pose and count for nothing (ingest.json says why)"
        ));
    }
    if frames_without_exposure > 0 {
        warnings.push(format!(
            "{frames_without_exposure} frames recorded no exposure time, so their blur was not judged; pass --exposure SECONDS"
        ));
    }
    if !checking_plan && shots.is_empty() {
        return Err(CoverageError::Option(
            "no frame of the flight has a pose, so nothing can be judged; check the pose source with `postflight ingest`".into(),
        ));
    }
    let shots_blurred = shots
        .iter()
        .filter(|s| s.is_blurred(view.max_blur_px))
        .count();

    // Views each face needs: more around defect candidates, if asked.
    let defects = match options.settings.views_near_defects {
        Some(_) => defect_positions(&flight.run.file("defects.json"))?,
        None => Vec::new(),
    };
    let radius = options
        .settings
        .defect_radius_m
        .unwrap_or(CoverageOptions::DEFAULT_DEFECT_RADIUS_M);
    let need: Vec<u32> = faces
        .iter()
        .map(|f| {
            match options.settings.views_near_defects {
                Some(n) if defects.iter().any(|d| (d - f.centre).norm() <= radius) => n,
                _ => view.views_required,
            }
            .max(1)
        })
        .collect();

    let plan_shots: Option<Vec<Shot>> = plan.as_ref().map(|p| viewpoint_shots(p, &extrinsic));

    let total = faces.len() as u64;
    progress(0, total);
    let mut flown: Vec<FaceCover> = Vec::with_capacity(faces.len());
    let mut planned: Vec<FaceCover> = Vec::new();
    let mut reachable: Vec<bool> = Vec::with_capacity(faces.len());
    let max_gsd_distance = view.max_gsd_mm / 1000.0 * lenses[0].fx.min(lenses[0].fy);
    for (chunk, need) in faces.chunks(CHUNK).zip(need.chunks(CHUNK)) {
        let got = cover(chunk, need, &shots, &lenses, &map, &view);
        reachable.extend(
            chunk
                .par_iter()
                .zip(&got)
                .map(|(f, c)| c.miss.is_none() || inspectable(f, &map, &view, max_gsd_distance))
                .collect::<Vec<bool>>(),
        );
        flown.extend(got);
        if let Some(ps) = &plan_shots {
            planned.extend(cover(chunk, need, ps, &lenses, &map, &view));
        }
        progress(flown.len() as u64, total);
    }

    if !shots.is_empty() && flown.iter().all(|c| c.miss == Some(Miss::TooFar)) {
        return Err(CoverageError::Option(format!(
            "no camera came within {} m of any target voxel (cameras span {}, targets span {}); check that the poses and the targets are in the same world frame",
            view.max_distance_m,
            span(
                shots
                    .iter()
                    .map(|s| Point3::from(s.camera.translation.vector))
            ),
            span(targets.iter().map(|v| grid.center(*v))),
        )));
    }
    let records = voxel_records(
        &grid,
        &targets,
        &faces,
        &need,
        &flown,
        &planned,
        &reachable,
        plan_shots.is_some(),
    );
    let n = records.len();
    let inspected = records.iter().filter(|r| r.inspected).count();
    let planned_voxels = plan_shots
        .as_ref()
        .map(|_| records.iter().filter(|r| r.planned == Some(true)).count());
    let planned_inspected = records
        .iter()
        .filter(|r| r.planned == Some(true) && r.inspected)
        .count();
    let uninspectable = records.iter().filter(|r| r.uninspectable).count();
    let mut reasons = ReasonCounts::new();
    for r in &records {
        if let Some(m) = r.reason {
            *reasons.entry(m.to_string()).or_default() += 1;
        }
    }
    let inspected_faces = flown.iter().filter(|c| c.miss.is_none()).count();
    let pct = |a: usize, b: usize| {
        if b == 0 {
            0.0
        } else {
            100.0 * a as f64 / b as f64
        }
    };
    let summary = CoverageSummary {
        run: options.run.clone(),
        shots: options
            .viewpoints
            .as_ref()
            .map_or("flight".into(), |p| p.display().to_string()),
        view,
        resolution_m: grid.resolution,
        grid_origin: grid.origin.coords.into(),
        map: options.map.clone(),
        targets: targets_name,
        target_voxels: n,
        planned_voxels,
        inspected_voxels: inspected,
        inspected_pct: pct(inspected, n),
        planned_inspected_pct: planned_voxels.map(|p| pct(planned_inspected, p)),
        planned_missed_voxels: planned_voxels.map(|p| p - planned_inspected),
        gap_voxels: n - inspected - uninspectable,
        uninspectable_voxels: uninspectable,
        exposed_faces: faces.len(),
        inspected_faces,
        // Every face of a voxel grid has the same area.
        face_area_coverage_pct: pct(inspected_faces, faces.len()),
        obstacle_voxels: map
            .voxels
            .voxels()
            .filter(|v| !target_set.contains(v))
            .count(),
        reasons,
        shots_total: shots.len(),
        shots_usable: shots.len() - shots_blurred,
        shots_blurred,
        frames_without_pose,
        frames_without_exposure,
        faces_needing_more_views: need
            .iter()
            .filter(|n| **n > view.views_required.max(1))
            .count(),
        seconds: start.elapsed().as_secs_f64(),
        warnings,
    };
    let mut table =
        coverage_table(&records, grid.resolution).map_err(|e| CoverageError::Write {
            path: flight.run.file(table_name),
            why: e.to_string(),
        })?;
    flight.run.write_table(table_name, &mut table)?;
    flight.run.write_json(summary_name, &summary)?;
    Ok(summary)
}

/// The target voxels (deduplicated, in index order) and where they came
/// from; an error when they miss the map.
fn load_targets(
    source: &Targets,
    plan: Option<&InspectionPlan>,
    map: &SlamMap,
) -> Result<(Vec<VoxelIndex>, String), CoverageError> {
    let (targets, targets_name): (Vec<VoxelIndex>, String) = match source {
        Targets::Plan => {
            let plan = plan.ok_or_else(|| {
                CoverageError::Option(
                    "no target voxels: pass the plan with --plan, or the structure with --target-boxes or --target-cloud".into(),
                )
            })?;
            (plan.target_voxels.clone(), "plan".into())
        }
        Targets::Boxes(path) => (
            targets::in_boxes(&map.voxels, &targets::load_boxes(path)?),
            format!("boxes {}", path.display()),
        ),
        Targets::Cloud(path) => (
            targets::of_cloud(&map.voxels.grid, &PointCloud::load(path)?),
            format!("cloud {}", path.display()),
        ),
    };
    let targets: Vec<VoxelIndex> = targets
        .into_iter()
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    if targets.is_empty() {
        return Err(CoverageError::Option(format!(
            "the targets ({targets_name}) hold no voxel of the map; check that they are in the map's world frame and metres"
        )));
    }
    let mapped = targets
        .iter()
        .filter(|v| map.voxels.is_occupied(**v))
        .count();
    if (mapped as f64) < MIN_MAPPED_SHARE * targets.len() as f64 {
        return Err(CoverageError::Option(format!(
            "the targets ({targets_name}) do not overlap the map: {mapped} of {} target voxels hold map points (targets span {}, map spans {}); check that both are in the same world frame and in metres",
            targets.len(),
            span(targets.iter().map(|v| map.voxels.grid.center(*v))),
            span(map.cloud.points.iter().copied()),
        )));
    }
    Ok((targets, targets_name))
}

/// A plan's viewpoints as shots of the flight's first camera (sharp: a
/// plan is flown hovering).
fn viewpoint_shots(plan: &InspectionPlan, extrinsic: &Isometry3<f64>) -> Vec<Shot> {
    plan.viewpoints
        .iter()
        .enumerate()
        .map(|(i, v)| Shot {
            id: i as u32,
            camera: viewpoint_camera(v, extrinsic),
            lens: 0,
            blur_px: Some(0.0),
        })
        .collect()
}

/// The flight's frames as shots, and the frames that could not be.
struct FlightShots {
    shots: Vec<Shot>,
    /// Frames without a camera pose (or of a camera not in cameras.json).
    without_pose: usize,
    /// Frames whose blur cannot be judged: no exposure time recorded or given.
    without_exposure: usize,
}

/// Every frame with a pose, with its motion blur (`exposure_s` for frames
/// that recorded none).
fn flight_shots(
    flight: &Flight,
    lenses: &[Intrinsics],
    map: &SlamMap,
    exposure_s: Option<f64>,
) -> FlightShots {
    let mut out = FlightShots {
        shots: Vec::new(),
        without_pose: 0,
        without_exposure: 0,
    };
    for frame in &flight.frames {
        let (Some(camera), Some(lens)) = (
            frame.camera_pose,
            flight.cameras.iter().position(|c| c.topic == frame.topic),
        ) else {
            out.without_pose += 1;
            continue;
        };
        let exposure = frame.exposure_s.or(exposure_s);
        if exposure.is_none() {
            out.without_exposure += 1;
        }
        let blur = exposure.and_then(|e| {
            let extrinsic = flight.cameras[lens].extrinsic?;
            let PoseAt::Pose(body) = flight.trajectory.at(frame.time_ns, i64::MAX) else {
                return None;
            };
            let v = velocity(&flight.trajectory, frame.time_ns)?;
            Some(blur_px(
                &body,
                &extrinsic,
                &lenses[lens],
                &v,
                e,
                &map.voxels,
            ))
        });
        out.shots.push(Shot {
            id: frame.index,
            camera,
            lens,
            blur_px: blur,
        });
    }
    out
}

pub(crate) fn check_view(view: &ViewModel) -> Result<(), CoverageError> {
    let bad = |what: &str| Err(CoverageError::Option(format!("invalid View model: {what}")));
    if !(view.min_distance_m >= 0.0 && view.min_distance_m < view.max_distance_m) {
        return bad("the distance band needs 0 <= min < max (--min-distance, --max-distance)");
    }
    if !(view.cone_apex_deg > 0.0 && view.cone_apex_deg <= 180.0) {
        return bad("the cone apex angle must be in (0, 180] degrees (--cone-apex)");
    }
    if !(view.max_incidence_deg > 0.0 && view.max_incidence_deg <= 90.0) {
        return bad("the largest incidence must be in (0, 90] degrees (--max-incidence)");
    }
    if !(view.max_blur_px >= 0.0 && view.max_gsd_mm > 0.0) {
        return bad("blur and GSD limits must be positive (--max-blur, --max-gsd)");
    }
    Ok(())
}

/// Positions of the defect candidates in `defects.json` (written by localise).
fn defect_positions(path: &Path) -> Result<Vec<Point3<f64>>, CoverageError> {
    #[derive(Deserialize)]
    struct Defects {
        defects: Vec<Defect>,
    }
    #[derive(Deserialize)]
    struct Defect {
        position: [f64; 3],
    }
    let text = std::fs::read_to_string(path).map_err(|e| {
        CoverageError::Option(format!(
            "views near defects need {} ({e}); run `postflight localise` first",
            path.display()
        ))
    })?;
    let d: Defects = serde_json::from_str(&text).map_err(|e| {
        CoverageError::Option(format!(
            "{} is unreadable ({e}); rerun `postflight localise`",
            path.display()
        ))
    })?;
    Ok(d.defects.iter().map(|d| Point3::from(d.position)).collect())
}
